#include "capture/openni2_source.h"

#include <OpenNI.h>

#include <cmath>
#include <mutex>

#include "capture/error.h"

namespace mrgi::capture {
namespace {

std::string lastError() {
  const char* e = openni::OpenNI::getExtendedError();
  std::string s = e ? e : "";
  for (char& c : s)
    if (c == '\n' || c == '\r' || c == '\t') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  while (!s.empty() && s.front() == ' ') s.erase(s.begin());
  return s.empty() ? "unknown OpenNI2 error" : s;
}

void initialiseOnce() {
  static std::once_flag flag;
  static openni::Status status = openni::STATUS_OK;
  std::call_once(flag, [] { status = openni::OpenNI::initialize(); });
  if (status != openni::STATUS_OK) throw CaptureError("openni2://", "cannot initialise OpenNI2 (" + lastError() + ")");
}

Intrinsics intrinsicsOf(const openni::VideoStream& s) {
  const openni::VideoMode mode = s.getVideoMode();
  Intrinsics k;
  k.width = mode.getResolutionX();
  k.height = mode.getResolutionY();
  // OpenNI2 reports fields of view; the principal point is the image centre.
  k.fx = k.width / (2.0 * std::tan(s.getHorizontalFieldOfView() / 2.0));
  k.fy = k.height / (2.0 * std::tan(s.getVerticalFieldOfView() / 2.0));
  k.cx = (k.width - 1) / 2.0;
  k.cy = (k.height - 1) / 2.0;
  return k;
}

}  // namespace

struct OpenNI2Source::Impl {
  std::string uri;
  bool isFile = false;
  openni::Device device;
  openni::VideoStream depth, colour;
  bool hasColour = false;
  int64_t index = 0;
  int64_t fileFrames = -1;
  double lastTimestamp = -1.0;
};

OpenNI2Source::OpenNI2Source(const std::string& deviceUri, const OpenOptions& options) : impl_(std::make_unique<Impl>()) {
  auto& d = *impl_;
  d.isFile = deviceUri.size() > 4 && deviceUri.compare(deviceUri.size() - 4, 4, ".oni") == 0;
  d.uri = d.isFile ? deviceUri : "openni2://" + deviceUri;
  initialiseOnce();
  if (d.device.open(deviceUri.empty() ? openni::ANY_DEVICE : deviceUri.c_str()) != openni::STATUS_OK)
    throw CaptureError(d.isFile ? deviceUri : d.uri,
                       d.isFile ? "cannot open .oni file (" + lastError() + ")"
                                : deviceUri.empty() ? "no depth sensor connected" : "cannot open device (" + lastError() + ")");
  if (!d.device.hasSensor(openni::SENSOR_DEPTH) || d.depth.create(d.device, openni::SENSOR_DEPTH) != openni::STATUS_OK)
    throw CaptureError(d.uri, "device has no depth stream");
  if (d.device.hasSensor(openni::SENSOR_COLOR) && d.colour.create(d.device, openni::SENSOR_COLOR) == openni::STATUS_OK)
    d.hasColour = true;

  if (!d.isFile) {
    // Live devices: choose modes, then register depth to colour and sync the streams.
    auto pick = [&](openni::VideoStream& s, openni::PixelFormat fmt) {
      const auto& modes = s.getSensorInfo().getSupportedVideoModes();
      for (int i = 0; i < modes.getSize(); ++i) {
        const auto& m = modes[i];
        const bool sizeOk = options.width == 0 || (m.getResolutionX() == options.width && m.getResolutionY() == options.height);
        if (m.getPixelFormat() == fmt && sizeOk && m.getFps() >= 25) {
          s.setVideoMode(m);
          return;
        }
      }
    };
    pick(d.depth, openni::PIXEL_FORMAT_DEPTH_1_MM);
    if (d.hasColour) pick(d.colour, openni::PIXEL_FORMAT_RGB888);
    if (d.hasColour && d.device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR))
      d.device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
    if (d.hasColour) d.device.setDepthColorSyncEnabled(true);
  } else if (auto* playback = d.device.getPlaybackControl()) {
    playback->setSpeed(-1.0f);  // manual stepping: every readFrame returns the next recorded frame
    playback->setRepeatEnabled(false);
    d.fileFrames = playback->getNumberOfFrames(d.depth);
  }
  d.depth.setMirroringEnabled(false);
  if (d.hasColour) d.colour.setMirroringEnabled(false);
  if (d.depth.start() != openni::STATUS_OK) throw CaptureError(d.uri, "cannot start the depth stream (" + lastError() + ")");
  if (d.hasColour && d.colour.start() != openni::STATUS_OK)
    throw CaptureError(d.uri, "cannot start the colour stream (" + lastError() + ")");

  info_.uri = d.uri;
  info_.kind = "openni2";
  if (d.fileFrames >= 0) info_.frameCount = d.fileFrames;
  info_.depthIntrinsics = intrinsicsOf(d.depth);
  info_.colourIntrinsics = d.hasColour ? intrinsicsOf(d.colour) : info_.depthIntrinsics;
  info_.hasRgbd = true;
  info_.fps = d.depth.getVideoMode().getFps();
}

OpenNI2Source::~OpenNI2Source() {
  if (!impl_) return;
  impl_->depth.stop();
  impl_->colour.stop();
  impl_->depth.destroy();
  impl_->colour.destroy();
  impl_->device.close();
}

bool OpenNI2Source::depthOnly() const { return !impl_->hasColour; }

std::optional<Frame> OpenNI2Source::next() {
  auto& d = *impl_;
  if (d.fileFrames >= 0 && d.index >= d.fileFrames) return std::nullopt;
  constexpr int kTimeoutMs = 2000;
  openni::VideoFrameRef depthFrame, colourFrame;
  auto readOne = [&](openni::VideoStream& s, openni::VideoFrameRef& out) -> bool {
    openni::VideoStream* streams[] = {&s};
    int ready = -1;
    if (openni::OpenNI::waitForAnyStream(streams, 1, &ready, kTimeoutMs) != openni::STATUS_OK) return false;
    return s.readFrame(&out) == openni::STATUS_OK && out.isValid();
  };
  if (!readOne(d.depth, depthFrame)) {
    if (d.isFile) return std::nullopt;  // end of the recording
    throw CaptureError(d.uri, "device lost (no depth frame for 2 s)");
  }
  if (d.hasColour && !readOne(d.colour, colourFrame)) {
    if (d.isFile) return std::nullopt;
    throw CaptureError(d.uri, "device lost (no colour frame for 2 s)");
  }

  Frame f;
  f.index = d.index++;
  f.timestamp = static_cast<double>(depthFrame.getTimestamp()) * 1e-6;  // microseconds
  if (f.timestamp <= d.lastTimestamp) f.timestamp = d.lastTimestamp + 1e-6;  // keep the contract: increasing
  d.lastTimestamp = f.timestamp;

  RgbdFrame r;
  const int dw = depthFrame.getWidth(), dh = depthFrame.getHeight();
  const auto fmt = depthFrame.getVideoMode().getPixelFormat();
  const double unit = fmt == openni::PIXEL_FORMAT_DEPTH_100_UM ? 1e-4 : 1e-3;
  const cv::Mat raw(dh, dw, CV_16UC1, const_cast<void*>(depthFrame.getData()), depthFrame.getStrideInBytes());
  raw.convertTo(r.depth, CV_32F, unit);
  if (d.hasColour) {
    const cv::Mat rgb(colourFrame.getHeight(), colourFrame.getWidth(), CV_8UC3, const_cast<void*>(colourFrame.getData()),
                      colourFrame.getStrideInBytes());
    r.colour = rgb.clone();
  } else {
    r.colour = cv::Mat(dh, dw, CV_8UC3, cv::Scalar(128, 128, 128));
  }
  r.colourIntrinsics = info_.colourIntrinsics;
  r.depthIntrinsics = info_.depthIntrinsics;
  r.depthRegistered = d.hasColour && d.device.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
  if (!d.hasColour) r.depthRegistered = true;  // the grey stand-in is generated in the depth camera
  f.rgbd = std::move(r);
  return f;
}

}  // namespace mrgi::capture
