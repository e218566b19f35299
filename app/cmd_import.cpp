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
#include "capture/session.h"
#include "capture/visp_folder.h"

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
  const capture::VispFolder folder(o.input);
  capture::SessionManifest m;
  m.colour = folder.intrinsics();
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
  for (int i = 0;; ++i) {
    std::optional<capture::Frame> f = folder.frame(i, o.fps);
    if (!f) break;
    writer.append(*f);
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
