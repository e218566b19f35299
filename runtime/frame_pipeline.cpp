#include "runtime/frame_pipeline.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <deque>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "capture/colour.h"
#include "capture/error.h"
#include "capture/registration.h"
#include "capture/session.h"
#include "lighting/clipped_real.h"
#include "reconstruction/albedo.h"
#include "reconstruction/depth.h"
#include "reconstruction/depth_filter.h"
#include "reconstruction/point_index.h"
#include "reconstruction/room_bounce.h"
#include "runtime/source.h"

using nlohmann::json;

namespace mrgi::runtime {

size_t gpuBudgetBytes() {
  size_t mb = 4096;
  if (const char* env = std::getenv("MRGI_GPU_BUDGET_MB")) {
    char* end = nullptr;
    const unsigned long long v = std::strtoull(env, &end, 10);
    if (end != env && *end == '\0' && v > 0) mb = static_cast<size_t>(v);
  }
  return mb << 20;
}

FramePipeline::FramePipeline(std::optional<LightingSetup> setup, int width, int height, const FrameOptions& options)
    : setup_(std::move(setup)), options_(options) {
  if (!setup_) return;
  lighting::PipelineConfig pc = lighting::pipelineConfig(setup_->scene, width, height);
  pc.progress = options_.progress;
  pc.cacheDir = options_.cacheDir;
  if (options_.gpu) {
    // Refuse what cannot fit before allocating any of it (a 4096² RSM per light is gigabytes).
    const size_t lights =
        setup_->fisheye ? static_cast<size_t>(setup_->scene.fisheyeLightCount) : setup_->lights.size();
    const size_t need = lighting::estimateGpuBytes(pc, lights), budget = gpuBudgetBytes();
    if (need > budget)
      throw capture::CaptureError(
          setup_->scene.path.empty() ? "scene" : setup_->scene.path,
          "frame.rsm_size " + std::to_string(static_cast<int>(pc.knobs.at("frame").at("rsm_size"))) + " with " +
              std::to_string(lights) + " lights at " + std::to_string(width) + "x" + std::to_string(height) +
              " needs " + std::to_string(need >> 20) + " MiB of GPU memory, more than the " +
              std::to_string(budget >> 20) + " MiB budget (MRGI_GPU_BUDGET_MB)");
    pipeline_ = std::make_unique<lighting::LightingPipeline>(pc, setup_->scene.objects);
    // The room's environment is ray cast from the objects' centre over the whole sphere: it holds what every
    // real surface sends them, bounce included. (A fisheye's hemisphere looks up from elsewhere and misses
    // the surfaces below the object; there the virtual-role technique's bounce stays.)
    pipeline_->setEnvironment(setup_->scene.lightSource == lighting::LightSource::Room);
    // A setup that already carries a directional ambient (lights estimated before, e.g. a live window's
    // pipeline rebuilt for new knobs) shades with it from the first frame.
    pipeline_->setAmbientSh(setup_->ambientSh);
    inputBuilders_ = pipeline_->inputBuilders();
  }
  if (setup_->fisheye) fisheyeRays_ = reconstruction::fisheyeRays(*setup_->fisheye);
  if (setup_->scene.lightSource == lighting::LightSource::Room && !options_.fuse) {
    if (!options_.room)
      throw capture::CaptureError(setup_->scene.path.empty() ? "scene" : setup_->scene.path,
                                  "lights: \"room\" needs a room model (--room ROOM, built by mrgi room)");
    estimateRoomLights();
  }
  // A source that names no marker founds its world on its first frame when no tag is in it; a scene that
  // recorded such a world places the first frame there again (a live camera founds it anew).
  TrackingOptions tracking = options_.tracking;
  if (!setup_->markerGiven) tracking.worldFromFirstFrame = true;
  if (setup_->scene.firstFrameT_world_camera && !tracking.worldFromFirstFrame)
    throw capture::CaptureError(
        setup_->scene.path.empty() ? "scene" : setup_->scene.path,
        "world: the scene's objects are placed in a recording's first frame, but this source has a marker");
  if (setup_->scene.firstFrameT_world_camera && !options_.foundWorldAnew)
    tracking.firstFrameT_world_camera = *setup_->scene.firstFrameT_world_camera;
  poses_ = makePoseSource(options_.pose, setup_->marker(), setup_->T_world_marker, tracking);
  // A saved room is what odometry aligns frames with first; so is a room being fused (trackFusedRoom), each
  // refreshed surface handed to the measuring thread between frames (locate()), since fusion runs on the
  // render thread while the next frame is measured on the prepare worker.
  if (options_.room && (!options_.fuse || options_.trackFusedRoom)) poses_->useModel(options_.room);
}

void FramePipeline::estimateLights(const capture::Frame& frame, FrameResult& r, gl::Profiler& profiler) {
  // A new environment image: re-estimate the lights (kept on frames without one). The split of the
  // fisheye path: lights for the part above the image's mean luminance, SH bands 0-2 for the rest, with
  // the rays turned into the lighting world so that the SH is too.
  auto s = profiler.cpu("lights");
  if (!worldFisheyeRays_) {
    const capture::Pose T_world_fisheye = setup_->fisheye->T_world_fisheye.value_or(capture::identityPose());
    const capture::Pose T_marker_world =
        setup_->T_world_marker ? capture::inversePose(*setup_->T_world_marker) : capture::identityPose();
    const cv::Matx33d R = capture::rotationOf(T_marker_world * T_world_fisheye);
    worldFisheyeRays_ = *fisheyeRays_;
    worldFisheyeRays_->directions = fisheyeRays_->directions.clone();
    worldFisheyeRays_->directions.forEach<cv::Vec3f>(
        [&R](cv::Vec3f& d, const int*) { d = cv::Vec3f(R * cv::Vec3d(d)); });
  }
  reconstruction::LightSplitOptions so;
  so.medianCut.count = setup_->scene.fisheyeLightCount;
  const reconstruction::LightSplit split = reconstruction::splitLights(
      reconstruction::linearRadiance(frame.fisheye->image, frame.fisheye->exposure), *worldFisheyeRays_, so);
  setup_->lights.clear();
  for (const auto& l : split.lights) {
    lighting::SceneLight sl;
    sl.type = lighting::LightType::Directional;
    sl.direction = -l.direction;  // from the light into the scene
    sl.irradiance = reconstruction::normalIrradiance(l);
    sl.extent = l.angularRadius;
    setup_->lights.push_back(sl);
  }
  useAmbientSh(split.ambientSh, nullptr);
  r.info["lights_estimated"] = setup_->lights.size();
}

void FramePipeline::useAmbientSh(const std::array<cv::Vec3d, 9>& sh, std::shared_ptr<const lighting::RadianceMap> map) {
  // The remainder's uniform part (band 0, as radiance) is the ambient the techniques see too; bands 1-2 go
  // to the shading pass's directional ambient.
  setup_->ambient = sh[0] * 0.28209479177387814;  // Y_00
  std::array<cv::Vec3d, 9> directional = sh;
  directional[0] = {0, 0, 0};
  setup_->ambientSh = directional;  // render() hands it to the lighting with the frame's lights
  setup_->ambientMap = std::move(map);
}

bool FramePipeline::litByRoom() const { return setup_ && setup_->scene.lightSource == lighting::LightSource::Room; }

void FramePipeline::takeLights(PreparedFrame& p) const {
  if (!setup_) return;
  p.lights = setup_->lights;
  p.ambient = setup_->ambient;
  p.ambientSh = setup_->ambientSh;
  p.ambientMap = setup_->ambientMap;
}

cv::Vec3d FramePipeline::objectsCentre() const {
  // The mean of the objects' bounding boxes' centres in the marker frame.
  cv::Vec3d centre(0, 0, 0);
  for (const auto& o : setup_->scene.objects) {
    const cv::Vec3d c = 0.5 * (cv::Vec3d(o.mesh.boundsMin) + cv::Vec3d(o.mesh.boundsMax));
    centre += capture::transformPoint(capture::Pose(o.T_marker_object), c);
  }
  if (!setup_->scene.objects.empty()) centre /= static_cast<double>(setup_->scene.objects.size());
  return centre;
}

void FramePipeline::estimateRoomLights() {
  // Seen from the virtual objects' centre.
  const cv::Vec3d centre = objectsCentre();
  reconstruction::RoomLightOptions ro;
  ro.split.medianCut.count = setup_->scene.roomLightCount;
  ro.saturatedGain = setup_->scene.roomSaturatedGain;
  ro.whiteAlbedo = setup_->scene.roomWhiteAlbedo;
  // A room fixed for the whole run (a recording fused first, or --room) is searched for a distant light it shows
  // only by its sunlit patches and shadows (a second or two, once). A room fused as a sensor's frames come is
  // searched again each time it has grown by a quarter (what it shows of the sun grows with it), and at the
  // refreshes between, the light found last is measured from its direction (no search).
  const size_t vertices = options_.room->positions.size();
  const bool search = !options_.fuse || !distantSearchedAt_ || vertices * 4 >= distantSearchedAt_ * 5;
  if (!search && distantTowards_) ro.distant.towards = distantTowards_;
  ro.findDistant = search || distantTowards_.has_value();
  roomLightEstimate_ =
      std::make_shared<reconstruction::RoomLights>(reconstruction::estimateRoomLights(*options_.room, centre, ro));
  if (search) {
    distantSearchedAt_ = vertices;
    distantTowards_.reset();
  }
  if (roomLightEstimate_->distant) distantTowards_ = roomLightEstimate_->distant->towards;
  if (const auto& d = roomLightEstimate_->distant) {
    char line[300];
    std::snprintf(line, sizeof line,
                  "the room shows a light the camera never saw (the sun through a window?), found from %d of "
                  "its shadow edges: towards (%.2f, %.2f, %.2f), irradiance %.3g%s",
                  d->edges, d->towards[0], d->towards[1], d->towards[2], capture::luminance(d->irradiance),
                  d->atLeast() ? " at least (its sunlit patches are clipped)" : "");
    sayNoteOnce(line);
  }
  setup_->lights.clear();
  for (const reconstruction::RoomLight& l : roomLightEstimate_->lights) {
    lighting::SceneLight sl;
    if (l.point) {
      sl.type = lighting::LightType::Point;
      sl.position = l.position;
      sl.intensity = l.intensity;
      sl.extent = cv::norm(l.position - centre) * std::sin(l.angularRadius);  // the sphere seen under it
    } else {
      sl.type = lighting::LightType::Directional;
      sl.direction = -l.direction;
      sl.irradiance = l.irradiance;
      sl.extent = l.angularRadius;
    }
    setup_->lights.push_back(sl);
  }
  // The remainder seen from the objects, texel by texel: what they hide of it across their caps.
  useAmbientSh(roomLightEstimate_->ambientSh,
               std::make_shared<lighting::RadianceMap>(roomLightEstimate_->split.remainder));
}

void FramePipeline::locate(const capture::Frame& frame, FrameResult& r, gl::Profiler& profiler) {
  std::shared_ptr<const reconstruction::RoomMesh> model;
  {
    std::lock_guard<std::mutex> lock(pendingModelMutex_);
    model = std::move(pendingModel_);
  }
  if (model) {
    auto s = profiler.cpu("track_model");
    poses_->useModel(std::move(model));
  }
  r.pose = poses_->locate(frame, profiler);
  r.T_marker_camera = r.pose.T_world_camera;
  r.info["marker"] = r.pose.by == PosedBy::GroundTruth ? std::string("ground-truth") : r.pose.marker;
  r.info["pose"] = r.pose.facts();
}

namespace {
/// Camera poses within 1 mm and 0.1 degree of each other.
bool sameView(const capture::Pose& a, const capture::Pose& b) {
  return reconstruction::translationError(a, b) < 1e-3 && reconstruction::rotationErrorDeg(a, b) < 0.1;
}

/// Mean absolute change of b against a, relative to a's mean.
double relativeChange(const cv::Mat& a, const cv::Mat& b) {
  const double mean = cv::mean(a.reshape(1))[0];
  return cv::norm(a, b, cv::NORM_L1) / (static_cast<double>(a.total() * a.channels()) * std::max(mean, 1e-6));
}
}  // namespace

/// Frames fused in the order they were handed over, one at a time, on a thread of its own. Each job's result
/// (or exception) is its future's; the destructor lets the queued jobs finish, then joins (fusion touches no
/// device, so it cannot hang there).
class FramePipeline::Fuser {
 public:
  Fuser() : thread_([this] { loop(); }) {}
  ~Fuser() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  std::shared_future<FusedFrame> submit(std::function<FusedFrame()> job) {
    std::packaged_task<FusedFrame()> task(std::move(job));
    std::shared_future<FusedFrame> result = task.get_future().share();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      queue_.push_back(std::move(task));
    }
    wake_.notify_all();
    return result;
  }
  /// Waits until every job handed over so far has run.
  void drain() {
    std::unique_lock<std::mutex> lock(mutex_);
    idle_.wait(lock, [this] { return queue_.empty() && !busy_; });
  }

 private:
  void loop() {
    for (;;) {
      std::packaged_task<FusedFrame()> task;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
        if (queue_.empty()) return;  // stopped, and nothing left to fuse
        task = std::move(queue_.front());
        queue_.pop_front();
        busy_ = true;
      }
      task();
      {
        std::lock_guard<std::mutex> lock(mutex_);
        busy_ = false;
      }
      idle_.notify_all();
    }
  }
  std::mutex mutex_;
  std::condition_variable wake_, idle_;
  std::deque<std::packaged_task<FusedFrame()>> queue_;
  bool busy_ = false, stop_ = false;
  std::thread thread_;  ///< last: it starts once the rest is constructed
};

FramePipeline::~FramePipeline() = default;

const reconstruction::RoomModel* FramePipeline::liveRoom() const {
  finishFusion();
  return options_.fuse.get();
}

void FramePipeline::finishFusion() const {
  if (fuser_) fuser_->drain();
}

cv::Mat measuredDepth(const FrameResult& r) {
  cv::Mat depth;
  cv::extractChannel(r.positions, depth, 2);
  cv::patchNaNs(depth, 0.0);
  return depth;
}

FrameResult FramePipeline::process(capture::Frame& frame, compositor::Compositor& compositor, gl::Profiler& profiler) {
  PreparedFrame p = prepare(frame, profiler);
  render(frame, p, compositor, profiler);
  return std::move(p.result);
}

PreparedFrame FramePipeline::prepare(capture::Frame& frame, gl::Profiler& profiler) {
  PreparedFrame p;
  p.result = measure(frame, profiler);
  // The frame's own lights (a fisheye's, a session's per frame) as measure() left them; lights from the room are
  // the rendering thread's (render() takes them).
  if (!litByRoom()) takeLights(p);
  if (options_.fuse) {
    // Fused on the thread that prepares (a worker while GL renders the frame before; frames in order); a
    // refreshed surface is handed to render(), which alone changes what the lighting reads (the room, its
    // lights), so the frame is lit by it as if fused and rendered in one go.
    fuseFrame(*frame.rgbd, p, profiler);
    return p;
  }
  buildSurface(frame, p, profiler);
  return p;
}

void FramePipeline::buildSurface(const capture::Frame& frame, PreparedFrame& p, gl::Profiler& profiler) {
  const FrameResult& r = p.result;
  if (!setup_ || !pipeline_ || !r.T_marker_camera || options_.room || r.reusedSurface || p.surface) return;
  p.surface = realSurface(frame, r, profiler);
  if (options_.reuse) surfaceCache_ = SurfaceCache{*r.T_marker_camera, thumbnail_.clone(), r.positions, r.normals};
  if (inputBuilders_.empty()) return;
  // The techniques' own inputs from this frame (e.g. real surfaces as light sources).
  auto s = profiler.cpu("technique_inputs");
  const capture::RgbdFrame& rgbd = *frame.rgbd;
  const lighting::InputFrame in{r.positions, r.normals, capture::radianceOf(rgbd.colour, rgbd.exposure),
                                rgbd.colourIntrinsics, *r.T_marker_camera};
  for (auto& [name, builder] : inputBuilders_) {
    auto input = builder->fromFrame(in);
    p.result.info.update(input->facts());
    p.inputs.emplace_back(name, std::move(input));
  }
}

void FramePipeline::fuseFrame(const capture::RgbdFrame& rgbd, PreparedFrame& p, gl::Profiler& profiler) {
  FrameResult& r = p.result;
  if (!r.T_marker_camera || r.positions.empty() || r.reusedSurface) return;
  if (r.pose.held()) {
    finishFusion();  // blocks() reads the room
    r.info["room_fusion"] = {{"integrated", false}, {"refused", "held pose"}, {"blocks", options_.fuse->blocks()}};
    return;
  }
  if (options_.fuseEvery > 1 && fuseOffered_++ % options_.fuseEvery != 0) {
    r.info["room_fusion"] = {{"integrated", false}, {"skipped", "fuse every " + std::to_string(options_.fuseEvery)}};
    return;
  }
  // The fusion thread takes copies: the frame may be gone before it is fused.
  if (!fuser_) fuser_ = std::make_unique<Fuser>();
  p.fused = fuser_->submit([this, depth = measuredDepth(r), colour = rgbd.colour.clone(), k = rgbd.colourIntrinsics,
                            T = *r.T_marker_camera,
                            exposure = rgbd.exposure] { return fuse(depth, colour, k, T, exposure); });
}

FusedFrame FramePipeline::fuse(const cv::Mat& depth, const cv::Mat& colour, const capture::Intrinsics& k,
                               const capture::Pose& T_marker_camera, double exposure) {
  FusedFrame f;
  f.stages = std::make_shared<gl::Profiler>();
  reconstruction::RoomIntegration in;
  {
    auto s = f.stages->cpu("room_fusion");
    in = options_.fuse->integrate(depth, colour, k, T_marker_camera, exposure);
  }
  f.info = {{"integrated", in.integrated}, {"blocks", options_.fuse->blocks()}};
  if (!in.integrated) f.info["refused"] = in.refused;
  const bool refresh = in.integrated && mayRefresh(fusedSurface_, framesSinceRefresh_);
  ++framesSinceRefresh_;
  if (!refresh) return f;
  auto s = f.stages->cpu("room_mesh");
  auto mesh = std::make_shared<const reconstruction::RoomMesh>(options_.fuse->mesh());
  if (mesh->positions.empty()) return f;
  fusedSurface_ = true;
  framesSinceRefresh_ = 0;
  f.refreshedRoom = std::move(mesh);
  return f;
}

bool FramePipeline::mayRefresh(bool hasSurface, int fusedSinceRefresh) const {
  return !hasSurface || fusedSinceRefresh + 1 >= std::max(options_.fuseRefresh, 1);
}

void FramePipeline::takeFused(PreparedFrame& p, gl::Profiler& profiler) {
  const FusedFrame f = p.fused.get();  // the fusion's exception, if it threw
  p.fused = {};
  if (f.stages) profiler.adopt(*f.stages);
  p.result.info["room_fusion"] = f.info;
  if (f.refreshedRoom) {
    p.refreshedRoom = f.refreshedRoom;
    takenSurface_ = true;
    takenSinceRefresh_ = 0;
  } else {
    ++takenSinceRefresh_;
  }
}

void FramePipeline::useRefreshedRoom(std::shared_ptr<const reconstruction::RoomMesh> mesh, FrameResult& r) {
  // Everything derived from the room follows its new surface: its albedo and the techniques' inputs (useRoom), the
  // nearest-vertex index of the view mesh, the rays of the debug views, and lights from the room.
  options_.room = std::move(mesh);
  roomLights_.reset();  // useRoom() re-estimates the albedo and builds the techniques' inputs again
  roomIndex_.reset();
  roomRays_.reset();
  if (options_.trackFusedRoom && (options_.pose == PoseMode::Odometry || options_.pose == PoseMode::Tracked)) {
    std::lock_guard<std::mutex> lock(pendingModelMutex_);
    pendingModel_ = options_.room;
  }
  if (setup_ && setup_->scene.lightSource == lighting::LightSource::Room) estimateRoomLights();
  r.info["room_fusion"]["refreshed"] = options_.room->positions.size();
}

CameraPose FramePipeline::locatePose(capture::Frame& frame, gl::Profiler& profiler) {
  if (!frame.rgbd->depthRegistered) {
    auto s = profiler.cpu("register");
    capture::ensureRegistered(*frame.rgbd);
  }
  FrameResult r;
  locate(frame, r, profiler);
  return r.pose;
}

FrameResult FramePipeline::measure(capture::Frame& frame, gl::Profiler& profiler) {
  FrameResult r;
  capture::RgbdFrame& rgbd = *frame.rgbd;
  r.exposure = rgbd.exposure;
  if (!rgbd.depthRegistered) {
    auto s = profiler.cpu("register");
    capture::ensureRegistered(rgbd);
  }
  if (!setup_) {
    auto s = profiler.cpu("normals");
    r.positions = reconstruction::backProject(rgbd.depth, rgbd.colourIntrinsics);
    r.normals = reconstruction::computeNormals(r.positions);
    return r;
  }
  // A session whose lights move: the frame's own ground-truth lights replace the manifest's.
  if (frame.groundTruthLights && setup_->scene.lightSource == lighting::LightSource::Manifest &&
      setup_->T_world_marker) {
    if (frame.groundTruthLights->size() > static_cast<size_t>(lighting::kMaxLights))
      throw capture::CaptureError("frames.jsonl", "frame " + std::to_string(frame.index) + ": " +
                                                      std::to_string(frame.groundTruthLights->size()) +
                                                      " lights, at most " + std::to_string(lighting::kMaxLights) +
                                                      " are supported");
    setup_->lights = lightsInMarkerFrame(*frame.groundTruthLights, *setup_->T_world_marker);
    r.info["lights_from_frame"] = setup_->lights.size();
  }
  if (fisheyeRays_ && frame.fisheye) estimateLights(frame, r, profiler);
  // The camera pose in the lighting world (the marker frame), from the pose source.
  locate(frame, r, profiler);
  if (options_.reuse && options_.gpu) {
    cv::resize(rgbd.colour, thumbnail_, {32, 24}, 0, 0, cv::INTER_AREA);
    thumbnail_.convertTo(thumbnail_, CV_32F);
    if (surfaceCache_ && r.T_marker_camera && sameView(surfaceCache_->T_marker_camera, *r.T_marker_camera) &&
        relativeChange(surfaceCache_->thumbnail, thumbnail_) < 0.01) {
      // A static camera over an unchanged image: the real surface it was built from still holds.
      r.T_marker_camera = surfaceCache_->T_marker_camera;
      r.positions = surfaceCache_->positions;
      r.normals = surfaceCache_->normals;
      r.reusedSurface = true;
      r.info["skipped"] = {"depth_filter", "normals"};
      return r;
    }
  }
  cv::Mat depth;
  {
    auto s = profiler.cpu("depth_filter");
    reconstruction::DepthFilterOptions fo;
    const cv::Mat guide = reconstruction::guideFromColour(rgbd.colour);
    depth = reconstruction::guidedFilterDepth(
        rgbd.depth, guide, reconstruction::filterRadiusPixels(rgbd.depth, rgbd.colourIntrinsics, fo), fo);
  }
  {
    auto s = profiler.cpu("normals");
    r.positions = reconstruction::backProject(depth, rgbd.colourIntrinsics);
    r.normals = reconstruction::computeNormals(r.positions);
  }
  return r;
}

reconstruction::AlbedoLights FramePipeline::albedoLights(const capture::Pose& T_frame_marker,
                                                         const std::vector<lighting::SceneLight>& lights,
                                                         const cv::Vec3d& ambient) const {
  reconstruction::AlbedoLights al;
  for (const auto& l : lights) {
    if (l.type == lighting::LightType::Directional) {
      reconstruction::EstimatedLight e;
      e.direction = -(capture::rotationOf(T_frame_marker) * l.direction);
      e.power = l.irradiance;
      e.angularRadius = l.extent;  // a disc lights by the part of it above a surface's horizon
      al.distant.push_back(e);
    } else {
      al.points.push_back({capture::transformPoint(T_frame_marker, l.position), l.intensity, l.extent});
    }
  }
  al.ambientIrradiance = CV_PI * ambient;
  return al;
}

RealSurface FramePipeline::realSurface(const capture::Frame& frame, const FrameResult& r,
                                       gl::Profiler& profiler) const {
  RealSurface out;
  const capture::Pose T_camera_marker = capture::inversePose(*r.T_marker_camera);
  cv::Mat albedo;
  {
    auto s = profiler.cpu("albedo");
    reconstruction::AlbedoOptions ao;
    ao.exposure = frame.rgbd->exposure;
    // Rejected pixels filled from 2 x 2 blocks, the holes inpainted at half resolution: measured against the
    // path-traced references as accurate as the full-resolution fill (README, Real time), at a fraction of
    // its cost; 4 x 4 blocks mix across the tag's edges.
    ao.fillScale = 2;
    albedo = reconstruction::estimateAlbedo(frame.rgbd->colour, r.positions, r.normals, frame.rgbd->colourIntrinsics,
                                            albedoLights(T_camera_marker, setup_->lights, setup_->ambient), ao)
                 .albedo;
  }
  {
    auto s = profiler.cpu("mesh");
    const auto mesh = reconstruction::buildDepthMesh(r.positions, r.normals, options_.meshStride);
    lighting::buildRealVertices(mesh, albedo, *r.T_marker_camera, out.vertices, out.indices);
  }
  out.pixelAlbedo = albedo;
  return out;
}

void FramePipeline::useRoom(const PreparedFrame& p, nlohmann::json& info, gl::Profiler& profiler) {
  if (roomLights_ && *roomLights_ == p.lights) {
    info["skipped"].push_back("room_albedo");
    return;
  }
  auto s = profiler.cpu("room_albedo");
  // A lamp the sensor saw is part of the room: its surface would enclose the light's own position, shadow
  // every shadow ray to it (the albedo) and every RSM texel. Triangles within kLightClearance of a point or
  // spot light are left out of the room the lighting sees.
  constexpr double kLightClearance = 0.1;
  reconstruction::RoomMesh room;
  {
    const reconstruction::RoomMesh& full = *options_.room;
    room.positions = full.positions, room.normals = full.normals, room.radiance = full.radiance;
    room.confidence = full.confidence, room.saturated = full.saturated;
    room.indices.reserve(full.indices.size());
    for (size_t t = 0; t + 2 < full.indices.size(); t += 3) {
      bool nearLight = false;
      for (const auto& l : p.lights) {
        if (l.type == lighting::LightType::Directional) continue;
        for (int k = 0; k < 3 && !nearLight; ++k)
          nearLight = cv::norm(cv::Vec3d(full.positions[full.indices[t + k]]) - l.position) < kLightClearance;
      }
      if (!nearLight)
        room.indices.insert(room.indices.end(), full.indices.begin() + static_cast<std::ptrdiff_t>(t),
                            full.indices.begin() + static_cast<std::ptrdiff_t>(t + 3));
    }
  }
  const size_t cleared = (options_.room->indices.size() - room.indices.size()) / 3;
  // Rays against this room, for what it hides from real surfaces and what it sends itself.
  const reconstruction::MeshRays clearedRays(room.positions, room.indices);
  // Lights listed apart from the room: what the objects hide from the real surfaces beside those lights is the
  // room's surfaces seen from the objects (lamps cleared above, saturated ones left out), not the listed ambient.
  if (setup_->scene.lightSource != lighting::LightSource::Room && !setup_->scene.objects.empty() &&
      !room.indices.empty()) {
    auto sh = profiler.cpu("room_hidden");
    reconstruction::RoomLightOptions ro;
    ro.mapWidth = 64;
    ro.saturatedGain = 1;
    const reconstruction::RoomLights seen = reconstruction::estimateRoomLights(room, objectsCentre(), ro, &clearedRays);
    lighting::Ambient hidden;
    hidden.uniform = cv::Vec3f(seen.surfacesSh[0] * 0.28209479177387814);  // Y_00
    for (size_t k = 1; k < 9; ++k) hidden.sh[k] = cv::Vec3f(seen.surfacesSh[k]);
    hidden.map = std::make_shared<lighting::RadianceMap>(seen.surfaces);
    pipeline_->setHiddenAmbient(hidden);
  }
  roomIndices_ = room.indices;
  roomInputsSet_ = false;
  // The lighting world (marker frame), as the room.
  if (!roomAlbedoCache_)
    roomAlbedoCache_ = std::make_shared<reconstruction::RoomAlbedoCache>(
        options_.fuse ? options_.fuse->options().voxelM : reconstruction::RoomOptions{}.voxelM);
  // What the room sends itself (its fused radiance, every bounce the camera saw) is the rest of each vertex's
  // irradiance beside the lights: without it a closed room's albedo comes out too bright by a half or more.
  std::vector<cv::Vec3f> bounce;
  {
    auto sb = profiler.cpu("room_bounce");
    reconstruction::RoomBounceOptions bo;
    bo.outside = p.ambient;
    bounce = reconstruction::roomBounceIrradiance(room, clearedRays, bo);
  }
  const reconstruction::RoomAlbedo albedo =
      reconstruction::estimateRoomAlbedo(room, albedoLights(capture::identityPose(), p.lights, p.ambient), {},
                                         roomAlbedoCache_.get(), &bounce, &clearedRays);
  const auto& rays = roomAlbedoCache_->lastStats();
  roomAlbedo_ = albedo.albedo;
  roomAlbedoStatus_ = albedo.status;
  std::vector<lighting::MeshVertex> vertices(room.positions.size());
  // The room's own mesh (RSMs, volumes, points: what bounces the lights) sends its fused radiance; the frame's
  // view of it (the G-buffer's albedo, roomViewMesh) reflects by the true albedo.
  for (size_t i = 0; i < vertices.size(); ++i) vertices[i] = {room.positions[i], room.normals[i], albedo.sent[i]};
  pipeline_->setRealMesh(std::move(vertices), room.indices);
  roomLights_ = p.lights;
  size_t measured = 0;
  for (auto st : albedo.status) measured += st == reconstruction::AlbedoStatus::Measured;
  info["room"] = {{"vertices", room.positions.size()},
                  {"albedo_measured", measured},
                  {"triangles_near_lights", cleared},
                  {"albedo_rays",
                   {{"cast", rays.raysCast},
                    {"rechecked", rays.raysRechecked},
                    {"reused", rays.raysReused},
                    {"changed_vertices", rays.changedVertices}}}};
  if (roomLightEstimate_)
    info["room"]["lights"] = {{"count", roomLightEstimate_->lights.size()},
                              {"saturated_gain", roomLightEstimate_->gain},
                              {"gain_estimated", roomLightEstimate_->gainEstimated},
                              {"gain_samples", roomLightEstimate_->gainSamples},
                              {"saturated_fraction", roomLightEstimate_->saturatedFraction},
                              {"lamp_lit_clipped_vertices", roomLightEstimate_->lampLitClipped},
                              {"over_exposed", roomLightEstimate_->overExposed},
                              {"coverage", roomLightEstimate_->coverage},
                              {"ambient_radiance",
                               {roomLightEstimate_->ambientRadiance[0], roomLightEstimate_->ambientRadiance[1],
                                roomLightEstimate_->ambientRadiance[2]}},
                              {"distant", reconstruction::distantLightFacts(*roomLightEstimate_)}};
}

const reconstruction::MeshRays& FramePipeline::roomRays() {
  if (!options_.room) throw std::logic_error("FramePipeline::roomRays: no room");
  if (!roomRays_)
    roomRays_ = std::make_shared<reconstruction::MeshRays>(options_.room->positions, options_.room->indices);
  return *roomRays_;
}

struct FramePipeline::RoomIndex {
  explicit RoomIndex(const std::vector<cv::Vec3f>& positions)
      : cloud{positions}, tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {}
  reconstruction::PointCloudAdaptor cloud;
  reconstruction::PointKdTree tree;
};

void FramePipeline::roomViewMesh(const capture::RgbdFrame& rgbd, FrameResult& r, gl::Profiler& profiler) {
  auto s = profiler.cpu("view_mesh");
  if (!roomIndex_) roomIndex_ = std::make_shared<RoomIndex>(options_.room->positions);
  // The mesh over the depth, for the shading pass's footprint only: the G-buffer draws the pixels themselves.
  std::vector<lighting::MeshVertex> vertices;
  std::vector<uint32_t> indices;
  const auto mesh = reconstruction::buildDepthMesh(r.positions, r.normals, options_.meshStride);
  lighting::buildRealVertices(mesh, cv::Mat(), *r.T_marker_camera, vertices, indices);
  const cv::Mat radiance = capture::radianceOf(rgbd.colour, rgbd.exposure);
  // Each pixel's albedo: the room vertex nearest its block of meshStride x meshStride pixels (nearest to the
  // block's first pixel with a depth: the mesh's vertex heading it where there is one) times the texture the
  // voxels blurred (albedoDetail).
  cv::Mat pixelAlbedo(rgbd.colour.size(), CV_32FC3, cv::Scalar::all(-1));
  const int stride = std::max(1, options_.meshStride);
  const cv::Matx44d& T = *r.T_marker_camera;
  std::atomic<size_t> detailedBlocks{0};
  const int rows = std::min(radiance.rows, r.positions.rows), cols = std::min(radiance.cols, r.positions.cols);
  // Rows of blocks over OpenCV's workers: each block writes its own pixels, and the room's index is only read.
  cv::parallel_for_(cv::Range(0, (rows + stride - 1) / stride), [&](const cv::Range& blockRows) {
    size_t detailed = 0;
    for (int by = blockRows.start * stride; by < blockRows.end * stride && by < rows; by += stride)
      for (int bx = 0; bx < cols; bx += stride) {
        const int yEnd = std::min(by + stride, rows), xEnd = std::min(bx + stride, cols);
        cv::Point head(-1, -1);
        for (int y = by; y < yEnd && head.x < 0; ++y)
          for (int x = bx; x < xEnd; ++x)
            if (reconstruction::validDepth(r.positions.at<cv::Vec3f>(y, x)[2])) {
              head = {x, y};
              break;
            }
        if (head.x < 0) continue;
        const cv::Vec3f world(capture::transformPoint(T, cv::Vec3d(r.positions.at<cv::Vec3f>(head))));
        uint32_t nearest = 0;
        float d2 = 0;
        if (roomIndex_->tree.knnSearch(&world[0], 1, &nearest, &d2) != 1) continue;
        const cv::Vec3f base = roomAlbedo_[nearest];
        const auto st = roomAlbedoStatus_[nearest];
        const bool detail =
            st == reconstruction::AlbedoStatus::Measured || st == reconstruction::AlbedoStatus::Saturated;
        detailed += detail;
        for (int y = by; y < yEnd; ++y)
          for (int x = bx; x < xEnd; ++x) {
            cv::Vec3f a = base;
            if (detail) {
              const cv::Vec3f d = reconstruction::albedoDetail(
                  rgbd.colour.at<cv::Vec3b>(y, x), radiance.at<cv::Vec3f>(y, x), options_.room->radiance[nearest]);
              for (int c = 0; c < 3; ++c) a[c] = std::min(1.0f, a[c] * d[c]);
            }
            pixelAlbedo.at<cv::Vec3f>(y, x) = a;
          }
      }
    detailedBlocks += detailed;
  });
  r.info["view_mesh_detailed"] = detailedBlocks.load();
  pipeline_->setViewMesh(std::move(vertices), std::move(indices));
  pipeline_->setViewSurface(r.positions, r.normals, options_.meshStride);
  pipeline_->setRealPixelAlbedo(pixelAlbedo, lighting::clippedChannels(rgbd.colour));
}

void FramePipeline::render(const capture::Frame& frame, FrameResult& r, compositor::Compositor& compositor,
                           gl::Profiler& profiler) {
  PreparedFrame p;
  p.result = std::move(r);
  takeLights(p);
  render(frame, p, compositor, profiler);
  r = std::move(p.result);
}

void FramePipeline::render(const capture::Frame& frame, PreparedFrame& p, compositor::Compositor& compositor,
                           gl::Profiler& profiler) {
  // A frame whose fusion may refresh the room's surface is lit by it: it waits for its fusion first. Any other
  // is fused while it renders (and the next frame is measured), and takes its facts at the end: the same
  // composites as fusing on the preparing thread.
  if (p.fused.valid() && mayRefresh(takenSurface_, takenSinceRefresh_)) takeFused(p, profiler);
  renderFrame(frame, p, compositor, profiler);
  if (p.fused.valid()) {
    takeFused(p, profiler);
    if (p.refreshedRoom) throw std::logic_error("FramePipeline::render: a frame refreshed the room after it was lit");
  }
}

void FramePipeline::renderFrame(const capture::Frame& frame, PreparedFrame& p, compositor::Compositor& compositor,
                                gl::Profiler& profiler) {
  if (p.refreshedRoom) useRefreshedRoom(std::move(p.refreshedRoom), p.result);
  if (litByRoom()) takeLights(p);  // lights from the room as it now is
  FrameResult& r = p.result;
  const capture::RgbdFrame& rgbd = *frame.rgbd;
  if (!setup_ || !r.T_marker_camera) {
    // No scene, or marker lost: nothing can be placed; the frame is the background.
    compositor.setExposure(rgbd.exposure);
    r.composite = compositor.composite(rgbd.colour, cv::Mat(), cv::Mat(), &profiler);
    return;
  }
  const bool own = !inputBuilders_.empty();
  if (options_.room) {
    useRoom(p, r.info, profiler);
    if (!r.reusedSurface) roomViewMesh(rgbd, r, profiler);
  } else if (r.reusedSurface) {
    for (const char* stage : {"albedo", "mesh"}) r.info["skipped"].push_back(stage);
    if (own) r.info["skipped"].push_back("technique_inputs");
  } else {
    buildSurface(frame, p, profiler);  // prepared already, unless measured only
    pipeline_->setRealMesh(std::move(p.surface->vertices), std::move(p.surface->indices));
    pipeline_->setViewSurface(r.positions, r.normals, options_.meshStride);
    pipeline_->setRealPixelAlbedo(p.surface->pixelAlbedo, lighting::clippedChannels(rgbd.colour));
    p.surface.reset();
    for (auto& [name, input] : p.inputs) pipeline_->setTechniqueInput(name, std::move(input));
    p.inputs.clear();
  }
  if (own && options_.room) {
    // The techniques' own inputs from the room: every surface it holds, in view or not, once per room (again
    // when the lights, and so the triangles cleared around them, change).
    if (!roomInputsSet_) {
      auto s = profiler.cpu("technique_inputs");
      for (auto& [name, builder] : inputBuilders_) {
        auto input = builder->fromRoom(*options_.room, roomIndices_);
        r.info.update(input->facts());
        pipeline_->setTechniqueInput(name, std::move(input));
      }
      roomInputsSet_ = true;
    } else {
      r.info["skipped"].push_back("technique_inputs");
    }
  }
  lighting::CameraView view;
  view.intrinsics = rgbd.colourIntrinsics;
  view.T_world_camera = *r.T_marker_camera;
  pipeline_->setAmbientSh(p.ambientSh);
  pipeline_->setAmbientMap(p.ambientMap);
  pipeline_->setCameraWhite(rgbd.exposure > 0 ? 1.0 / rgbd.exposure : 0.0);  // clipped pixels' shadows
  pipeline_->run(view, p.lights, p.ambient, &profiler);
  for (const std::string& stage : pipeline_->skippedStages()) r.info["skipped"].push_back(stage);
  if (const auto& rendered = pipeline_->lightsRendered(); rendered.size() < p.lights.size()) {
    // The lights too dim at the objects to be worth rendering (frame knob light_cutoff), by index.
    nlohmann::json skippedLights = nlohmann::json::array();
    for (size_t i = 0, k = 0; i < p.lights.size(); ++i)
      if (k < rendered.size() && rendered[k] == i)
        ++k;
      else
        skippedLights.push_back(i);
    r.info["lights_skipped"] = std::move(skippedLights);
  }
  // Each technique's facts of this frame (counts, flicker), under its name.
  if (options_.techniqueStats)
    if (auto stats = pipeline_->stats(); !stats.empty()) r.info["techniques"] = std::move(stats);
  compositor.setExposure(rgbd.exposure);
  r.composite = compositor.composite(rgbd.colour, pipeline_->shade(), &profiler);
  r.lit = true;
}

}  // namespace mrgi::runtime
