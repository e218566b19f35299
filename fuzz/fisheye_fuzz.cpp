// A session's fisheye frame ("lights": "fisheye"): the input is the image file (the first byte picks the
// name it is stored under: .exr, .hdr or .png), read as the session reader reads fisheye frames into a
// 32x24 session whose manifest holds a fisheye calibration of that size, then turned into lights as the
// frame pipeline does (linear radiance, solid angles, median cut with an SH remainder). Bad input must be an
// InputError; lights from an accepted image must be finite.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "capture/session.h"
#include "fuzz/fuzz_common.h"
#include "reconstruction/light_estimation.h"

namespace fs = std::filesystem;

namespace {
const fs::path& session() {
  static const fs::path dir = [] {
    const fs::path d = mrgi::fuzz::scratchDir("mrgi_fuzz_fisheye");
    fs::create_directories(d / "fisheye");
    std::ofstream(d / "manifest.json") << R"({"format": "mrgi-session", "version": 1,
      "colour": {"width": 32, "height": 24, "fx": 30, "fy": 30, "cx": 15.5, "cy": 11.5},
      "depth": {"width": 32, "height": 24, "fx": 30, "fy": 30, "cx": 15.5, "cy": 11.5, "units_m": 0.001},
      "fisheye": {"width": 32, "height": 24, "model": "equidistant", "K": [8, 0, 15.5, 0, 8, 11.5, 0, 0, 1], "D": [0, 0, 0, 0]}})";
    return d;
  }();
  return dir;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* kNames[] = {"fisheye/000000.exr", "fisheye/000000.hdr", "fisheye/000000.png"};
  const char* name = kNames[data[0] % 3];
  const fs::path& dir = session();
  std::ofstream(dir / name, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
  std::ofstream(dir / "frames.jsonl", std::ios::trunc) << R"({"index": 0, "t": 0, "fisheye": ")" << name << "\"}\n";
  mrgi::fuzz::expectInputErrorOnly([&] {
    mrgi::capture::SessionSource source(dir.string());
    const auto frame = source.next();
    if (!frame || !frame->fisheye) return;
    const mrgi::capture::FisheyeFrame& f = *frame->fisheye;
    const auto rays = mrgi::reconstruction::fisheyeRays(f.calibration);
    mrgi::reconstruction::LightSplitOptions so;
    so.medianCut.count = 4;
    const auto split =
        mrgi::reconstruction::splitLights(mrgi::reconstruction::linearRadiance(f.image, f.exposure), rays, so);
    for (const auto& l : split.lights)
      for (int c = 0; c < 3; ++c)
        if (!std::isfinite(l.power[c]) || !std::isfinite(l.direction[c]))
          std::abort();  // lights from an accepted image
    for (const auto& c : split.ambientSh)
      for (int k = 0; k < 3; ++k)
        if (!std::isfinite(c[k])) std::abort();
  });
  return 0;
}
