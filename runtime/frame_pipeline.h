#pragma once
// The per-frame work every application shares (replay, insert, live): camera pose, filtered depth, estimated
// lights and albedo, real mesh, lighting and compositing of one RGB-D frame. What lights the frames is
// runtime/lighting_setup.h, what a frame carries runtime/frame_data.h, reading ahead runtime/read_ahead.h.
#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame_source.h"
#include "capture/ground_truth.h"
#include "compositor/compositor.h"
#include "gl/profiler.h"
#include "lighting/pipeline.h"
#include "lighting/scene_file.h"
#include "reconstruction/light_estimation.h"
#include "reconstruction/marker.h"
#include "reconstruction/mesh_rays.h"
#include "reconstruction/room_lights.h"
#include "reconstruction/room_model.h"
#include "runtime/frame_data.h"
#include "runtime/lighting_setup.h"
#include "runtime/pose_source.h"
#include "runtime/read_ahead.h"

namespace mrgi::runtime {

/// The GPU memory a frame pipeline may take: MRGI_GPU_BUDGET_MB (MiB) when set, else 4096 MiB.
size_t gpuBudgetBytes();

struct FrameOptions {
  PoseMode pose = PoseMode::Tracked;  ///< where each frame's camera pose comes from (runtime/pose_source.h)
  TrackingOptions tracking;
  /// A scene whose world a recording's first frame founded: found it anew on this source's first frame (a live
  /// camera) instead of placing the first frame where the recording's was.
  bool foundWorldAnew = false;
  int meshStride = 2;
  bool gpu = true;  ///< false: measure() and realSurface() only, no lighting pipeline (no GL context needed)
  /// Skip work whose inputs did not change: while the camera stays put (pose within 1 mm and 0.1 degree of
  /// the frame the real surface was built from) and the colour image has not changed (mean change of a
  /// 32x24 thumbnail below 1 %), the real surface (filtered depth, normals, albedo, mesh, the techniques' own inputs)
  /// is kept and the camera pose snaps to that frame's; the lighting pipeline skips its own unchanged stages.
  bool reuse = true;
  /// The fused model of the room (mrgi room, in the marker frame): when set, it is the real scene of the
  /// lighting (G-buffer, RSMs, shadows) instead of each frame's depth mesh, with its albedo estimated once
  /// per set of lights; the per-frame albedo and depth mesh are not computed.
  std::shared_ptr<const reconstruction::RoomMesh> room;
  /// Build the room as the frames arrive (live, replay --fuse-room): every frame with a pose is fused into
  /// this model (shared: a pipeline rebuilt with new knobs keeps fusing into it), and its surface becomes
  /// `room` on the pipeline's first such frame and then every `fuseRefresh` frames fused (the albedo, the lights
  /// from the room and the techniques' inputs from it follow). Null: none.
  std::shared_ptr<reconstruction::RoomModel> fuse;
  int fuseRefresh = 30;
  /// With `fuse`: every `fuseEvery`-th frame with a pose is fused, from the first (1: every one): fusion's cost
  /// a frame for views left out. The refreshes come every `fuseRefresh` frames fused.
  int fuseEvery = 1;
  /// With `fuse` and odometry or tracked poses: each refreshed surface becomes what the next frames are
  /// aligned with first (frame-to-model, PoseSource::useModel), handed to the measuring thread between frames.
  /// Off by default: on the bundled sessions (marker in view) it placed frames worse than the keyframes
  /// (ATE 5.95 -> 10.0 mm on tabletop-pt; Tracking.ARoomFusedAsTheFramesComeIsTrackedAgainst).
  bool trackFusedRoom = false;
  /// Each technique's facts of a frame (counts, mean irradiance, flicker) in FrameResult::info["techniques"].
  /// Some are read back from the GPU: a frame loop that writes and shows none turns them off. (Whether the
  /// composite is read back is the compositor's setting: compositor::Compositor::setReadback.)
  bool techniqueStats = true;
  /// Progress of a technique's long precompute (lighting::PipelineConfig::progress); may be empty.
  std::function<void(const std::string& what, double fraction)> progress;
  /// Where techniques keep their precomputed data between runs (a saved room's folder); empty: nowhere.
  std::string cacheDir;
};

class FramePipeline {
 public:
  /// Without a setup frames are only decoded and composited as background.
  FramePipeline(std::optional<LightingSetup> setup, int width, int height, const FrameOptions& options);
  ~FramePipeline();
  /// Processes one frame (registers its depth if needed) inside the current GL context: prepare, then render.
  FrameResult process(capture::Frame& frame, compositor::Compositor& compositor, gl::Profiler& profiler);
  /// The CPU half of process(): measure(), then the real surface and the techniques' own inputs from the frame's depth.
  /// It touches neither GL nor anything render() reads, so a frame loop may prepare frame n + 1 on another thread while
  /// render() works on frame n (frames prepared in order; `profiler` then one of that thread's own, CPU stages only).
  /// With FrameOptions::fuse it only measures: fusion refreshes what render() reads.
  PreparedFrame prepare(capture::Frame& frame, gl::Profiler& profiler);
  /// The GL half of process(): a prepared frame lit and composited (background only without a marker pose).
  void render(const capture::Frame& frame, PreparedFrame& p, compositor::Compositor& compositor,
              gl::Profiler& profiler);
  /// The measuring half: registration, fisheye lights, marker pose, filtered depth, normals.
  FrameResult measure(capture::Frame& frame, gl::Profiler& profiler);
  /// The next frame's camera pose alone (depth registered, then the pose source; no depth filter or normals):
  /// for a pass that only needs the trajectory. Frames in order, as measure().
  CameraPose locatePose(capture::Frame& frame, gl::Profiler& profiler);
  /// A measured frame rendered: albedo, real mesh, lighting, composite (prepare()'s rest, then render()).
  void render(const capture::Frame& frame, FrameResult& r, compositor::Compositor& compositor, gl::Profiler& profiler);
  /// Albedo and real mesh of a measured frame with a marker pose (what prepare() adds to measure()).
  RealSurface realSurface(const capture::Frame& frame, const FrameResult& r, gl::Profiler& profiler) const;
  lighting::LightingPipeline* lighting() { return pipeline_.get(); }
  /// Where the frames' camera poses come from (null without a setup).
  const PoseSource* poses() const { return poses_.get(); }
  /// Replaces where the next frames' poses come from (a trajectory decided beforehand: makeGivenPoseSource).
  void usePoses(std::unique_ptr<PoseSource> poses) { poses_ = std::move(poses); }
  /// The room the pose source aligns the next frames with (PoseSource::useModel); only between frames, on the
  /// thread that measures them.
  void trackAgainst(std::shared_ptr<const reconstruction::RoomMesh> room) {
    if (poses_) poses_->useModel(std::move(room));
  }
  const LightingSetup* setup() const { return setup_ ? &*setup_ : nullptr; }
  /// The lights estimated from the room ("lights": "room"), else null.
  const reconstruction::RoomLights* roomLights() const { return roomLightEstimate_.get(); }
  /// The room model (FrameOptions::room), else null; its albedo per vertex under the current lights (empty
  /// until a frame has been lit from the room); rays against the whole room (built on first use).
  const reconstruction::RoomMesh* room() const { return options_.room.get(); }
  const std::vector<cv::Vec3f>& roomAlbedo() const { return roomAlbedo_; }
  const reconstruction::MeshRays& roomRays();
  /// The room being fused (FrameOptions::fuse), else null; every frame handed to the fusion thread is fused into it
  /// first (finishFusion).
  const reconstruction::RoomModel* liveRoom() const;
  /// Waits until every frame prepared so far is fused (FrameOptions::fuse): the room is then this thread's to read.
  void finishFusion() const;

 private:
  void estimateLights(const capture::Frame& frame, FrameResult& r, gl::Profiler& profiler);
  void locate(const capture::Frame& frame, FrameResult& r, gl::Profiler& profiler);

  std::optional<LightingSetup> setup_;
  FrameOptions options_;
  std::unique_ptr<lighting::LightingPipeline> pipeline_;
  std::optional<reconstruction::FisheyeRays> fisheyeRays_;
  std::optional<reconstruction::FisheyeRays> worldFisheyeRays_;  ///< the same rays in the lighting world
  std::unique_ptr<PoseSource> poses_;
  /// The builders of the techniques' own inputs (technique name, builder; they may fuse over frames).
  std::vector<std::pair<std::string, std::unique_ptr<lighting::TechniqueInputBuilder>>> inputBuilders_;
  /// The frame the lighting pipeline's real surface was built from (FrameOptions::reuse).
  struct SurfaceCache {
    capture::Pose T_marker_camera;
    cv::Mat thumbnail, positions, normals;
  };
  std::optional<SurfaceCache> surfaceCache_;
  /// The lights the room's albedo was estimated under (FrameOptions::room): re-estimated when they change.
  std::optional<std::vector<lighting::SceneLight>> roomLights_;
  std::vector<cv::Vec3f> roomAlbedo_;  ///< per room vertex, under roomLights_
  std::vector<reconstruction::AlbedoStatus> roomAlbedoStatus_;
  /// The room albedo's shadow rays kept between refreshes of a fused room: a refresh casts what changed.
  std::shared_ptr<reconstruction::RoomAlbedoCache> roomAlbedoCache_;
  std::vector<uint32_t> roomIndices_;  ///< the room's triangles the lighting sees (none around point lights)
  bool roomInputsSet_ = false;         ///< the techniques' own inputs are built from the room for roomIndices_
  struct RoomIndex;                    ///< nearest room vertex of a point (the view mesh's albedo)
  std::shared_ptr<RoomIndex> roomIndex_;
  std::shared_ptr<reconstruction::MeshRays> roomRays_;
  /// The fusion thread's: frames fused since the room's surface was last refreshed, and whether it has one.
  int framesSinceRefresh_ = 0;
  int64_t fuseOffered_ = 0;  ///< frames fuseFrame() could have fused (FrameOptions::fuseEvery), its thread's
  bool fusedSurface_ = false;
  /// render()'s view of the same, from the fused frames it has taken up (frames in order): whether the next one
  /// may refresh the surface, and so must be fused before it is lit.
  int takenSinceRefresh_ = 0;
  bool takenSurface_ = false;
  /// A refreshed fused room for the pose source, from the thread that fuses to the one that measures.
  std::mutex pendingModelMutex_;
  std::shared_ptr<const reconstruction::RoomMesh> pendingModel_;
  /// FrameOptions::fuse: the measured frame handed to the fusion thread, which fuses it into the live room and
  /// refreshes the room's surface when due (fuse()).
  void fuseFrame(const capture::RgbdFrame& rgbd, PreparedFrame& p, gl::Profiler& profiler);
  FusedFrame fuse(const cv::Mat& depth, const cv::Mat& colour, const capture::Intrinsics& k,
                  const capture::Pose& T_marker_camera, double exposure);
  /// Whether the next frame fused, if it is integrated, refreshes the room's surface: there is none yet, or it
  /// is the fuseRefresh-th since the last refresh. The fusion thread decides by it, and render() by the same
  /// rule on its own count whether a frame must be fused before it is lit.
  bool mayRefresh(bool hasSurface, int fusedSinceRefresh) const;
  /// The frame's fusion taken up by render(): its facts, stages and refreshed surface (waits for it).
  void takeFused(PreparedFrame& p, gl::Profiler& profiler);
  /// render()'s work on a frame, its fusion taken up before (when it may refresh the room) or after.
  void renderFrame(const capture::Frame& frame, PreparedFrame& p, compositor::Compositor& compositor,
                   gl::Profiler& profiler);
  /// A refreshed surface of the room being fused becomes the room the frames are lit by (render's thread).
  void useRefreshedRoom(std::shared_ptr<const reconstruction::RoomMesh> mesh, FrameResult& r);
  void useRoom(const PreparedFrame& p, nlohmann::json& info, gl::Profiler& profiler);
  /// The real surface (and the techniques' own inputs) of a frame lit from its own depth, unless it has one, its last
  /// one holds, or a room lights it; keeps the reuse cache.
  void buildSurface(const capture::Frame& frame, PreparedFrame& p, gl::Profiler& profiler);
  /// "lights": "room": the lights and ambient from the room model, once (the room is static).
  void estimateRoomLights();
  /// An SH remainder of estimated lights as this pipeline's ambient: band 0 uniform, bands 1-2 directional; with
  /// its lat-long map (a room's), what the objects hide of it is read from the map.
  void useAmbientSh(const std::array<cv::Vec3d, 9>& sh, std::shared_ptr<const lighting::RadianceMap> map);
  /// The setup's lights and ambient as they are now, for a frame to be lit under.
  void takeLights(PreparedFrame& p) const;
  /// The lights come from the room (estimated by the rendering thread, taken in render()).
  bool litByRoom() const;
  std::shared_ptr<const reconstruction::RoomLights> roomLightEstimate_;
  /// A room fused as the frames come: its vertices when a distant light was last searched for, and the direction
  /// found (measured again, not searched, at the refreshes between).
  size_t distantSearchedAt_ = 0;
  std::optional<cv::Vec3d> distantTowards_;
  cv::Vec3d objectsCentre() const;  ///< the scene's objects' centre, marker frame
  /// The setup's lights and ambient as the albedo estimate takes them, in the frame T_frame_marker maps to
  /// (the camera for a frame's pixels, the marker frame itself for the room).
  reconstruction::AlbedoLights albedoLights(const capture::Pose& T_frame_marker,
                                            const std::vector<lighting::SceneLight>& lights,
                                            const cv::Vec3d& ambient) const;
  /// The frame's depth mesh, each vertex with the albedo of the nearest room vertex: the G-buffer's real surface.
  void roomViewMesh(const capture::RgbdFrame& rgbd, FrameResult& r, gl::Profiler& profiler);
  cv::Mat thumbnail_;  ///< of the frame being processed
  /// One thread that fuses the prepared frames into the live room in order (FrameOptions::fuse), while the next
  /// frame is measured and this one rendered. Declared last: it finishes and joins before the rest goes.
  class Fuser;
  std::unique_ptr<Fuser> fuser_;
};

}  // namespace mrgi::runtime
