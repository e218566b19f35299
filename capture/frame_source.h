#pragma once
/// One interface for live and recorded sources; one factory opens them all.
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
};

/// Opens a source from a path or URI:
///   openni2://            first OpenNI2 device;  openni2://<device-uri>  a specific one
///   FILE.oni              OpenNI2 playback through the same code path as a device
///   v4l2:///dev/videoN    V4L2 fisheye camera
///   DIR with manifest.json            an mrgi session
///   DIR with rgb.txt and depth.txt    a TUM RGB-D sequence
/// Throws CaptureError naming the path when nothing can open it.
std::unique_ptr<FrameSource> open(const std::string& uri, const OpenOptions& options = {});

}  // namespace mrgi::capture
