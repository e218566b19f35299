#include "runtime/room_fusion.h"

#include <algorithm>
#include <chrono>
#include <filesystem>

#include "capture/error.h"
#include "capture/session.h"
#include "lighting/gl/profiler.h"

namespace mrgi::runtime {

LightingSetup markerSetup(const capture::FrameSource& source) {
  LightingSetup setup;
  const capture::SessionManifest* manifest = source.sessionManifest();
  if (manifest && manifest->marker) {
    setup.tagFamily = manifest->marker->family;
    setup.tagSize = manifest->marker->sizeMetres;
    setup.tagId = manifest->marker->id;
    setup.markerGiven = true;
  }
  if (manifest) setup.T_world_marker = manifest->truth.T_world_marker;
  return setup;
}

namespace {
double median(std::vector<double> sorted) {
  if (sorted.empty()) return 0.0;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
  return sorted[sorted.size() / 2];
}
}  // namespace

double RoomFusion::medianFuseMs() const { return median(fuseMs); }
double RoomFusion::medianSurfaceMs() const { return median(surfaceMs); }

RoomFusion fuseRoom(capture::FrameSource& source, PoseMode pose, const reconstruction::RoomOptions& options,
                    int64_t limit, int every, int trackEvery,
                    const std::function<void(const nlohmann::json&, const reconstruction::RoomModel&)>& onFrame) {
  const capture::SourceInfo& info = source.info();
  FrameOptions fo;
  fo.pose = pose;
  fo.gpu = false;
  fo.reuse = false;
  FramePipeline frames(markerSetup(source), info.colourIntrinsics.width, info.colourIntrinsics.height, fo);
  RoomFusion out{reconstruction::RoomModel(options), 0, 0, 0, 0, {}, {}, nlohmann::json::array()};
  gl::Profiler profiler;
  while (limit < 0 || out.frames < limit) {
    auto frame = source.next();
    if (!frame) break;
    const int64_t index = out.frames++;
    if (index % every != 0 || !frame->rgbd) continue;
    const FrameResult r = frames.measure(*frame, profiler);
    // What the frame's depth cost before fusion: the guided filter and the normals.
    double filterMs = 0;
    for (const auto& [stage, t] : profiler.resolve())
      if (stage == "depth_filter" || stage == "normals") filterMs += t.cpuMs;
    nlohmann::json line = {{"frame", index}, {"pose", r.pose.facts()}};
    if (!r.T_marker_camera || r.positions.empty()) {
      line["integrated"] = false;
      line["refused"] = "lost: no trusted camera pose";
      ++out.lost;
    } else if (r.pose.held()) {
      line["integrated"] = false;
      line["refused"] = "held pose: the marker is out of view";
      ++out.held;
    } else {
      ++out.posed;
      const cv::Mat depth = measuredDepth(r);
      const auto t0 = std::chrono::steady_clock::now();
      const auto result = out.model.integrate(depth, frame->rgbd->colour, frame->rgbd->colourIntrinsics, *r.T_marker_camera,
                                                 frame->rgbd->exposure);
      out.fuseMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      out.surfaceMs.push_back(filterMs + out.fuseMs.back());
      line["integrated"] = result.integrated;
      // Frame-to-model: the poses of the next frames are aligned with the room fused so far, its surface
      // taken anew every `trackEvery` fused frames.
      if (result.integrated && trackEvery > 0 && (pose == PoseMode::Odometry || pose == PoseMode::Tracked) &&
          out.model.framesIntegrated() % trackEvery == 0) {
        const auto t1 = std::chrono::steady_clock::now();
        frames.trackAgainst(std::make_shared<const reconstruction::RoomMesh>(out.model.mesh()));
        line["model_ms"] = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();
      }
      if (!result.integrated) line["refused"] = result.refused;
      line["overlap"] = result.overlap;
      line["inconsistent"] = result.inconsistent;
      line["new_blocks"] = result.newBlocks;
      line["fuse_ms"] = out.fuseMs.back();
      line["filter_ms"] = filterMs;
    }
    if (onFrame) onFrame(line, out.model);
    out.perFrame.push_back(std::move(line));
  }
  return out;
}

reconstruction::RoomMesh saveRoomModel(const std::string& dir, const reconstruction::RoomModel& room, const std::string& session) {
  reconstruction::RoomMesh mesh = room.mesh();
  if (mesh.positions.empty()) return mesh;
  reconstruction::RoomInfo ri;
  ri.options = room.options();
  ri.framesIntegrated = room.framesIntegrated();
  ri.framesRefused = room.framesRefused();
  ri.blocks = room.blocks();
  ri.bytes = room.bytes();
  ri.appearanceBytes = room.appearanceBytes();
  ri.session = std::filesystem::absolute(session).lexically_normal().string();
  reconstruction::saveRoom(dir, mesh, ri);
  return mesh;
}

}  // namespace mrgi::runtime
