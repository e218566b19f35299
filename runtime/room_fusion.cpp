#include "runtime/room_fusion.h"

#include <algorithm>
#include <chrono>
#include <filesystem>

#include "capture/error.h"
#include "capture/session.h"
#include "lighting/gl/profiler.h"
#include "runtime/source.h"

namespace mrgi::runtime {

namespace {
double median(std::vector<double> sorted) {
  if (sorted.empty()) return 0.0;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2), sorted.end());
  return sorted[sorted.size() / 2];
}
}  // namespace

double RoomFusion::medianFuseMs() const { return median(fuseMs); }

std::string RoomFusion::clippingNote(const std::string& path) const {
  if (clippedFrames == 0) return {};
  char text[320];
  std::snprintf(text, sizeof text,
                "%s: %lld of %lld frames have more than %.0f %% of their pixels at the sensor's white (up to %.0f %%): "
                "what is brighter (a sunlit patch, a lamp, a window) reads as that white, and the lights found from "
                "it dimmer than they are",
                path.c_str(), static_cast<long long>(clippedFrames), static_cast<long long>(frames),
                100 * kClippedShare, 100 * mostClipped);
  return text;
}

namespace {
/// The share of an 8-bit colour image's pixels with a channel at 250 or more.
double clippedShare(const cv::Mat& colour) {
  if (colour.empty() || colour.type() != CV_8UC3) return 0;
  cv::Mat top;
  cv::reduce(colour.reshape(1, static_cast<int>(colour.total())), top, 1, cv::REDUCE_MAX);
  return cv::countNonZero(top >= 250) / static_cast<double>(colour.total());
}
}  // namespace
double RoomFusion::medianSurfaceMs() const { return median(surfaceMs); }

namespace {

/// A pipeline that only measures frames (camera pose, filtered depth), as fusion needs them.
FramePipeline measuringPipeline(const capture::FrameSource& source, PoseMode pose) {
  const capture::SourceInfo& info = source.info();
  FrameOptions fo;
  fo.pose = pose;
  fo.gpu = false;
  fo.reuse = false;
  return FramePipeline(markerSetup(source), info.colourIntrinsics.width, info.colourIntrinsics.height, fo);
}

/// The tracker's poses of every measured frame (the first pass of an optimised fusion), each posed frame
/// added to the trajectory's graph; then the optimised poses, with the tracker's facts of each frame.
std::vector<CameraPose> optimisedPoses(const std::string& path, const RoomFusionOptions& o, nlohmann::json& facts,
                                       std::vector<std::optional<capture::Pose>>& trackerPoses) {
  auto source = openSource(path, o.open);
  FramePipeline frames = measuringPipeline(*source, o.pose);
  reconstruction::TrajectoryOptions to = o.trajectory;
  to.odometry = FrameOptions{}.tracking.odometry;
  reconstruction::TrajectoryOptimiser graph(to);
  std::vector<CameraPose> poses;
  gl::Profiler profiler;
  for (int64_t index = 0; o.limit < 0 || index < o.limit; ++index) {
    auto frame = source->next();
    if (!frame) break;
    if (index % o.every != 0 || !frame->rgbd) continue;
    const CameraPose pose = frames.locatePose(*frame, profiler);
    const bool posed = pose.tracked() && !pose.held();
    graph.add(reconstruction::OdometryFrame(frame->rgbd->depth, frame->rgbd->colour, frame->rgbd->colourIntrinsics,
                                            to.odometry, frame->rgbd->exposure),
              {posed ? pose.T_world_camera : std::nullopt, pose.markerT_world_camera});
    poses.push_back(pose);
    trackerPoses.push_back(posed ? pose.T_world_camera : std::nullopt);
  }
  const reconstruction::TrajectoryResult t = graph.optimise();
  for (size_t i = 0; i < poses.size(); ++i)
    if (t.T_world_camera[i]) poses[i].T_world_camera = t.T_world_camera[i];
  facts = {{"odometry_edges", t.odometryEdges},
           {"loop_edges", t.loopEdges},
           {"marker_edges", t.markerEdges},
           {"pruned_edges", t.prunedEdges},
           {"refused_alignments", t.refusedAlignments},
           {"mean_shift_m", t.meanShiftM},
           {"max_shift_m", t.maxShiftM}};
  return poses;
}

}  // namespace

RoomFusion fuseRoom(const std::string& path, const RoomFusionOptions& o,
                    const std::function<void(const nlohmann::json&, const reconstruction::RoomModel&)>& onFrame) {
  const bool tracks = o.pose == PoseMode::Odometry || o.pose == PoseMode::Tracked;
  RoomFusion out{reconstruction::RoomModel(o.room), 0, 0, 0, 0, {}, {}, nlohmann::json::array(), {}, nullptr, {}};
  std::optional<std::vector<CameraPose>> given;
  if (o.optimise && tracks && o.trackEvery == 0) {
    nlohmann::json facts;
    given = optimisedPoses(path, o, facts, out.trackerPoses);
    out.trajectory = facts;
  }
  auto source = openSource(path, o.open);
  FramePipeline frames = measuringPipeline(*source, o.pose);
  if (given) frames.usePoses(makeGivenPoseSource(o.pose, *given));
  gl::Profiler profiler;
  while (o.limit < 0 || out.frames < o.limit) {
    auto frame = source->next();
    if (!frame) break;
    const int64_t index = out.frames++;
    if (index % o.every != 0 || !frame->rgbd) continue;
    const double clipped = clippedShare(frame->rgbd->colour);
    out.clippedFrames += clipped > RoomFusion::kClippedShare;
    out.mostClipped = std::max(out.mostClipped, clipped);
    const FrameResult r = frames.measure(*frame, profiler);
    // What the frame's depth cost before fusion: the guided filter and the normals.
    double filterMs = 0;
    for (const auto& [stage, t] : profiler.resolve())
      if (stage == "depth_filter" || stage == "normals") filterMs += t.cpuMs;
    nlohmann::json line = {{"frame", index}, {"pose", r.pose.facts()}};
    out.poses.push_back(r.T_marker_camera && !r.positions.empty() && !r.pose.held() ? r.T_marker_camera : std::nullopt);
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
      const auto result = out.model.integrate(depth, frame->rgbd->colour, frame->rgbd->colourIntrinsics,
                                              *r.T_marker_camera, frame->rgbd->exposure);
      out.fuseMs.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      out.surfaceMs.push_back(filterMs + out.fuseMs.back());
      line["integrated"] = result.integrated;
      // Frame-to-model: the poses of the next frames are aligned with the room fused so far, its surface
      // taken anew every `trackEvery` fused frames.
      if (!given && result.integrated && o.trackEvery > 0 && tracks &&
          out.model.framesIntegrated() % o.trackEvery == 0) {
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

bool fusesRecordingFirst(const LightingSetup& setup, const RoomOptions& rooms, bool roomGiven) {
  return setup.scene.lightSource == lighting::LightSource::Room && !roomGiven && rooms.fuse && !rooms.fuseAsked &&
         !rooms.perFrameMesh;
}

std::shared_ptr<const reconstruction::RoomMesh> fuseWholeRecording(
    const std::string& path, PoseMode pose, const capture::OpenOptions& open, RoomFusion* fused,
    const std::function<void(const nlohmann::json&, const reconstruction::RoomModel&)>& onFrame) {
  RoomFusionOptions o;
  o.pose = pose;
  o.open = open;
  RoomFusion f = fuseRoom(path, o, onFrame);
  auto mesh = std::make_shared<const reconstruction::RoomMesh>(f.model.mesh());
  if (mesh->positions.empty())
    throw capture::CaptureError(path, "lists no lights and no room could be fused from its frames (" +
                                          std::to_string(f.posed) + " of " + std::to_string(f.frames) +
                                          " posed); list lights in a scene file (--scene)");
  if (const std::string note = f.clippingNote(path); !note.empty()) sayNoteOnce(note);
  if (fused) *fused = std::move(f);
  return mesh;
}

reconstruction::RoomMesh saveRoomModel(const std::string& dir, const reconstruction::RoomModel& room,
                                       const std::string& session) {
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
