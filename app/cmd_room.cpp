// mrgi room: builds the persistent model of the real room from a recording (every frame's filtered depth
// fused with its marker pose) and saves it as ROOM/room.ply + ROOM/room.json.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "app/cli_checks.h"
#include "app/commands.h"
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

using nlohmann::json;
namespace fs = std::filesystem;

namespace mrgi::app {
namespace {

struct RoomCliOptions {
  std::string source, out;
  PoseMode pose = PoseMode::Tracked;
  int frames = 0;
  int every = 1;
  int trackEvery = 0;
  bool noOptimise = false;
  reconstruction::RoomOptions room;
  bool json = false;
};

int runRoom(const RoomCliOptions& o) {
  if (o.room.truncM < 2 * o.room.voxelM)
    throw FlagError("--trunc", "must be at least 2 voxels (2 x --voxel = " + capture::formatNumber(2 * o.room.voxelM) +
                                   " m), not " + capture::formatNumber(o.room.truncM));
  o.room.validate("mrgi room");
  auto source = capture::open(o.source);
  const capture::SourceInfo& info = source->info();
  if (!info.hasRgbd) throw capture::CaptureError(o.source, "has no RGB-D frames to build a room from");
  const LightingSetup setup = markerSetup(*source);
  if (o.pose == PoseMode::GroundTruth && !setup.T_world_marker)
    throw capture::CaptureError(o.source, "--pose ground-truth needs ground_truth.T_world_marker in the manifest");
  prepareOutputDirectory(o.out, "room.json", "mrgi room");

  ProgressBar bar("room");
  const int64_t total = info.frameCount ? *info.frameCount : -1;
  const int64_t limit = o.frames > 0 ? (total >= 0 ? std::min<int64_t>(o.frames, total) : o.frames) : total;
  runtime::RoomFusionOptions fo;
  fo.pose = o.pose;
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
  const reconstruction::RoomMesh mesh = runtime::saveRoomModel(o.out, room, o.source);
  if (mesh.positions.empty()) throw capture::CaptureError(o.source, "the fused room has no surface");
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
                        {"per_frame", fusion.perFrame}};
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
      "wrote %s: %zu vertices, %zu triangles, %zu blocks (%.0f MiB of voxels) from %d of %lld frames; fusion %.1f ms "
      "median, %.1f ms with the depth filter\n",
      o.out.c_str(), mesh.positions.size(), mesh.triangleCount(), room.blocks(),
      static_cast<double>(room.bytes()) / (1 << 20), room.framesIntegrated(), static_cast<long long>(seen),
      fusion.medianFuseMs(), fusion.medianSurfaceMs());
  return 0;
}

struct RoomLightsCliOptions {
  std::string room;
  std::vector<double> at{0, 0, 0.06};
  int count = 4;
  double gain = 0, whiteAlbedo = 0.8;
  std::string map;
  bool json = false;
};

int runRoomLights(const RoomLightsCliOptions& o) {
  checkReplaceable(o.map, "--map", "mrgi room-lights");
  const reconstruction::RoomMesh room = reconstruction::loadRoom(o.room);
  reconstruction::RoomLightOptions ro;
  ro.split.medianCut.count = o.count;
  ro.saturatedGain = o.gain;
  ro.whiteAlbedo = o.whiteAlbedo;
  const cv::Vec3d at(o.at[0], o.at[1], o.at[2]);
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
  const json out = {{"at", o.at},
                    {"lights", lights},
                    {"ambient_radiance", {l.ambientRadiance[0], l.ambientRadiance[1], l.ambientRadiance[2]}},
                    {"ambient_sh", sh},
                    {"saturated_gain", l.gain},
                    {"gain_estimated", l.gainEstimated},
                    {"gain_samples", l.gainSamples},
                    {"saturated_fraction", l.saturatedFraction},
                    {"over_exposed", l.overExposed},
                    {"coverage", l.coverage}};
  if (!o.map.empty()) writePng(o.map, runtime::roomLightsImage(l), "mrgi room-lights");
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
      std::printf("  %s at (%.3f, %.3f, %.3f), irradiance %.4g\n", x.point ? "point" : "directional", x.position[0],
                  x.position[1], x.position[2], capture::luminance(x.irradiance));
  }
  return 0;
}

}  // namespace

Action addRoomLights(CLI::App& app) {
  auto o = std::make_shared<RoomLightsCliOptions>();
  app.add_option("room", o->room, "room folder (mrgi room)")->required();
  app.add_option("--at", o->at, "where the virtual object will be, marker frame (metres)")
      ->expected(3)
      ->check(numberIn(-1e4, 1e4))
      ->capture_default_str();
  app.add_option("--count", o->count, "lights from the split")->check(numberIn(1, 16))->capture_default_str();
  app.add_option("--gain", o->gain, "gain on saturated radiance (0 = estimate from the white-patch assumption)")
      ->check(numberIn(0.0, 1e4))
      ->capture_default_str();
  app.add_option("--white-albedo", o->whiteAlbedo, "the white patch's albedo for the estimate")
      ->check(numberIn(0.05, 1.0))
      ->capture_default_str();
  app.add_option("--map", o->map, "write the room's environment at that point (lat-long PNG, lights circled)");
  app.add_flag("--json", o->json, "print one JSON object");
  return [o] { return runRoomLights(*o); };
}

Action addRoom(CLI::App& app) {
  auto o = std::make_shared<RoomCliOptions>();
  app.add_option("source", o->source, "recording to build the room from (session, TUM sequence, .oni file)")
      ->required();
  app.add_option("--out", o->out, "room folder to write (room.ply, room_appearance.npy, room.json)")->required();
  addPoseOption(app, o->pose);
  app.add_option("--frames", o->frames, "read at most N frames (0 = all)")->check(numberIn(0, 1e9));
  app.add_option("--every", o->every, "integrate every Nth frame")->check(numberIn(1, 1e6));
  app.add_option(
         "--track-every", o->trackEvery,
         "with odometry or tracked poses, align the next frames with the room fused so far, its surface taken anew "
         "every N fused frames (0 = keyframes only: on the bundled sessions, whose marker is in view, every 2 or 5 "
         "frames moved the room 2.0 -> 2.4-2.8 mm (synth), 7.0 -> 6.6 (pt), 4.2 -> 5.9-7.8 (hdr) from the true one)")
      ->check(numberIn(0, 1e6))
      ->capture_default_str();
  app.add_flag("--no-optimise", o->noOptimise,
               "with odometry or tracked poses, fuse each frame at the tracker's pose instead of optimising the whole "
               "trajectory first (a pose graph of odometry, loop-closure and marker edges; off with --track-every)");
  app.add_option("--voxel", o->room.voxelM, "voxel edge in metres")->check(numberIn(0.002, 0.2))->capture_default_str();
  app.add_option("--trunc", o->room.truncM, "truncation distance of the signed distance, metres (at least 2 voxels)")
      ->check(numberIn(0.004, 1.0))
      ->capture_default_str();
  app.add_option("--max-blocks", o->room.maxBlocks, "memory budget in voxel blocks of 16^3 voxels")
      ->check(numberIn(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--max-depth", o->room.maxDepthM, "depth beyond this (metres) is not integrated")
      ->check(numberAbove(0.1, 20))
      ->capture_default_str();
  app.add_option("--outlier", o->room.outlierM,
                 "a frame is not integrated when more than 30 % of its points in observed space lie farther than this "
                 "(metres) from the model (its pose disagrees)")
      ->check(numberAbove(0, 1))
      ->capture_default_str();
  app.add_flag("--json", o->json, "print one JSON object (per-frame integration, blocks, timing) instead of lines");
  return [o] { return runRoom(*o); };
}

}  // namespace mrgi::app
