#include <iostream>
#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "capture/frame_source.h"
#include "runtime/source.h"

namespace mrgi::app {

namespace {
nlohmann::json intrinsicsJson(const capture::Intrinsics& k) {
  return {{"width", k.width}, {"height", k.height}, {"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}};
}
}  // namespace

Action addInfo(CLI::App& app) {
  auto source = std::make_shared<std::string>();
  app.add_option("SOURCE", *source, "session directory, TUM directory, Open3D RGB-D folder, .oni file or device URI")
      ->required();
  return [source] {
    auto src = runtime::openSource(*source);  // says the source's calibration note, as replay does
    const capture::SourceInfo& info = src->info();
    nlohmann::json j;
    j["source"] = info.uri;
    j["kind"] = info.kind;
    j["frame_count"] = info.frameCount ? nlohmann::json(*info.frameCount) : nlohmann::json(nullptr);
    j["colour_resolution"] = {info.colourIntrinsics.width, info.colourIntrinsics.height};
    j["depth_resolution"] = {info.depthIntrinsics.width, info.depthIntrinsics.height};
    j["colour_intrinsics"] = intrinsicsJson(info.colourIntrinsics);
    j["depth_intrinsics"] = intrinsicsJson(info.depthIntrinsics);
    j["has_fisheye"] = info.hasFisheye;
    j["has_ground_truth"] = info.hasGroundTruth;
    std::cout << j.dump() << std::endl;
    return 0;
  };
}

}  // namespace mrgi::app
