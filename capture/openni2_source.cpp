#include "capture/openni2_source.h"

#include <OpenNI.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <set>

#include "capture/error.h"
#include "capture/timestamp_pairing.h"

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

/// A usable field of view: finite, in (0, pi).
bool usableFov(double h, double v) {
  return std::isfinite(h) && std::isfinite(v) && h > 0 && v > 0 && h < CV_PI && v < CV_PI;
}

/// Intrinsics from a stream's fields of view (OpenNI2 reports no principal point: the image centre).
/// A stream that reports no usable field of view (colour streams of OpenNI 1.x recordings report 0) takes
/// `fallback`'s and says so in `note` (the source's calibration note, said once by the command); without one it
/// fails in one line.
Intrinsics intrinsicsOf(const openni::VideoStream& s, const std::string& uri, const char* name,
                        const openni::VideoStream* fallback, std::string* note) {
  const openni::VideoMode mode = s.getVideoMode();
  Intrinsics k;
  k.width = mode.getResolutionX();
  k.height = mode.getResolutionY();
  double h = s.getHorizontalFieldOfView(), v = s.getVerticalFieldOfView();
  if (!usableFov(h, v)) {
    if (!fallback || !usableFov(fallback->getHorizontalFieldOfView(), fallback->getVerticalFieldOfView()))
      throw CaptureError(uri, std::string("the ") + name + " stream reports no field of view (" + std::to_string(h) +
                                  " x " + std::to_string(v) + " rad); its intrinsics are unknown");
    h = fallback->getHorizontalFieldOfView();
    v = fallback->getVerticalFieldOfView();
    char text[160];
    std::snprintf(text, sizeof text,
                  "the %s stream reports no field of view; using the depth stream's (%.1f x %.1f deg)", name,
                  h * 180 / CV_PI, v * 180 / CV_PI);
    if (note) *note = uri + ": " + text;
  }
  k.fx = k.width / (2.0 * std::tan(h / 2.0));
  k.fy = k.height / (2.0 * std::tan(v / 2.0));
  k.cx = (k.width - 1) / 2.0;
  k.cy = (k.height - 1) / 2.0;
  if (!k.valid()) throw CaptureError(uri, std::string("the ") + name + " stream reports an unusable video mode");
  return k;
}

/// What is known about a file OpenNI2 cannot open: its size and header.
std::string describeOniFile(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return "cannot read the file";
  std::ifstream in(path, std::ios::binary);
  char magic[4] = {0, 0, 0, 0};
  in.read(magic, 4);
  const std::string m(magic, static_cast<size_t>(in.gcount()));
  std::string what = std::to_string(size) + " bytes";
  if (m == "NI10")
    what += ", an OpenNI 1.x recording header";
  else if (m.size() == 4 && m.compare(0, 2, "NI") == 0)
    what += ", an ONI header ('" + m + "')";
  else
    what += ", no ONI header (not a recording)";
  return what;
}

/// OpenNI2 plays a file once per process: a second opening of the same path while the first is open shares its
/// player and its place in the file (a recording read to its end gave the next reader no frame at all), and two
/// players of one file open at once crash inside OpenNI2 when closed. An opening holds its file's claim; a
/// second claim while it is held is refused in one line.
class FileClaim {
 public:
  explicit FileClaim(const std::string& path) {
    std::error_code ec;
    const std::filesystem::path p = std::filesystem::weakly_canonical(path, ec);
    key_ = ec ? path : p.string();
    const std::lock_guard<std::mutex> lock(mutex());
    if (!claimed().insert(key_).second)
      throw CaptureError(path, "is already open in this process (OpenNI2 plays a file once at a time)");
  }
  ~FileClaim() {
    const std::lock_guard<std::mutex> lock(mutex());
    claimed().erase(key_);
  }
  FileClaim(const FileClaim&) = delete;
  FileClaim& operator=(const FileClaim&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static std::set<std::string>& claimed() {
    static std::set<std::string> s;
    return s;
  }
  std::string key_;
};

}  // namespace

struct OpenNI2Source::Impl {
  std::optional<FileClaim> claim;  ///< file playback: this opening's claim on the file (released last)
  std::string uri;
  bool isFile = false;
  openni::Device device;
  openni::VideoStream depth, colour;
  bool hasColour = false;
  int64_t index = 0;
  int64_t fileFrames = -1;
  double lastTimestamp = -1.0;
  int64_t colourFrames = -1, colourRead = 0;   ///< file playback: the colour stream's length, frames read
  int64_t depthFrames = -1, depthRead = 0;     ///< file playback: the depth stream's length, frames read
  bool flipDepth = false, flipColour = false;  ///< recorded mirrored: un-mirror in software
  std::optional<NearestInTime<openni::VideoFrameRef>> colourPairs;  ///< file playback: colour nearest in time
};

OpenNI2Source::OpenNI2Source(const std::string& deviceUri, const OpenOptions& options)
    : impl_(std::make_unique<Impl>()) {
  auto& d = *impl_;
  d.isFile = deviceUri.size() > 4 && deviceUri.compare(deviceUri.size() - 4, 4, ".oni") == 0;
  d.uri = d.isFile ? deviceUri : "openni2://" + deviceUri;
  initialiseOnce();
  if (d.isFile) d.claim.emplace(deviceUri);
  if (d.device.open(deviceUri.empty() ? openni::ANY_DEVICE : deviceUri.c_str()) != openni::STATUS_OK)
    throw CaptureError(d.isFile ? deviceUri : d.uri, d.isFile
                                                         ? "cannot open .oni file (" + describeOniFile(deviceUri) +
                                                               "; OpenNI2: " + lastError() + "): truncated or corrupt"
                                                     : deviceUri.empty() ? "no depth sensor connected"
                                                                         : "cannot open device (" + lastError() + ")");
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
        const bool sizeOk =
            options.width == 0 || (m.getResolutionX() == options.width && m.getResolutionY() == options.height);
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
    d.fileFrames = d.depthFrames = playback->getNumberOfFrames(d.depth);
    // Pairs are made by timestamp; a pair needs a frame of each stream.
    if (d.hasColour) {
      d.colourFrames = playback->getNumberOfFrames(d.colour);
      d.fileFrames = std::min(d.fileFrames, d.colourFrames);
    }
  }
  // Mirroring off. File playback cannot switch it (the recording's setting holds): such frames are
  // un-mirrored in software.
  d.depth.setMirroringEnabled(false);
  if (d.hasColour) d.colour.setMirroringEnabled(false);
  d.flipDepth = d.depth.getMirroringEnabled();
  d.flipColour = d.hasColour && d.colour.getMirroringEnabled();
  if (d.depth.start() != openni::STATUS_OK)
    throw CaptureError(d.uri, "cannot start the depth stream (" + lastError() + ")");
  if (d.hasColour && d.colour.start() != openni::STATUS_OK)
    throw CaptureError(d.uri, "cannot start the colour stream (" + lastError() + ")");

  info_.uri = d.uri;
  info_.kind = "openni2";
  if (d.fileFrames >= 0) info_.frameCount = d.fileFrames;
  info_.depthIntrinsics = intrinsicsOf(d.depth, d.uri, "depth", nullptr, nullptr);
  info_.colourIntrinsics =
      d.hasColour ? intrinsicsOf(d.colour, d.uri, "colour", &d.depth, &info_.calibrationNote) : info_.depthIntrinsics;
  if (d.hasColour)
    d.colourPairs.emplace([&d]() -> std::optional<std::pair<openni::VideoFrameRef, double>> {
      if (d.colourFrames >= 0 && d.colourRead >= d.colourFrames) return std::nullopt;  // its end: no need to wait
      ++d.colourRead;
      openni::VideoFrameRef c;
      openni::VideoStream* streams[] = {&d.colour};
      int ready = -1;
      if (openni::OpenNI::waitForAnyStream(streams, 1, &ready, 2000) != openni::STATUS_OK) return std::nullopt;
      if (d.colour.readFrame(&c) != openni::STATUS_OK || !c.isValid()) return std::nullopt;
      return std::pair{c, static_cast<double>(c.getTimestamp()) * 1e-6};
    });
  info_.hasRgbd = true;
  info_.fps = d.depth.getVideoMode().getFps();
}

OpenNI2Source::~OpenNI2Source() {
  if (!impl_) return;
  auto& d = *impl_;
  d.colourPairs.reset();  // the colour frames held for pairing go back while their stream lives
  // OpenNI2's file player runs on a thread of its own, stepped by hand: each frame read lets it deliver the
  // recording's next one, and it then waits for the next step. Tearing it down is safe in only one order per
  // state (OpenNI2.ClosingARecording… tries both states, and fails with the other order in either):
  //  - every frame read: the player has run past the end and walks its list of streams without pause or lock,
  //    so a stream destroyed under it is a use after free. Close the device first: that joins the thread.
  //  - frames left: the player holds the next one, waiting. Closing the device wakes it and it delivers that
  //    frame into streams that are being closed (a crash inside OpenNI2). Destroy the streams first: the player
  //    then has no stream to deliver to, and closing the device joins it.
  const bool playedToTheEnd = d.isFile && d.depthFrames >= 0 && d.depthRead >= d.depthFrames &&
                              (!d.hasColour || d.colourRead >= d.colourFrames);
  if (playedToTheEnd) {
    // The last frame read let the player take its next step (to the end of the file, or to frames past those the
    // streams report): it settles first, any frame it still delivers read and let go, until 50 ms pass without one.
    openni::VideoStream* streams[] = {&d.depth, &d.colour};
    for (int step = 0; step < 64; ++step) {
      int ready = -1;
      if (openni::OpenNI::waitForAnyStream(streams, d.hasColour ? 2 : 1, &ready, 50) != openni::STATUS_OK) break;
      openni::VideoFrameRef frame;
      if (ready < 0 || ready > 1 || streams[ready]->readFrame(&frame) != openni::STATUS_OK) break;
    }
  }
  d.depth.stop();
  d.colour.stop();
  if (playedToTheEnd) d.device.close();
  d.depth.destroy();
  d.colour.destroy();
  d.device.close();
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
  ++d.depthRead;
  if (!readOne(d.depth, depthFrame)) {
    if (d.isFile) return std::nullopt;  // end of the recording
    throw CaptureError(d.uri, "device lost (no depth frame for 2 s)");
  }
  if (d.hasColour && d.isFile) {
    // Playback reads the streams independently: the colour frame nearest the depth frame's time.
    const auto c = d.colourPairs->nearest(static_cast<double>(depthFrame.getTimestamp()) * 1e-6);
    if (!c) return std::nullopt;
    colourFrame = *c;
  } else if (d.hasColour && !readOne(d.colour, colourFrame)) {
    throw CaptureError(d.uri, "device lost (no colour frame for 2 s)");
  }

  Frame f;
  f.index = d.index++;
  f.timestamp = static_cast<double>(depthFrame.getTimestamp()) * 1e-6;       // microseconds
  if (f.timestamp <= d.lastTimestamp) f.timestamp = d.lastTimestamp + 1e-6;  // keep the contract: increasing
  d.lastTimestamp = f.timestamp;

  RgbdFrame r;
  const int dw = depthFrame.getWidth(), dh = depthFrame.getHeight();
  const auto fmt = depthFrame.getVideoMode().getPixelFormat();
  const double unit = fmt == openni::PIXEL_FORMAT_DEPTH_100_UM ? 1e-4 : 1e-3;
  const cv::Mat raw(dh, dw, CV_16UC1, const_cast<void*>(depthFrame.getData()), depthFrame.getStrideInBytes());
  raw.convertTo(r.depth, CV_32F, unit);
  if (d.flipDepth) cv::flip(r.depth, r.depth, 1);
  if (d.hasColour) {
    const cv::Mat rgb(colourFrame.getHeight(), colourFrame.getWidth(), CV_8UC3,
                      const_cast<void*>(colourFrame.getData()), colourFrame.getStrideInBytes());
    r.colour = rgb.clone();
    if (d.flipColour) cv::flip(r.colour, r.colour, 1);
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
