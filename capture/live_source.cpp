#include "capture/live_source.h"

#include <algorithm>

#include "capture/error.h"
#include "capture/v4l2_source.h"

namespace mrgi::capture {

LiveSource::LiveSource(LiveSourceOptions o) : o_(std::move(o)) {
  if (!o_.source.empty() && !o_.fisheye.empty())
    throw FlagError("--fisheye",
                    "a fisheye camera is read only beside a live depth sensor, not with --source (a recording's "
                    "fisheye frames come from the recording)");
  if (!o_.source.empty()) {
    source_ = open(o_.source);
    name_ = o_.source;
  } else {
    try {
      source_ = open(o_.device);
    } catch (const CaptureError& e) {
      throw CaptureError(o_.device, std::string("no depth sensor (") + e.what() +
                                        "); use --source SESSION or FILE.oni to play a recording instead");
    }
    name_ = o_.device;
    if (!o_.fisheye.empty()) {
      OpenOptions fo;
      fo.fisheyeCalibration = o_.fisheyeCalibration;
      fisheye_ = open("v4l2://" + o_.fisheye, fo);
    }
  }
  if (!source_->info().hasRgbd) throw CaptureError(name_, "has no RGB-D frames");
}

std::optional<Frame> LiveSource::next() {
  auto f = source_->next();
  if (!f && recording() && o_.loop) {
    source_ = open(o_.source);  // from the start again
    ++loops_;
    f = source_->next();
  }
  if (f && fisheye_ && count_++ % std::max(o_.fisheyeEvery, 1) == 0)
    if (auto fe = fisheye_->next(); fe && fe->fisheye) {
      calibration_ = fe->fisheye->calibration;
      f->fisheye = fe->fisheye;
    }
  if (f && loops_ > 0) f->timestamp += static_cast<double>(loops_) * 1e6;  // timestamps keep increasing
  return f;
}

std::optional<FisheyeCalibration> LiveSource::fisheyeCalibration() {
  if (fisheye_ && !calibration_)
    if (auto f = fisheye_->next(); f && f->fisheye) calibration_ = f->fisheye->calibration;
  return calibration_;
}

SessionManifest manifestFor(const FrameSource& source, const Frame& first) {
  if (const SessionManifest* s = source.sessionManifest()) {
    SessionManifest m = *s;
    if (m.groundTruth.is_object()) m.groundTruth.erase("reference");  // its files are not copied
    m.truth.reference.reset();
    return m;
  }
  SessionManifest m;
  m.colour = first.rgbd->colourIntrinsics;
  m.depth = first.rgbd->depthIntrinsics;
  m.depthRegistered = first.rgbd->depthRegistered;
  m.T_colour_depth = first.rgbd->T_colour_depth;
  if (first.fisheye) m.fisheye = first.fisheye->calibration;
  return m;
}

}  // namespace mrgi::capture
