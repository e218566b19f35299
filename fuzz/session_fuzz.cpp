// A whole recorded session: manifest.json and frames.jsonl from the input (split at the first NUL byte;
// without one the input is frames.jsonl under a fixed manifest), frame images from a small valid set, then
// the session opened and every frame read as replay does.
#include <filesystem>
#include <opencv2/core.hpp>

#include "capture/image_io.h"
#include "capture/session.h"
#include "fuzz/fuzz_common.h"

namespace fs = std::filesystem;

namespace {

/// The session folder of this process: colour and depth PNGs of three 80x60 frames (a gradient, a plane).
const fs::path& sessionDir() {
  static const fs::path dir = [] {
    const fs::path d = mrgi::fuzz::scratchDir("mrgi_fuzz_session");
    fs::create_directories(d / "colour");
    fs::create_directories(d / "depth");
    for (int i = 0; i < 3; ++i) {
      cv::Mat colour(60, 80, CV_8UC3), depth(60, 80, CV_16UC1);
      for (int y = 0; y < 60; ++y)
        for (int x = 0; x < 80; ++x) {
          colour.at<cv::Vec3b>(y, x) = cv::Vec3b(uchar(3 * x), uchar(4 * y), uchar(40 * i));
          depth.at<uint16_t>(y, x) = static_cast<uint16_t>(800 + 5 * y + 100 * i);
        }
      char name[32];
      std::snprintf(name, sizeof name, "%06d.png", i);
      mrgi::capture::writeFileAtomically(d / "colour" / name, mrgi::capture::encodePng(colour, name));
      mrgi::capture::writeFileAtomically(d / "depth" / name, mrgi::capture::encodePng(depth, name));
    }
    return d;
  }();
  return dir;
}

const char* kManifest = R"({"version": 1, "format": "mrgi-session",
  "colour": {"width": 80, "height": 60, "fx": 65.6, "fy": 65.6, "cx": 39.5, "cy": 29.5},
  "depth": {"width": 80, "height": 60, "fx": 65.6, "fy": 65.6, "cx": 39.5, "cy": 29.5, "units_m": 0.001, "registered": true,
            "T_colour_depth": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}})";

void write(const fs::path& p, const char* data, size_t size) {
  std::ofstream(p, std::ios::binary | std::ios::trunc).write(data, static_cast<std::streamsize>(size));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const fs::path& dir = sessionDir();
  const char* text = reinterpret_cast<const char*>(data);
  const auto* nul = static_cast<const uint8_t*>(std::memchr(data, 0, size));
  if (nul) {
    const size_t at = static_cast<size_t>(nul - data);
    write(dir / "manifest.json", text, at);
    write(dir / "frames.jsonl", text + at + 1, size - at - 1);
  } else {
    write(dir / "manifest.json", kManifest, std::strlen(kManifest));
    write(dir / "frames.jsonl", text, size);
  }
  mrgi::fuzz::expectInputErrorOnly([&] {
    mrgi::capture::SessionSource source(dir.string());
    for (int n = 0; n < 8 && source.next(); ++n) {
    }
  });
  return 0;
}
