// mrgi import-visp: turns a ViSP RGB-D AprilTag sequence (colour_image_NNNN.png, depth_image_NNNN.npz with
// uint16 millimetres, cam.json intrinsics, apriltag_data.json tag size) into an mrgi session.
#include <cstdio>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "capture/error.h"
#include "capture/session.h"
#include "capture/visp_folder.h"

namespace mrgi::app {
namespace {

struct ImportOptions {
  std::string input, out, family = "tag36h11";
  int tagId = 3;
  double fps = 30.0;
};

int runImport(const ImportOptions& o) {
  checkTagId(o.family, o.tagId, "--tag-id");
  const capture::VispFolder folder(o.input);
  capture::SessionManifest m;
  m.colour = folder.intrinsics();
  m.depth = m.colour;  // depth is already aligned to colour (depth_M_color = identity)
  m.depthUnitsMetres = 0.001;
  m.marker = capture::MarkerSpec{o.family, folder.tagSize(), o.tagId};
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
