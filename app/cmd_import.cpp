// mrgi import-visp: turns a ViSP RGB-D AprilTag sequence (colour_image_NNNN.png, depth_image_NNNN.npz with
// uint16 millimetres, cam.json intrinsics, apriltag_data.json tag size) into an mrgi session.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"
#include "capture/npz.h"
#include "capture/session.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::app {
namespace {

struct ImportOptions {
  std::string input, out, family = "tag36h11";
  int tagId = 3;
  double fps = 30.0;
};

json readJson(const fs::path& p) {
  return capture::parseJson(capture::readFileBounded(p.string(), capture::kMaxTextFileBytes, "JSON file"), p.string());
}

int runImport(const ImportOptions& o) {
  checkTagId(o.family, o.tagId, "--tag-id");
  const fs::path dir(o.input);
  const json cam = readJson(dir / "cam.json");
  capture::SessionManifest m;
  const std::string camFile = (dir / "cam.json").string();
  m.colour = {capture::jsonInt(cam, "w", camFile),     capture::jsonInt(cam, "h", camFile),
              capture::jsonNumber(cam, "px", camFile), capture::jsonNumber(cam, "py", camFile),
              capture::jsonNumber(cam, "u0", camFile), capture::jsonNumber(cam, "v0", camFile)};
  m.depth = m.colour;  // depth is already aligned to colour (depth_M_color = identity)
  m.depthUnitsMetres = 0.001;
  double tagSize = 0;
  if (fs::exists(dir / "apriltag_data.json")) {
    const json tags = readJson(dir / "apriltag_data.json");
    if (tags.is_object() && tags.contains("tag_size") && tags["tag_size"].is_number())
      tagSize = tags["tag_size"].get<double>();
  }
  if (!(tagSize > 0)) throw capture::CaptureError((dir / "apriltag_data.json").string(), "no tag_size");
  capture::checkNumber(tagSize, capture::kMinTagSizeM, capture::kMaxTagSizeM, (dir / "apriltag_data.json").string(),
                       "tag_size");
  m.marker = capture::MarkerSpec{o.family, tagSize, o.tagId};
  capture::SessionWriter writer(o.out, m);
  const double scale = capture::jsonNumberOr(cam, "depthScale", 0.001, camFile);
  for (int i = 0;; ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "color_image_%04d.png", i);
    const fs::path colourPath = dir / name;
    if (!fs::exists(colourPath)) break;
    std::snprintf(name, sizeof name, "depth_image_%04d.npz", i);
    const cv::Mat raw = capture::readNpzArray((dir / name).string(), "data.npy");
    if (raw.type() != CV_16UC1 || raw.cols != m.colour.width || raw.rows != m.colour.height)
      throw capture::CaptureError((dir / name).string(), "expected a " + std::to_string(m.colour.width) + "x" +
                                                             std::to_string(m.colour.height) + " uint16 depth array");
    capture::Frame f;
    f.index = i;
    f.timestamp = i / o.fps;
    capture::RgbdFrame rgbd;
    rgbd.colour = capture::readColour(colourPath.string());
    raw.convertTo(rgbd.depth, CV_32F, scale);
    rgbd.colourIntrinsics = rgbd.depthIntrinsics = m.colour;
    f.rgbd = rgbd;
    writer.append(f);
  }
  if (writer.framesWritten() == 0)
    throw capture::CaptureError(o.input, "no color_image_0000.png: not a ViSP RGB-D sequence");
  std::printf("imported %lld frames into %s\n", static_cast<long long>(writer.framesWritten()), o.out.c_str());
  return 0;
}

}  // namespace

Action addImportVisp(CLI::App& app) {
  auto o = std::make_shared<ImportOptions>();
  app.add_option("DIR", o->input, "ViSP RGB-D sequence folder (e.g. ../shared/data/rgbd-visp-apriltag)")->required();
  app.add_option("--out", o->out, "new session directory")->required();
  app.add_option("--tag-id", o->tagId, "AprilTag id that anchors the scene (default 3: seen in every frame)");
  app.add_option("--family", o->family, "AprilTag family")->check(tagFamily());
  return [o] { return runImport(*o); };
}

}  // namespace mrgi::app
