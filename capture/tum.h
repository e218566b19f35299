#pragma once
/// TUM RGB-D benchmark sequences: rgb.txt, depth.txt (and optional groundtruth.txt), each line
/// "timestamp path" ("timestamp tx ty tz qx qy qz qw" for ground truth), '#' comments.
/// Depth PNGs are 16-bit with 5000 units per metre.
#include <string>
#include <vector>

#include "capture/frame_source.h"

namespace mrgi::capture {

inline constexpr double kTumDepthUnitsPerMetre = 5000.0;
inline constexpr double kTumMaxAssociationGap = 0.02;  ///< seconds, as in the benchmark's associate.py

struct TumEntry {
  double t;
  std::string value;  ///< file path, or the 7 pose numbers as text
  int line = 0;       ///< where it stands in its list (1-based), for errors
};

/// Reads a TUM list file; throws CaptureError("<file>:<line>: ...") for a malformed or non-monotonic line.
std::vector<TumEntry> readTumList(const std::string& path);

/// Pairs each colour entry with the nearest unused depth entry within maxGap seconds, keeping time order.
/// Returns index pairs (colour, depth).
std::vector<std::pair<size_t, size_t>> associateTimestamps(const std::vector<double>& a, const std::vector<double>& b,
                                                           double maxGap);

/// Intrinsics of the TUM Kinects by sequence name (freiburg1/2/3), else the ROS default 525/319.5/239.5.
/// A folder may carry its own calibration (camera_intrinsic.json or camera.json, Open3D's format), or be
/// given one (OpenOptions::intrinsics).
Intrinsics tumIntrinsics(const std::string& directoryName, int width, int height);

class TumSource final : public FrameSource {
 public:
  explicit TumSource(const std::string& directory, const OpenOptions& options = {});
  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override;

 private:
  struct Item {
    double t;
    std::string colour, depth;
    std::optional<Pose> pose;
  };
  std::string dir_;
  std::vector<Item> items_;
  SourceInfo info_;
  double unitsPerMetre_ = kTumDepthUnitsPerMetre;
  size_t cursor_ = 0;
};

}  // namespace mrgi::capture
