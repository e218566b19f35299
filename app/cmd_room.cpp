// mrgi room: builds the persistent model of the real room from a recording (every frame's filtered depth
// fused with its marker pose) and saves it as ROOM/room.ply + ROOM/room.json.
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "app/output.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/session.h"
#include "reconstruction/room_model.h"
#include "runtime/room_fusion.h"

using nlohmann::json;
namespace fs = std::filesystem;

namespace mrgi::app {
namespace {

struct RoomCliOptions {
  std::string source, out;
  std::string pose = "marker";
  int frames = 0;
  int every = 1;
  reconstruction::RoomOptions room;
  bool json = false;
};

int runRoom(const RoomCliOptions& o) {
  o.room.validate("mrgi room");
  auto source = capture::open(o.source);
  const capture::SourceInfo& info = source->info();
  if (!info.hasRgbd) throw capture::CaptureError(o.source, "has no RGB-D frames to build a room from");
  const LightingSetup setup = markerSetup(*source);
  if (o.pose == "ground-truth" && !setup.T_world_marker)
    throw capture::CaptureError(o.source, "--pose ground-truth needs ground_truth.T_world_marker in the manifest");
  prepareOutputDirectory(o.out, "room.json", "mrgi room");

  ProgressBar bar("room");
  const int64_t total = info.frameCount ? *info.frameCount : -1;
  const int64_t limit = o.frames > 0 ? (total >= 0 ? std::min<int64_t>(o.frames, total) : o.frames) : total;
  RoomFusion fusion = fuseRoom(*source, o.pose, o.room, limit, o.every, [&](const json& line, const reconstruction::RoomModel& model) {
    if (!o.json)
      std::printf("frame %lld: %s%s, %zu blocks\n", static_cast<long long>(line["frame"].get<int64_t>()),
                  line["integrated"].get<bool>() ? "integrated" : "not integrated: ",
                  line.contains("refused") ? line["refused"].get<std::string>().c_str() : "", model.blocks());
    if (limit > 0) bar(static_cast<double>(line["frame"].get<int64_t>() + 1) / static_cast<double>(limit));
  });
  const reconstruction::RoomModel& room = fusion.model;
  const int64_t seen = fusion.frames;
  if (room.framesIntegrated() == 0)
    throw capture::CaptureError(o.source, fusion.posed == 0 ? "no frame has a marker pose: nothing to build a room from"
                                                     : "no frame could be integrated (every pose disagreed or the budget was reached)");
  const reconstruction::RoomMesh mesh = room.mesh();
  if (mesh.positions.empty()) throw capture::CaptureError(o.source, "the fused room has no surface");
  reconstruction::RoomInfo ri;
  ri.options = room.options();
  ri.framesIntegrated = room.framesIntegrated();
  ri.framesRefused = room.framesRefused();
  ri.blocks = room.blocks();
  ri.bytes = room.bytes();
  ri.appearanceBytes = room.appearanceBytes();
  ri.session = fs::absolute(o.source).lexically_normal().string();
  reconstruction::saveRoom(o.out, mesh, ri);
  const json summary = {{"frames", seen},
                        {"integrated", room.framesIntegrated()},
                        {"refused", room.framesRefused()},
                        {"blocks", room.blocks()},
                        {"voxel_mib", static_cast<double>(room.bytes()) / (1 << 20)},
                        {"appearance_mib", static_cast<double>(room.appearanceBytes()) / (1 << 20)},
                        {"saturated_vertices", std::count(mesh.saturated.begin(), mesh.saturated.end(), 1)},
                        {"vertices", mesh.positions.size()},
                        {"triangles", mesh.triangleCount()},
                        {"fuse_ms_median", fusion.medianFuseMs()},
                        {"per_frame", fusion.perFrame}};
  if (o.json)
    std::printf("%s\n", summary.dump().c_str());
  else
    std::printf("wrote %s: %zu vertices, %zu triangles, %zu blocks (%.0f MiB of voxels) from %d of %lld frames; fusion %.1f ms median\n",
                o.out.c_str(), mesh.positions.size(), mesh.triangleCount(), room.blocks(),
                static_cast<double>(room.bytes()) / (1 << 20), room.framesIntegrated(), static_cast<long long>(seen),
                fusion.medianFuseMs());
  return 0;
}

}  // namespace

Action addRoom(CLI::App& app) {
  auto o = std::make_shared<RoomCliOptions>();
  app.add_option("source", o->source, "recording to build the room from (session, TUM sequence, .oni file)")->required();
  app.add_option("--out", o->out, "room folder to write (room.ply, room_appearance.npy, room.json)")->required();
  app.add_option("--pose", o->pose, "camera pose per frame: marker (tracked tag) or ground-truth (the session's)")
      ->check(CLI::IsMember({"marker", "ground-truth"}));
  app.add_option("--frames", o->frames, "read at most N frames (0 = all)")->check(CLI::NonNegativeNumber);
  app.add_option("--every", o->every, "integrate every Nth frame")->check(CLI::PositiveNumber);
  app.add_option("--voxel", o->room.voxelM, "voxel edge in metres")->capture_default_str();
  app.add_option("--trunc", o->room.truncM, "truncation distance of the signed distance, metres (at least 2 voxels)")->capture_default_str();
  app.add_option("--max-blocks", o->room.maxBlocks, "memory budget in voxel blocks of 16^3 voxels")->capture_default_str();
  app.add_option("--max-depth", o->room.maxDepthM, "depth beyond this (metres) is not integrated")->capture_default_str();
  app.add_option("--outlier", o->room.outlierM,
                 "a frame is not integrated when more than 30 % of its points in observed space lie farther than this "
                 "(metres) from the model (its pose disagrees)")
      ->capture_default_str();
  app.add_flag("--json", o->json, "print one JSON object (per-frame integration, blocks, timing) instead of lines");
  return [o] { return runRoom(*o); };
}

}  // namespace mrgi::app
