#pragma once
// Where the interactive commands (live, record) get frames: the depth sensor with the fisheye camera
// grabbed every N frames, or a recording through the same interface (looped for the live demo).
#include <memory>
#include <optional>
#include <string>

#include "capture/frame_source.h"
#include "capture/session.h"

namespace mrgi::app {

struct LiveSourceOptions {
  std::string source;  ///< session, TUM or .oni; empty: the depth sensor
  std::string device = "openni2://";
  std::string fisheye;             ///< V4L2 device of the fisheye camera (with the sensor)
  std::string fisheyeCalibration;  ///< its calibration YAML
  int fisheyeEvery = 30;           ///< grab a fisheye frame every N depth frames
  bool loop = false;               ///< play a recording again from the start at its end
};

class LiveSource {
 public:
  /// Throws a one-line CaptureError when no sensor is there ("... use --source").
  explicit LiveSource(LiveSourceOptions o);
  const capture::FrameSource& source() const { return *source_; }
  const std::string& name() const { return name_; }
  bool recording() const { return !o_.source.empty(); }
  /// The next frame (with a fisheye frame every N); nullopt at the end of a recording that does not loop.
  std::optional<capture::Frame> next();
  /// The fisheye camera's calibration (sensor with --fisheye), else nullopt: that of the fisheye frames
  /// next() handed out, or of one frame grabbed for it before any.
  std::optional<capture::FisheyeCalibration> fisheyeCalibration();

 private:
  LiveSourceOptions o_;
  std::unique_ptr<capture::FrameSource> source_, fisheye_;
  std::string name_;
  int64_t loops_ = 0, count_ = 0;
  std::optional<capture::FisheyeCalibration> calibration_;
};

/// The manifest a recording of this source starts with: a session's own (its ground-truth reference files
/// stay behind), else the first frame's intrinsics and its fisheye calibration.
capture::SessionManifest manifestFor(const capture::FrameSource& source, const capture::Frame& first);

}  // namespace mrgi::app
