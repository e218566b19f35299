#include "runtime/room_build.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "capture/checks.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/session.h"
#include "reconstruction/room_lights.h"
#include "reconstruction/room_model.h"
#include "runtime/debug_view.h"
#include "runtime/output.h"
#include "runtime/room_fusion.h"
#include "runtime/room_preview.h"
#include "runtime/source.h"

using nlohmann::json;
namespace fs = std::filesystem;

namespace mrgi::runtime {

int buildRoom(const BuildRoomOptions& o) {
  if (o.room.truncM < 2 * o.room.voxelM)
    throw capture::FlagError("--trunc",
                             "must be at least 2 voxels (2 x --voxel = " + capture::formatNumber(2 * o.room.voxelM) +
                                 " m), not " + capture::formatNumber(o.room.truncM));
  o.room.validate("mrgi room");
  auto source = openSource(o.source, o.open);
  const capture::SourceInfo info = source->info();  // a copy: the source is closed before the fusion
  if (!info.hasRgbd) throw capture::CaptureError(o.source, "has no RGB-D frames to build a room from");
  const LightingSetup setup = markerSetup(*source);
  if (o.pose == PoseMode::GroundTruth && !setup.T_world_marker)
    throw capture::CaptureError(o.source, "--pose ground-truth needs ground_truth.T_world_marker in the manifest");
  const OutputClaim claim = prepareOutputDirectory(o.out, "room.json", "mrgi room");
  const int64_t total = info.frameCount ? *info.frameCount : -1;
  source.reset();  // the fusion reads the recording itself (a device's recording plays once at a time)

  ProgressBar bar("room");
  const int64_t limit = o.frames > 0 ? (total >= 0 ? std::min<int64_t>(o.frames, total) : o.frames) : total;
  RoomFusionOptions fo;
  fo.pose = o.pose;
  fo.open = o.open;
  fo.room = o.room;
  fo.limit = limit;
  fo.every = o.every;
  fo.trackEvery = o.trackEvery;
  fo.optimise = !o.noOptimise;
  RoomFusion fusion = fuseRoom(o.source, fo, [&](const json& line, const reconstruction::RoomModel& model) {
    if (!o.json)
      std::printf("frame %lld: %s%s, %zu blocks\n", static_cast<long long>(line["frame"].get<int64_t>()),
                  line["integrated"].get<bool>() ? "integrated" : "not integrated: ",
                  line.contains("refused") ? line["refused"].get<std::string>().c_str() : "", model.blocks());
    if (limit > 0) bar(static_cast<double>(line["frame"].get<int64_t>() + 1) / static_cast<double>(limit));
  });
  const reconstruction::RoomModel& room = fusion.model;
  const int64_t seen = fusion.frames;
  if (room.framesIntegrated() == 0)
    throw capture::CaptureError(
        o.source, fusion.posed == 0 ? "no frame has a trusted camera pose (" + std::to_string(fusion.lost) + " lost, " +
                                          std::to_string(fusion.held) + " held): nothing to build a room from"
                                    : "no frame could be integrated (every pose disagreed or the budget was reached)");
  const reconstruction::RoomMesh mesh = saveRoomModel(o.out, room, o.source);
  if (mesh.positions.empty()) throw capture::CaptureError(o.source, "the fused room has no surface");
  // The picture a person looks at: the room from the first fused camera and from above, and its lights.
  std::optional<capture::Pose> firstCamera;
  for (const auto& p : fusion.poses)
    if (p) {
      firstCamera = *p;
      break;
    }
  double coverage = 0;
  const std::string preview = (std::filesystem::path(o.out) / "preview.png").string();
  writePng(preview, roomPreview(mesh, firstCamera, info.colourIntrinsics, {}, &coverage), "mrgi room");
  const json summary = {{"frames", seen},
                        {"integrated", room.framesIntegrated()},
                        {"refused", room.framesRefused()},
                        {"pose", {{"mode", toString(o.pose)}, {"lost", fusion.lost}, {"held", fusion.held}}},
                        {"trajectory", fusion.trajectory},
                        {"blocks", room.blocks()},
                        {"voxel_mib", static_cast<double>(room.bytes()) / (1 << 20)},
                        {"appearance_mib", static_cast<double>(room.appearanceBytes()) / (1 << 20)},
                        {"saturated_vertices", std::count(mesh.saturated.begin(), mesh.saturated.end(), 1)},
                        {"vertices", mesh.positions.size()},
                        {"triangles", mesh.triangleCount()},
                        {"fuse_ms_median", fusion.medianFuseMs()},
                        {"surface_ms_median", fusion.medianSurfaceMs()},
                        {"per_frame", fusion.perFrame},
                        {"preview", preview},
                        {"coverage_at_object", coverage}};
  warnIfRoomCoverageLow(o.out, coverage, "the object's place (0, 0, 0.06)");
  if (fusion.lost + fusion.held > 0)
    std::fprintf(stderr,
                 "warning: %s: %lld of %lld frames not fused for their pose (%lld lost, %lld held: --pose %s)\n",
                 o.source.c_str(), static_cast<long long>(fusion.lost + fusion.held), static_cast<long long>(seen),
                 static_cast<long long>(fusion.lost), static_cast<long long>(fusion.held), toString(o.pose));
  if (o.json) {
    std::printf("%s\n", jsonText(summary, o.source).c_str());
    return 0;
  }
  if (const json& t = fusion.trajectory; !t.is_null())
    std::printf(
        "trajectory optimised: %d odometry, %d loop-closure and %d marker edges (%d pruned); frames moved %.1f mm on "
        "average, "
        "%.1f mm at most\n",
        t["odometry_edges"].get<int>(), t["loop_edges"].get<int>(), t["marker_edges"].get<int>(),
        t["pruned_edges"].get<int>(), 1e3 * t["mean_shift_m"].get<double>(), 1e3 * t["max_shift_m"].get<double>());
  std::printf(
      "room: %zu vertices, %zu triangles, %zu blocks (%.0f MiB of voxels) from %d of %lld frames; fusion %.1f ms "
      "median, %.1f ms with the depth filter\n",
      mesh.positions.size(), mesh.triangleCount(), room.blocks(), static_cast<double>(room.bytes()) / (1 << 20),
      room.framesIntegrated(), static_cast<long long>(seen), fusion.medianFuseMs(), fusion.medianSurfaceMs());
  std::printf("%s: the room from its first camera and from above, and its lights at the object\n", preview.c_str());
  std::printf("wrote %s: %s\n", o.out.c_str(), describeFolder(o.out).c_str());
  return 0;
}

int roomLights(const RoomLightsOptions& o) {
  checkReplaceable(o.map, "--map", "mrgi room-lights");
  const reconstruction::RoomMesh room = reconstruction::loadRoom(o.room);
  reconstruction::RoomLightOptions ro;
  ro.split.medianCut.count = o.count;
  ro.saturatedGain = o.gain;
  ro.whiteAlbedo = o.whiteAlbedo;
  ro.findDistant = true;
  const cv::Vec3d& at = o.at;
  const reconstruction::RoomLights l = reconstruction::estimateRoomLights(room, at, ro);
  json lights = json::array();
  for (const auto& x : l.lights) {
    json j = {{"direction", {x.direction[0], x.direction[1], x.direction[2]}},
              {"irradiance", {x.irradiance[0], x.irradiance[1], x.irradiance[2]}},
              {"saturated_fraction", x.saturatedFraction}};
    if (x.point) {
      j["type"] = "point";
      j["position"] = {x.position[0], x.position[1], x.position[2]};
      j["intensity"] = {x.intensity[0], x.intensity[1], x.intensity[2]};
    } else {
      j["type"] = "directional";
    }
    lights.push_back(j);
  }
  json sh = json::array();
  for (const auto& c : l.ambientSh) sh.push_back({c[0], c[1], c[2]});
  json out = {{"at", {at[0], at[1], at[2]}},
              {"lights", lights},
              {"ambient_radiance", {l.ambientRadiance[0], l.ambientRadiance[1], l.ambientRadiance[2]}},
              {"ambient_sh", sh},
              {"saturated_gain", l.gain},
              {"gain_estimated", l.gainEstimated},
              {"gain_samples", l.gainSamples},
              {"saturated_fraction", l.saturatedFraction},
              {"over_exposed", l.overExposed},
              {"coverage", l.coverage}};
  out["distant_light"] = reconstruction::distantLightFacts(l);
  if (!o.map.empty()) writePng(o.map, roomLightsImage(l), "mrgi room-lights");
  if (o.json) {
    std::printf("%s\n", jsonText(out, o.room).c_str());
  } else {
    std::printf("%zu lights at (%.3f, %.3f, %.3f); saturated gain %.3g (%s); room covers %.0f %% of the view\n",
                l.lights.size(), at[0], at[1], at[2], l.gain,
                l.gainEstimated ? "estimated"
                : l.overExposed ? "over-exposed: not estimated"
                                : "given",
                100 * l.coverage);
    for (const auto& x : l.lights)
      if (x.distant)
        std::printf(
            "  distant, towards (%.3f, %.3f, %.3f), irradiance %.4g%s: not seen, found from the room's shadow "
            "edges (%d of them, %.0f %% agreeing)\n",
            x.direction[0], x.direction[1], x.direction[2], capture::luminance(x.irradiance),
            l.distant->atLeast() ? " (at least: its sunlit patches are clipped)" : "", l.distant->edges,
            100 * l.distant->consistency);
      else if (x.point)
        std::printf("  point at (%.3f, %.3f, %.3f), irradiance %.4g\n", x.position[0], x.position[1], x.position[2],
                    capture::luminance(x.irradiance));
      else  // no surface in its region: it has a direction, no position
        std::printf("  directional, towards (%.3f, %.3f, %.3f) from the point, irradiance %.4g\n", x.direction[0],
                    x.direction[1], x.direction[2], capture::luminance(x.irradiance));
    if (!l.distant) std::printf("  no distant light shows in the room's shadow edges\n");
  }
  return 0;
}

}  // namespace mrgi::runtime
