#pragma once
/// One interface for live and recorded sources; one factory opens them all.
#include <array>
#include <memory>
#include <optional>
#include <string>

#include "capture/types.h"

namespace mrgi::capture {

struct SessionManifest;

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual const SourceInfo& info() const = 0;
  /// The next frame, or std::nullopt at the end of a recording. Throws CaptureError for corrupt data
  /// or a lost device ("openni2://...: device lost"), never crashes.
  virtual std::optional<Frame> next() = 0;
  /// A recorded session's manifest (marker, fisheye calibration, typed ground truth); nullptr for sources
  /// without one.
  virtual const SessionManifest* sessionManifest() const { return nullptr; }
};

struct OpenOptions {
  /// Fisheye calibration (OpenCV YAML with K, D) for v4l2 sources; sessions carry their own.
  std::string fisheyeCalibration;
  int width = 0, height = 0;  ///< requested live resolution, 0 = device default
  /// A recorded folder's calibration (TUM, Open3D) in pixels: fx, fy, cx, cy; over what the folder says.
  std::optional<std::array<double, 4>> intrinsics;
  /// Units per metre of a folder's 16-bit depth images (0: the format's own, TUM 5000, Open3D 1000).
  double depthUnitsPerMetre = 0;
};

/// A folder's colour intrinsics: `options.intrinsics` when given, else `fromFolder` (its calibration file or
/// what its name says), else `fallback` with `note` set to one line for the user naming the folder, the
/// values taken and how to give the right ones. Throws CaptureError when the given values are not finite
/// and positive.
Intrinsics folderIntrinsics(const std::string& folder, const OpenOptions& options,
                            const std::optional<Intrinsics>& fromFolder, const Intrinsics& fallback, int width,
                            int height, std::string& note);
/// `options.depthUnitsPerMetre`, or `formatDefault` when it is 0; throws CaptureError when not finite and
/// positive.
double folderDepthUnits(const std::string& folder, const OpenOptions& options, double formatDefault);

/// Opens a source from a path or URI:
///   openni2://            first OpenNI2 device;  openni2://<device-uri>  a specific one
///   FILE.oni              OpenNI2 playback through the same code path as a device
///   v4l2:///dev/videoN    V4L2 fisheye camera
///   DIR with manifest.json            an mrgi session
///   DIR with rgb.txt and depth.txt    a TUM RGB-D sequence
///   DIR with color/ (or image/) and depth/   an Open3D RGB-D folder
/// Throws CaptureError naming the path when nothing can open it.
std::unique_ptr<FrameSource> open(const std::string& uri, const OpenOptions& options = {});

}  // namespace mrgi::capture
