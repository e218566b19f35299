#include "app/output.h"

#include <map>
#include <memory>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/error.h"
#include "capture/json_io.h"
#include "capture/image_io.h"

namespace fs = std::filesystem;

namespace mrgi::app {

void writeExr(const std::string& path, const cv::Mat& rgb) {
  capture::writeFileAtomically(path, capture::encodeExr(rgb, false, path));
}

void writePng(const std::string& path, const cv::Mat& rgb) {
  capture::writeFileAtomically(path, capture::encodePng(rgb, path));
}

void createParentDirectory(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent);
}

void prepareOutputDirectory(const std::string& out, const std::string& marker, const std::string& generator) {
  std::error_code ec;
  if (fs::exists(out, ec)) {
    if (!fs::is_directory(out, ec)) throw capture::CaptureError(out, "exists and is not a directory");
    if (!fs::is_empty(out, ec)) {
      // Our own earlier output is recognised by what its marker says, not by its name alone.
      bool ours = false;
      const fs::path m = fs::path(out) / marker;
      if (fs::is_regular_file(m, ec) && fs::file_size(m, ec) < (1u << 26)) {
        std::ifstream in(m);
        try {
          const nlohmann::json j = capture::parseJson(in, m.string());
          ours = j.is_object() && j.contains("generated_by") && j["generated_by"].is_string() &&
                 j["generated_by"].get<std::string>() == generator;
        } catch (const capture::InputError&) {
        }
      }
      if (!ours)
        throw capture::CaptureError(out, "is not empty and holds no earlier output of " + generator + "; refusing to overwrite");
    }
  }
  fs::create_directories(out, ec);
  if (ec) throw capture::CaptureError(out, "cannot create output directory: " + ec.message());
}

void checkInsideOutput(const std::string& name, const std::string& flag) {
  const fs::path p = fs::path(name).lexically_normal();
  if (p.is_absolute() || p.empty() || *p.begin() == "..")
    throw std::invalid_argument(flag + " " + name + ": must be a file name inside --out (nothing is written outside it)");
}

ProgressBar::ProgressBar(std::string label) : label_(std::move(label)), tty_(isatty(fileno(stderr))) {}

ProgressBar::~ProgressBar() {
  if (tty_ && shown_ >= 0) std::fprintf(stderr, "\n");
}

void ProgressBar::operator()(double fraction) {
  const int percent = static_cast<int>(std::clamp(fraction, 0.0, 1.0) * 100.0);
  if (!tty_ || percent == shown_) return;
  shown_ = percent;
  char bar[41];
  for (int i = 0; i < 40; ++i) bar[i] = i < percent * 40 / 100 ? '#' : '.';
  bar[40] = 0;
  std::fprintf(stderr, "\r%s [%s] %3d%%", label_.c_str(), bar, percent);
  std::fflush(stderr);
}

namespace {
std::atomic<bool> gInterrupted{false};
struct sigaction gOldInt, gOldTerm;

void onInterrupt(int) {
  if (gInterrupted.exchange(true)) std::_Exit(130);  // the second Ctrl-C
}
}  // namespace

InterruptGuard::InterruptGuard() {
  gInterrupted = false;
  struct sigaction sa {};
  sa.sa_handler = onInterrupt;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, &gOldInt);
  sigaction(SIGTERM, &sa, &gOldTerm);
}

InterruptGuard::~InterruptGuard() {
  sigaction(SIGINT, &gOldInt, nullptr);
  sigaction(SIGTERM, &gOldTerm, nullptr);
}

bool InterruptGuard::interrupted() { return gInterrupted.load(); }

Mp4Writer::Mp4Writer(std::string path, int width, int height, double fps)
    : path_(std::move(path)), partial_(path_ + ".partial.mp4") {
  writer_ = cv::makePtr<cv::VideoWriter>(partial_, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps, cv::Size(width, height));
  if (!writer_->isOpened()) throw capture::CaptureError(path_, "cannot open an MP4 writer (OpenCV videoio without FFmpeg?)");
}

Mp4Writer::~Mp4Writer() {
  if (writer_) {
    writer_->release();
    std::error_code ec;
    fs::remove(partial_, ec);
  }
}

void Mp4Writer::write(const cv::Mat& rgb) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  writer_->write(bgr);
  ++frames_;
}

int Mp4Writer::close() {
  writer_->release();
  writer_.reset();
  std::error_code ec;
  fs::rename(partial_, path_, ec);
  if (ec) throw capture::CaptureError(path_, "cannot move the finished video into place: " + ec.message());
  return frames_;
}

std::function<void(const std::string& what, double fraction)> precomputeProgress() {
  auto bars = std::make_shared<std::map<std::string, std::unique_ptr<ProgressBar>>>();
  return [bars](const std::string& what, double fraction) {
    auto& bar = (*bars)[what];
    if (!bar) bar = std::make_unique<ProgressBar>(what);
    (*bar)(fraction);
    if (fraction >= 1.0) bar.reset();  // done: the next precompute of this kind draws a new bar
  };
}

}  // namespace mrgi::app
