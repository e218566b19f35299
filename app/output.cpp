#include "app/output.h"

#include <cstdio>
#include <filesystem>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/error.h"
#include "capture/image_io.h"

namespace fs = std::filesystem;

namespace mrgi::app {

void writeExr(const std::string& path, const cv::Mat& rgb) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<uchar> bytes;
  if (!cv::imencode(".exr", bgr, bytes)) throw capture::CaptureError(path, "cannot encode EXR");
  capture::writeFileAtomically(path, bytes);
}

void writePng(const std::string& path, const cv::Mat& rgb) {
  capture::writeFileAtomically(path, capture::encodePng(rgb, path));
}

void createParentDirectory(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent);
}

void prepareOutputDirectory(const std::string& out, const std::string& marker) {
  std::error_code ec;
  if (fs::exists(out, ec)) {
    if (!fs::is_directory(out, ec)) throw capture::CaptureError(out, "exists and is not a directory");
    if (!fs::is_empty(out, ec) && !fs::exists(fs::path(out) / marker, ec))
      throw capture::CaptureError(out, "is not empty and holds no earlier mrgi output; refusing to overwrite");
  }
  fs::create_directories(out, ec);
  if (ec) throw capture::CaptureError(out, "cannot create output directory: " + ec.message());
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

}  // namespace mrgi::app
