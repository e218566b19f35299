#pragma once
// Where the interactive commands (live, record) get frames: the depth sensor with the fisheye camera
// grabbed every N frames, or a recording through the same interface (looped for the live demo).
#include <memory>
#include <optional>
#include <string>

#include "capture/frame_source.h"
#include "capture/session.h"

namespace mrgi::capture {

struct LiveSourceOptions {
  std::string source;  ///< session, TUM or .oni; empty: the depth sensor
  std::string device = "openni2://";
  std::string fisheye;             ///< V4L2 device of the fisheye camera (with the sensor)
  std::string fisheyeCalibration;  ///< its calibration YAML
  int fisheyeEvery = 30;           ///< grab a fisheye frame every N depth frames
  bool loop = false;               ///< play a recording again from the start at its end
};

/// The depth sensor (with the fisheye camera's frames every N), or a recording played through the same interface.
class LiveSource : public FrameSource {
 public:
  /// Throws a one-line CaptureError when no sensor is there ("... use --source"), FlagError("--fisheye") for a
  /// fisheye camera beside a recording.
  explicit LiveSource(LiveSourceOptions o);
  const SourceInfo& info() const override { return source_->info(); }
  const SessionManifest* sessionManifest() const override { return source_->sessionManifest(); }
  const std::string& name() const { return name_; }
  bool recording() const { return !o_.source.empty(); }
  /// The next frame (with a fisheye frame every N); nullopt at the end of a recording that does not loop.
  std::optional<Frame> next() override;
  /// The fisheye camera's calibration (sensor with --fisheye), else nullopt: that of the fisheye frames
  /// next() handed out, or of one frame grabbed for it before any.
  std::optional<FisheyeCalibration> fisheyeCalibration();

 private:
  LiveSourceOptions o_;
  std::unique_ptr<FrameSource> source_, fisheye_;
  std::string name_;
  int64_t loops_ = 0, count_ = 0;
  std::optional<FisheyeCalibration> calibration_;
};

/// The manifest a recording of this source starts with: a session's own (its ground-truth reference files
/// stay behind), else the first frame's intrinsics and its fisheye calibration.
SessionManifest manifestFor(const FrameSource& source, const Frame& first);

}  // namespace mrgi::capture
