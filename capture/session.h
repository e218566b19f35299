#pragma once
/// The mrgi session format (recordings/FORMAT.md): a directory with manifest.json, frames.jsonl (one JSON
/// line per complete frame) and per-frame image files. Writing is crash-safe: a reader replays a
/// recording cut at any byte up to its last complete frame.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame_source.h"
#include "capture/ground_truth.h"
#include "capture/types.h"

namespace mrgi::capture {

inline constexpr int kSessionVersion = 1;
/// The largest image side a session may declare (pixels).
inline constexpr int kMaxImageSide = 16384;

struct MarkerSpec {
  std::string family = "tag36h11";
  double sizeMetres = 0.0;  ///< edge length of the tag's black square
  int id = 0;
};

struct SessionManifest {
  int version = kSessionVersion;
  Intrinsics colour;
  Intrinsics depth;
  double depthUnitsMetres = 0.001;  ///< metres per unit of the 16-bit depth PNGs
  bool depthRegistered = true;
  Pose T_colour_depth = identityPose();
  std::optional<FisheyeCalibration> fisheye;
  std::optional<MarkerSpec> marker;
  /// Optional ground truth as stored: {"T_world_marker": [16], "lights": [...], "scene": {...}}; null if absent.
  nlohmann::json groundTruth;
  /// The same, typed and checked (filled by fromJson; what readers use).
  GroundTruth truth;

  nlohmann::json toJson() const;
  /// Throws CaptureError("<file>: ...") naming the bad key.
  static SessionManifest fromJson(const nlohmann::json& j, const std::string& fileForErrors);

 private:
  static SessionManifest fromJsonChecked(const nlohmann::json& j, const std::string& fileForErrors);
};

/// Appends frames to a new session directory. Never overwrites: the directory must not exist or be empty.
class SessionWriter {
 public:
  SessionWriter(std::string directory, SessionManifest manifest);
  ~SessionWriter();
  SessionWriter(const SessionWriter&) = delete;
  SessionWriter& operator=(const SessionWriter&) = delete;

  /// Writes the frame's images to temporary names, fsyncs and renames them, then appends and fsyncs its
  /// index line. Frame timestamps must increase. colour as RGB CV_8UC3; depth metres CV_32FC1.
  void append(const Frame& frame);
  int64_t framesWritten() const { return written_; }
  /// The colour images of the frames appended from now on: JPEG at this quality (1-100; smaller, lossy), or
  /// PNG (0, the default: lossless).
  void setColourJpegQuality(int quality) { jpegQuality_ = quality; }
  const std::string& directory() const { return dir_; }

 private:
  std::string dir_;
  SessionManifest manifest_;
  int indexFd_ = -1;
  int64_t written_ = 0;
  int jpegQuality_ = 0;
  double lastTimestamp_ = 0.0;
};

/// Reads a session; the index is read at open, images are decoded lazily by next().
class SessionSource final : public FrameSource {
 public:
  explicit SessionSource(const std::string& directory);
  const SourceInfo& info() const override { return info_; }
  std::optional<Frame> next() override;

  const SessionManifest& manifest() const { return manifest_; }
  const SessionManifest* sessionManifest() const override { return &manifest_; }
  /// Reads frame i (0-based) without moving the cursor.
  Frame read(int64_t i) const;
  int64_t frameCount() const { return static_cast<int64_t>(entries_.size()); }
  /// Bytes of frames.jsonl after the last complete line (a write cut short); 0 for a clean recording.
  int64_t trailingBytes() const { return trailingBytes_; }

 private:
  struct Entry {
    int64_t index;
    double t;
    std::string colour, depth, fisheye;
    double exposure = 1.0, colourExposure = 1.0;
    std::optional<Pose> pose;
    std::optional<std::vector<GroundTruthLight>> lights;
  };
  std::string dir_;
  SessionManifest manifest_;
  std::vector<Entry> entries_;
  SourceInfo info_;
  int64_t cursor_ = 0;
  int64_t trailingBytes_ = 0;
};

/// JSON helpers shared by the format's readers and writers (row-major 4x4, 3x3).
nlohmann::json poseToJson(const Pose& p);
Pose poseFromJson(const nlohmann::json& j, const std::string& fileForErrors, const std::string& key);

}  // namespace mrgi::capture
