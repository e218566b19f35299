#pragma once
/// OpenNI2 depth sensors: a live device (openni2:// or openni2://<device-uri>) and `.oni` playback go
/// through the same code path. Registration depth->colour on, mirroring off, depth/colour sync on.
#include <memory>
#include <string>

#include "capture/frame_source.h"

namespace mrgi::capture {

class OpenNI2Source final : public FrameSource {
 public:
  /// deviceUri: "" for the first device, a device URI, or a path to a .oni file.
  /// Throws CaptureError("openni2://...: no device found") etc.
  explicit OpenNI2Source(const std::string& deviceUri, const OpenOptions& options = {});
  ~OpenNI2Source() override;
  const SourceInfo& info() const override { return info_; }
  /// Returns nullopt at the end of a .oni file; throws CaptureError when a live device is lost.
  std::optional<Frame> next() override;

  /// True when the device has no colour stream (the frames' colour is then mid-grey).
  bool depthOnly() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  SourceInfo info_;
};

}  // namespace mrgi::capture
