#include "evaluation/bench_run.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/quality.hpp>

#include "capture/checks.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/json_io.h"
#include "capture/registration.h"
#include "capture/session.h"
#include "compositor/compositor.h"
#include "evaluation/bench.h"
#include "evaluation/metrics.h"
#include "evaluation/reference_scene.h"
#include "evaluation/tabletop.h"
#include "evaluation/tag_pixels.h"
#include "evaluation/tracking_metrics.h"
#include "gl/context.h"
#include "gl/profiler.h"
#include "groundtruth/path_tracer.h"
#include "groundtruth/raycaster.h"
#include "lighting/debug_views.h"
#include "lighting/pipeline.h"
#include "lighting/techniques/kinect_val/real_vals.h"  // --against bruteforce: real VALs subsampled by count
#include "lighting/techniques/registry.h"
#include "reconstruction/depth.h"
#include "reconstruction/depth_filter.h"
#include "reconstruction/room_lights.h"
#include "runtime/frame_pipeline.h"
#include "runtime/output.h"
#include "runtime/room_fusion.h"
#include "runtime/threads.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::evaluation {
namespace {

/// The pixels the objects `caster` holds cover in part, seen through `camera` (Truth::partial): 4 x 4 rays a pixel,
/// tested within a box just around the objects.
cv::Mat partlyVirtual(const groundtruth::RayCaster& caster, const groundtruth::PinholeCamera& camera) {
  return groundtruth::partlyVirtualMask(caster, camera, 4, groundtruth::virtualFocus(caster.scene(), camera, 0.1));
}

using namespace mrgi::runtime;

int runBruteForce(const BenchOptions& o) {
  // The technique's sparse method against its own brute force (a "brute_force" knob): its real-surface area
  // lights come from the frame; --sparse and --occlusion set its "sparse_points" and "occlusion" knobs.
  lighting::KnobSet baseKnobs;
  lighting::completeKnobs(baseKnobs);
  const lighting::TechniqueChoice choice = lighting::parseTechniqueChoice(o.technique, &baseKnobs);
  const lighting::TechniqueInfo* info = lighting::findTechnique(choice.virtualObject);
  if (!info || !info->knobs.find("brute_force") || !info->knobs.find("sparse_points"))
    throw std::invalid_argument(
        "--technique " + o.technique +
        ": --against bruteforce needs a virtual-object technique with brute_force and sparse_points knobs");
  const std::string group = info->knobs.key;
  if (const lighting::KnobInfo* k = info->knobs.find("k_cache"); k && (o.kCache < k->lo || o.kCache > k->hi))
    throw capture::FlagError("--k-cache", "must be in [" + capture::formatNumber(k->lo) + ", " +
                                              capture::formatNumber(k->hi) + "] (" + group + ".k_cache), not " +
                                              std::to_string(o.kCache));
  if (o.sessions.empty()) throw std::invalid_argument("--session: none given");
  const std::string& session = o.sessions.front();
  auto source = capture::open(session);
  auto frame = source->next();
  if (!frame || !frame->rgbd) throw capture::CaptureError(session, "has no RGB-D frame");
  capture::RgbdFrame& rgbd = *frame->rgbd;
  capture::ensureRegistered(rgbd);
  // The camera pose in the object's world (marker frame with ground truth, else the camera frame).
  capture::Pose T_world_camera = capture::identityPose();
  bool onMarker = true;
  if (const capture::SessionManifest* m = source->sessionManifest();
      m && frame->groundTruthT_world_camera && m->truth.T_world_marker) {
    T_world_camera = capture::inversePose(*m->truth.T_world_marker) * *frame->groundTruthT_world_camera;
  } else {
    onMarker = false;  // no marker frame: 1 m in front of the camera
  }
  const cv::Mat positions = reconstruction::backProject(rgbd.depth, rgbd.colourIntrinsics);
  const cv::Mat normals = reconstruction::computeNormals(positions);
  const auto all = lighting::valsFromRgbd(positions, normals, capture::radianceOf(rgbd.colour, rgbd.exposure),
                                          rgbd.colourIntrinsics, T_world_camera, 1);
  if (all.empty()) throw capture::CaptureError(session, "frame 0 has no valid depth to make VALs from");

  lighting::VirtualObject object;
  object.model = o.model;
  object.mesh = lighting::loadMesh(o.model);
  for (auto& p : object.mesh.positions) p *= static_cast<float>(o.scale);
  object.mesh.computeBounds();
  const cv::Vec3d objectAt(0, 0, onMarker ? -object.mesh.boundsMin[2] : 1.0);  // resting on the marker plane
  object.T_marker_object = capture::makePose(cv::Matx33d::eye(), objectAt);
  object.material.albedo = {0.7f, 0.7f, 0.7f};
  object.material.specular = 0.2f;
  object.material.roughness = 0.5f;

  const int width = rgbd.colour.cols, height = rgbd.colour.rows;
  gl::ContextConfig cfg;
  cfg.backend = gl::parseBackend(o.gl);
  cfg.width = width;
  cfg.height = height;
  auto context = gl::createContext(cfg);
  std::vector<lighting::MeshVertex> realVertices;
  std::vector<uint32_t> realIndices;
  lighting::buildRealVertices(reconstruction::buildDepthMesh(positions, normals, 2), cv::Mat(), T_world_camera,
                              realVertices, realIndices);
  lighting::CameraView view;
  view.intrinsics = rgbd.colourIntrinsics;
  view.T_world_camera = T_world_camera;
  auto makePipeline = [&](int sparse, bool occlusion, bool bruteForce) {
    lighting::PipelineConfig pc;
    pc.width = width;
    pc.height = height;
    pc.technique = choice;
    pc.knobs = baseKnobs;
    if (info->knobs.find("k_cache")) pc.set(group, "k_cache", o.kCache);
    pc.set(group, "sparse_points", sparse);
    if (info->knobs.find("occlusion")) pc.set(group, "occlusion", occlusion ? 1 : 0);
    pc.set(group, "brute_force", bruteForce ? 1 : 0);
    auto pipe = std::make_unique<lighting::LightingPipeline>(pc, std::vector<lighting::VirtualObject>{object});
    pipe->setRealMesh(realVertices, realIndices);
    return pipe;
  };

  json records = json::array();
  for (int valCount : o.valCounts) {
    // An even subsample of the frame's VALs, each carrying its share of the frame's light.
    std::vector<lighting::Val> vals;
    const size_t n = std::min<size_t>(valCount, all.size());
    const float share = static_cast<float>(all.size()) / static_cast<float>(n);
    for (size_t i = 0; i < n; ++i) {
      lighting::Val v = all[i * all.size() / n];
      v.area *= share;
      v.flux *= share;
      vals.push_back(v);
    }
    // Brute force: the reference image of the object's bounce light and the cost of its gather.
    auto input = std::make_shared<lighting::RealVals>();
    input->vals = vals;
    auto brute = makePipeline(64, false, true);
    brute->setTechniqueInput(info->name, input);
    const auto bruteStages = bestStages(*brute, view, std::max(1, std::min(o.repeats, 2)));
    const cv::Mat reference = brute->downloadShade();
    const size_t pixels = brute->stats().value(info->name, nlohmann::json::object()).value("receivers", size_t(0));
    double msBrute = 0;  // the brute force's gather: its stages less the read-back staging
    for (const auto& [stage, ms] : bruteStages)
      if (lighting::isTechniqueStage(stage) && stage.find("staging") == std::string::npos) msBrute += ms;
    double refSum = 0;
    for (int i = 0; i < static_cast<int>(reference.total()); ++i) {
      const cv::Vec4f v = reference.at<cv::Vec4f>(i);
      if (v[3] > 0.5f) refSum += v[0] + v[1] + v[2];
    }
    for (int sparseCount : o.sparseCounts)
      for (bool occlusion : {false, true}) {
        if ((occlusion && o.occlusion == "off") || (!occlusion && o.occlusion == "on")) continue;
        const auto t0 = std::chrono::steady_clock::now();
        auto pipe = makePipeline(sparseCount, occlusion, false);
        const double msPrecompute =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        pipe->setTechniqueInput(info->name, input);
        const auto stages = bestStages(*pipe, view, o.repeats);
        const cv::Mat shade = pipe->downloadShade();
        double err = 0;
        for (int i = 0; i < static_cast<int>(shade.total()); ++i) {
          const cv::Vec4f a = shade.at<cv::Vec4f>(i), b = reference.at<cv::Vec4f>(i);
          if (b[3] > 0.5f) err += std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
        }
        json msStages = json::object();
        double msSparse = 0;
        for (const auto& [stage, ms] : stages)
          if (lighting::isTechniqueStage(stage)) {
            msStages[stage] = ms;
            msSparse += ms;
          }
        msStages["precompute"] = msPrecompute;  // sparse points + k-d tree weights, once per mesh
        json r = {
            {"technique", choice.name},
            {"knobs",
             {{"vals", vals.size()}, {"sparse_points", sparseCount}, {"k_cache", o.kCache}, {"occlusion", occlusion}}},
            {"receivers_bruteforce", pixels},
            {"ms_sparse", msSparse},
            {"ms_stages", msStages},
            {"ms_bruteforce", msBrute},
            {"speedup", msSparse > 0 ? msBrute / msSparse : 0.0},
            {"rel_error_vs_bruteforce", refSum > 0 ? err / refSum : 0.0}};
        std::printf(
            "%s vals %6zu sparse %5d occlusion %d: sparse %8.2f ms, brute force %9.2f ms over %zu pixels "
            "(x%.1f), rel. error %.4f\n",
            choice.name.c_str(), vals.size(), sparseCount, occlusion ? 1 : 0, msSparse, msBrute, pixels,
            r["speedup"].get<double>(), r["rel_error_vs_bruteforce"].get<double>());
        std::fflush(stdout);
        records.push_back(r);
      }
  }
  json out = {
      {"generated_by", "mrgi bench"},         {"session", session}, {"model", o.model}, {"gl", context->renderer()},
      {"process", processSettingsInEffect()}, {"records", records}};
  if (!o.json.empty()) {
    createParentDirectory(o.json);
    capture::writeFileAtomically(o.json, out.dump(2) + "\n");
  }
  return 0;
}

/// One session of the sweep: its frames, lighting setup and truths.
struct BenchSession {
  std::string path, scene;
  LightingSetup setup;
  std::vector<capture::Frame> frames;
  int W = 0, H = 0;
  std::map<int, Truth> truths;    ///< path traced from the inputs the pipeline sees (measures the technique)
  std::map<int, Truth> trueRefs;  ///< the synthetic session's own reference composites (the whole pipeline)
  std::shared_ptr<const reconstruction::RoomMesh> room;  ///< --room: the session fused over all its frames
  /// The true irradiance at the objects' centre for the six axis normals (marker frame), path traced in the
  /// synthetic room the session was made in; empty when the session is not one (computed on first use).
  std::optional<std::optional<std::array<cv::Vec3d, 6>>> trueIrradiance;
  json refInfo;
  std::unique_ptr<compositor::Compositor> compositor;
};

/// Same models, placements, scales and materials, in the same order.
bool sameObjects(const lighting::SceneDescription& a, const lighting::SceneDescription& b) {
  if (a.objects.size() != b.objects.size()) return false;
  std::error_code ec;
  for (size_t i = 0; i < a.objects.size(); ++i) {
    const auto &x = a.objects[i], &y = b.objects[i];
    if (!fs::equivalent(x.model, y.model, ec) || cv::norm(x.T_marker_object - y.T_marker_object) > 1e-9 ||
        x.mesh.positions.size() != y.mesh.positions.size() || cv::norm(x.material.albedo - y.material.albedo) > 1e-6 ||
        x.material.roughness != y.material.roughness || x.material.specular != y.material.specular)
      return false;
    for (size_t k = 0; k < x.mesh.positions.size(); ++k)
      if (cv::norm(x.mesh.positions[k] - y.mesh.positions[k]) > 1e-7) return false;  // the same scale
  }
  return true;
}

/// The true reference composites a synthetic session carries (manifest ground_truth.reference, whose
/// scene file is `referenceScene`) when `scene` places the same objects, for `frames` (keyed by position):
/// composite, delta (rho - mu on real pixels, rho on virtual) and mask; with the marker's world pose and a
/// frame's true camera pose, the pixels its objects cover in part (Truth::partial; the objects alone, seen
/// through the true camera).
std::map<int, Truth> loadTrueReferences(const std::string& session, const capture::GroundTruthReference& reference,
                                        const std::string& referenceScene, const lighting::SceneDescription& scene,
                                        const std::optional<capture::Pose>& T_world_marker,
                                        const std::vector<capture::Frame>& frames) {
  std::map<int, Truth> out;
  // The truth depends on the objects alone (the room and its lights are the session's): any scene placing
  // the same objects the same way can use it.
  if (referenceScene.empty() || !sameObjects(lighting::loadScene(referenceScene), scene)) return out;
  groundtruth::Scene objectScene;  // the objects alone, for the pixels they cover in part
  std::optional<groundtruth::RayCaster> objects;
  if (T_world_marker) {
    addVirtualObjects(scene.objects, *T_world_marker, objectScene);
    objects.emplace(objectScene);
  }
  auto path = [&](const std::string& key, int64_t f) {
    const std::string& pattern = key == "composite" ? reference.composite
                                 : key == "delta"   ? reference.delta
                                                    : reference.mask;
    return capture::GroundTruthReference::pathFor(session, pattern, f);
  };
  for (int f = 0; f < static_cast<int>(frames.size()); ++f) {
    const int64_t index = frames[f].index;
    Truth t;
    t.frame = f;
    t.composite = capture::readColour(path("composite", index));  // RGB
    t.delta = capture::readAny(path("delta", index));             // RGB float
    t.images.mask = cv::imread(path("mask", index), cv::IMREAD_GRAYSCALE);
    if (t.images.mask.empty() || t.delta.depth() != CV_32F)
      throw capture::CaptureError(path("mask", index),
                                  "true reference of frame " + std::to_string(index) + " is missing or unreadable");
    if (objects && frames[f].groundTruthT_world_camera && frames[f].rgbd &&
        frames[f].rgbd->colourIntrinsics.width == t.delta.cols &&
        frames[f].rgbd->colourIntrinsics.height == t.delta.rows) {
      const groundtruth::PinholeCamera camera{frames[f].rgbd->colourIntrinsics, *frames[f].groundTruthT_world_camera};
      t.partial = partlyVirtual(*objects, camera);
    }
    out[f] = std::move(t);
  }
  return out;
}

/// How far the tracked marker pose is from the session's ground truth over the bench frames: the camera
/// position error (mm) and orientation error (degrees), mean and max, and the frames without a pose. The
/// pipeline's own --pose decides what the sweep uses; this says what marker tracking would add.
json markerPoseError(const BenchSession& bs, const BenchOptions& o) {
  if (!bs.setup.T_world_marker) return nullptr;
  FrameOptions mo;
  mo.pose = PoseMode::Marker;
  mo.gpu = false;
  FramePipeline tracker(bs.setup, bs.W, bs.H, mo);
  gl::Profiler none;
  double tSum = 0, tMax = 0, rSum = 0, rMax = 0;
  int n = 0, lost = 0;
  for (const capture::Frame& f : bs.frames) {
    if (!f.groundTruthT_world_camera) continue;
    capture::Frame frame = f;
    const FrameResult r = tracker.measure(frame, none);
    if (!r.T_marker_camera) {
      ++lost;
      continue;
    }
    const capture::Pose truth = capture::inversePose(*bs.setup.T_world_marker) * *f.groundTruthT_world_camera;
    const double dt = reconstruction::translationError(*r.T_marker_camera, truth) * 1000.0;
    const double dr = reconstruction::rotationErrorDeg(*r.T_marker_camera, truth);
    tSum += dt, rSum += dr, tMax = std::max(tMax, dt), rMax = std::max(rMax, dr);
    ++n;
  }
  return {{"frames", n},
          {"lost", lost},
          {"position_mm_mean", n ? tSum / n : 0.0},
          {"position_mm_max", tMax},
          {"rotation_deg_mean", n ? rSum / n : 0.0},
          {"rotation_deg_max", rMax},
          {"resolution", {bs.W, bs.H}}};
}

/// Each way of placing the camera (marker, odometry, tracked) against the session's ground truth over the
/// bench frames: absolute trajectory error, relative pose error between consecutive frames, the last frame's
/// error (drift) and the frames lost. The world is the marker frame for all three.
json trackingError(const BenchSession& bs) {
  if (!bs.setup.T_world_marker) return nullptr;
  json out = json::object();
  for (const PoseMode mode : {PoseMode::Marker, PoseMode::Odometry, PoseMode::Tracked}) {
    FrameOptions mo;
    mo.pose = mode;
    mo.gpu = false;
    FramePipeline tracker(bs.setup, bs.W, bs.H, mo);
    gl::Profiler none;
    std::vector<std::optional<capture::Pose>> estimate;
    std::vector<capture::Pose> truth;
    for (const capture::Frame& f : bs.frames) {
      if (!f.groundTruthT_world_camera) continue;
      capture::Frame frame = f;
      estimate.push_back(tracker.measure(frame, none).T_marker_camera);
      truth.push_back(capture::inversePose(*bs.setup.T_world_marker) * *f.groundTruthT_world_camera);
    }
    const TrajectoryError e = trajectoryError(estimate, truth);
    out[toString(mode)] = {{"frames", e.frames},
                           {"tracked", e.tracked},
                           {"ate_rmse_mm", 1e3 * e.ateRmseM},
                           {"ate_max_mm", 1e3 * e.ateMaxM},
                           {"rpe_rmse_mm", 1e3 * e.rpeRmseM},
                           {"rpe_rmse_deg", e.rpeRmseDeg},
                           {"last_mm", 1e3 * e.lastM}};
  }
  return out;
}

BenchSession loadBenchSession(const std::string& path, const BenchOptions& o) {
  BenchSession bs;
  bs.path = path;
  auto source = capture::open(path);
  const capture::SourceInfo& info = source->info();
  if (!info.hasRgbd) throw capture::CaptureError(path, "has no RGB-D frames");
  // A synthetic session names the scene its true references show (relative to the session); without
  // --scene that is the one measured.
  const capture::SessionManifest* manifest = source->sessionManifest();
  const std::optional<capture::GroundTruthReference> reference = manifest ? manifest->truth.reference : std::nullopt;
  const std::string referenceScene = reference ? (fs::path(path) / reference->scene).lexically_normal().string() : "";
  bs.scene = !o.scene.empty()          ? o.scene
             : !referenceScene.empty() ? referenceScene
                                       : runtime::bundledPath("recordings/scenes/tabletop.json");
  bs.setup = prepareLighting(lighting::loadScene(bs.scene), bs.scene, *source, path, o.pose);
  if (bs.setup.scene.objects.empty()) throw capture::CaptureError(bs.scene, "has no virtual object to measure");
  while (static_cast<int>(bs.frames.size()) < o.frames) {
    auto f = source->next();
    if (!f) break;
    if (f->rgbd) bs.frames.push_back(std::move(*f));
  }
  if (bs.frames.empty()) throw capture::CaptureError(path, "has no RGB-D frame");
  json roomInfo;
  // The whole recording fused (a scan of the room), with the poses the pipeline uses: what each configuration's
  // per-view cost is measured over (measureConfig's ms_view), and with --room what it is also lit from.
  const auto t0 = std::chrono::steady_clock::now();
  runtime::RoomFusionOptions fusionOptions;
  fusionOptions.pose = o.pose;
  RoomFusion fusion = fuseRoom(path, fusionOptions);
  const double fuseMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (fusion.model.framesIntegrated() > 0) {
    auto mesh = std::make_shared<const reconstruction::RoomMesh>(fusion.model.mesh());
    if (mesh->triangleCount() > 0) bs.room = std::move(mesh);
  }
  if (!bs.room && !o.room)
    std::printf("%s: no room could be fused: the per-view cost is that of every pass\n", path.c_str());
  if (o.room) {
    if (!bs.room) throw capture::CaptureError(path, "--room: no frame could be fused into a room");
    roomInfo = {{"frames", fusion.model.framesIntegrated()},
                {"refused", fusion.model.framesRefused()},
                {"triangles", bs.room->triangleCount()},
                {"voxel_mib", static_cast<double>(fusion.model.bytes()) / (1 << 20)},
                {"appearance_mib", static_cast<double>(fusion.model.appearanceBytes()) / (1 << 20)},
                {"fuse_ms_median", fusion.medianFuseMs()},
                {"surface_ms_median", fusion.medianSurfaceMs()},
                {"ms", fuseMs}};
    if (o.pose != PoseMode::Tracked) {
      // The same recording fused from tracked poses, next to this one: how far its surface lies from it and
      // how much of it it covers (a scan's frames that tracking loses are refused, never fused at a guess).
      runtime::RoomFusionOptions to;
      RoomFusion tracked = fuseRoom(path, to);
      const auto mesh = tracked.model.mesh();
      const SurfaceDistance accuracy = surfaceDistance(mesh, *bs.room), coverage = surfaceDistance(*bs.room, mesh);
      roomInfo["tracked"] = {{"frames", tracked.model.framesIntegrated()},
                             {"lost", tracked.lost},
                             {"surface_mm_mean", 1e3 * accuracy.meanM},
                             {"surface_mm_p90", 1e3 * accuracy.p90M},
                             {"covers", coverage.within2cm}};
      std::printf(
          "%s: room from tracked poses: %d frames (%lld lost), surface %.1f mm from the %s room, covering %.0f %% of "
          "it\n",
          path.c_str(), tracked.model.framesIntegrated(), static_cast<long long>(tracked.lost), 1e3 * accuracy.meanM,
          toString(o.pose), 100 * coverage.within2cm);
    }
    std::printf(
        "%s: room fused from %d frames (%zu triangles, %.0f MiB of voxels, %.1f ms per frame median, %.1f ms with the "
        "depth filter)\n",
        path.c_str(), fusion.model.framesIntegrated(), bs.room->triangleCount(),
        static_cast<double>(fusion.model.bytes()) / (1 << 20), fusion.medianFuseMs(), fusion.medianSurfaceMs());
  }
  bs.W = info.colourIntrinsics.width, bs.H = info.colourIntrinsics.height;
  const int n = static_cast<int>(bs.frames.size());
  std::vector<int> refFrames;
  const int refs = std::min(o.refFrames, n);
  for (int i = 0; i < refs; ++i) refFrames.push_back(refs == 1 ? 0 : i * (n - 1) / (refs - 1));

  // Ground truth: the same inputs, path traced, with more samples around the objects.
  const int focusSpp = o.refFocusSpp > 0 ? o.refFocusSpp : 16 * o.refSpp;
  bs.refInfo = {{"session", path},       {"scene", bs.scene},       {"spp", o.refSpp},
                {"focus_spp", focusSpp}, {"bounces", o.refBounces}, {"frames", refFrames}};
  if (!roomInfo.is_null()) bs.refInfo["room"] = roomInfo;
  FrameOptions mo;
  mo.pose = o.pose;
  mo.gpu = false;
  FramePipeline measurer(bs.setup, bs.W, bs.H, mo);
  gl::Profiler none;
  double ms = 0;
  // Odometry carries the pose from frame to frame: the frames between the reference frames are tracked too.
  const bool carried = o.pose == PoseMode::Odometry || o.pose == PoseMode::Tracked;
  int measured = 0;
  for (int f : refFrames) {
    for (; carried && measured < f; ++measured) {
      capture::Frame between = bs.frames[static_cast<size_t>(measured)];
      if (between.rgbd) measurer.measure(between, none);
    }
    measured = f + 1;
    capture::Frame frame = bs.frames[f];
    const FrameResult r = measurer.measure(frame, none);
    if (!r.T_marker_camera)
      throw capture::CaptureError(
          path, "frame " + std::to_string(f) + ": no camera pose (--pose " + toString(o.pose) + ": tracking lost)");
    const ReferenceScenes scenes = reconstructedScenes(*measurer.setup(), measurer.realSurface(frame, r, none),
                                                       frame.rgbd->colourIntrinsics, *r.T_marker_camera);
    groundtruth::PathTraceOptions po;
    po.spp = o.refSpp;
    po.focusSpp = focusSpp;
    po.focus = groundtruth::virtualFocus(scenes.withObjects, scenes.camera);
    po.bounces = o.refBounces;
    ProgressBar bar(fs::path(path).filename().string() + ": reference frame " + std::to_string(f));
    po.progress = [&bar](double x) { bar(x); };
    const auto t0 = std::chrono::steady_clock::now();
    Truth t;
    t.frame = f;
    t.images = groundtruth::renderDifferential(scenes.withObjects, scenes.realOnly, scenes.camera, po);
    ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    t.delta = t.images.delta();
    t.partial = partlyVirtual(groundtruth::RayCaster(scenes.withObjects), scenes.camera);
    t.composite = compositor::compositeReference(frame.rgbd->colour, t.delta, t.images.mask);
    if (bs.truths.empty()) {
      // The reference's own noise: a second render with another seed. Each has error ≈ this / √2 against
      // the converged image, the floor under every technique's error.
      po.seed += 1;
      po.progress = nullptr;
      const auto again = groundtruth::renderDifferential(scenes.withObjects, scenes.realOnly, scenes.camera, po);
      cv::Mat shadeLike(again.rho.size(), CV_32FC4);
      const cv::Mat d2 = again.delta();
      for (int i = 0; i < static_cast<int>(d2.total()); ++i) {
        const cv::Vec3f v = d2.at<cv::Vec3f>(i);
        shadeLike.at<cv::Vec4f>(i) = {v[0], v[1], v[2], again.mask.at<uchar>(i) ? 1.f : 0.f};
      }
      const ErrorSums e = errorSums(shadeLike, t);
      t.second = d2;
      // The noise itself as an RMS: (r1 - r2)^2 / 2 per real pixel and channel is each render's variance,
      // relative to the mean r1 r2 (unbiased for the truth's square).
      cv::Mat real;
      cv::compare(t.images.mask, 0, real, cv::CMP_EQ);
      const double pixels = 3.0 * std::max(cv::countNonZero(real), 1);
      const double variance = cv::norm(t.delta, d2, cv::NORM_L2SQR, real) / 2.0 / pixels;
      const cv::Scalar products = cv::mean(t.delta.mul(d2), real);
      const double truthSq = (products[0] + products[1] + products[2]) / 3.0;
      bs.refInfo["noise_rel_rms_delta"] = truthSq > 0 ? std::sqrt(variance / truthSq) : 0.0;
      bs.refInfo["noise_rel_error_delta"] = e.absRef > 0 ? e.abs / e.absRef / std::sqrt(2.0) : 0.0;
      bs.refInfo["noise_rel_error_virtual"] = e.virtRef > 0 ? e.virtAbs / e.virtRef / std::sqrt(2.0) : 0.0;
      std::printf("%s: reference noise (two seeds, / sqrt 2): delta %.3f, virtual %.3f\n", path.c_str(),
                  bs.refInfo["noise_rel_error_delta"].get<double>(),
                  bs.refInfo["noise_rel_error_virtual"].get<double>());
    }
    bs.truths[f] = std::move(t);
  }
  bs.refInfo["ms_per_frame"] = ms / refs;
  std::printf("%s: reference %d frames, %d spp, %d bounces, %.1f s per frame\n", path.c_str(), refs, o.refSpp,
              o.refBounces, ms / refs / 1000);
  bs.refInfo["marker_pose_error"] = markerPoseError(bs, o);
  bs.refInfo["tracking"] = trackingError(bs);
  if (reference)
    bs.trueRefs =
        loadTrueReferences(path, *reference, referenceScene, bs.setup.scene, bs.setup.T_world_marker, bs.frames);
  if (!bs.trueRefs.empty()) {
    bs.refInfo["true_reference_frames"] = bs.trueRefs.size();
    std::printf("%s: %zu true reference composites (whole-pipeline error)\n", path.c_str(), bs.trueRefs.size());
  }
  return bs;
}

/// The virtual object's mean sRGB level in the composite against the truth's, over the truth's virtual
/// pixels: what a viewer sees as "too dark" (ratio - 1 < 0) or "too bright".
struct BrightnessSums {
  double ours = 0, truth = 0;
  void add(const cv::Mat& composite, const Truth& t) {
    for (int y = 0; y < composite.rows; ++y)
      for (int x = 0; x < composite.cols; ++x) {
        if (!t.images.mask.at<uchar>(y, x)) continue;
        const cv::Vec3b a = composite.at<cv::Vec3b>(y, x), b = t.composite.at<cv::Vec3b>(y, x);
        ours += a[0] + a[1] + a[2], truth += b[0] + b[1] + b[2];
      }
  }
  double ratio() const { return truth > 0 ? ours / truth : 0.0; }
};

/// Irradiance at `p` for normal n from a set of lights (shadows aside, lighting::unshadowedIrradiance) plus a
/// uniform ambient.
cv::Vec3d irradianceAt(const std::vector<lighting::SceneLight>& lights, const cv::Vec3d& ambient, const cv::Vec3d& p,
                       const cv::Vec3d& n) {
  cv::Vec3d E = ambient * CV_PI;
  for (const auto& l : lights) E += lighting::unshadowedIrradiance(l, p, n);
  return E;
}

const cv::Vec3d kAxes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

/// The irradiance at point c (marker frame) for the six axis normals in the room a synthetic session was
/// made in (mrgi synth's tabletop, rebuilt from the manifest's seed and marker; not for outdoor sessions):
/// the lamp's direct light exactly (its sphere, with shadows), plus the bounce light path traced with
/// `samples` cosine-weighted rays per normal (3 bounces) that do not see the lamp's sphere itself.
std::optional<std::array<cv::Vec3d, 6>> trueIrradianceAt(const std::string& session, const cv::Vec3d& c,
                                                         int samples = 8192) {
  const std::string path = (fs::path(session) / "manifest.json").string();
  const json manifest =
      capture::parseJson(capture::readFileBounded(path, capture::kMaxTextFileBytes, "session manifest"), path);
  const json& gt = manifest.value("ground_truth", json::object());
  if (!gt.contains("scene") || gt.contains("environment") || !manifest.contains("marker") ||
      gt["scene"].value("generator", std::string()).rfind("mrgi synth", 0) != 0)
    return std::nullopt;
  TabletopConfig tc;
  tc.tagId = capture::jsonInt(manifest["marker"], "id", "manifest.json");
  tc.tagSize = capture::jsonNumber(manifest["marker"], "size_m", "manifest.json");
  tc.seed = static_cast<uint64_t>(capture::jsonIntOr(gt["scene"], "seed", 1, "manifest.json"));
  const Tabletop table = buildTabletop(tc);
  const groundtruth::RayCaster caster(table.scene);
  groundtruth::PathTraceOptions po;
  po.bounces = 3;
  const groundtruth::PathTracer tracer(caster, po);
  const cv::Vec3d p = capture::transformPoint(table.T_world_marker, c);
  const cv::Matx33d R = capture::rotationOf(table.T_world_marker);
  std::array<cv::Vec3d, 6> out;
  for (int a = 0; a < 6; ++a) {
    const cv::Vec3d n = R * kAxes[a];
    cv::Vec3d E(0, 0, 0);
    for (size_t i = 0; i < table.scene.lights.size(); ++i) {
      const auto in = caster.incident(i, cv::Vec3f(p), cv::Vec3f(n));
      E += cv::Vec3d(in.irradiance) * std::max(0.0, n.dot(cv::Vec3d(in.direction)));
    }
    // Cosine-weighted directions about n: E = pi x mean radiance.
    cv::Vec3d t = std::abs(n[0]) < 0.9 ? cv::Vec3d(1, 0, 0) : cv::Vec3d(0, 1, 0);
    t = cv::normalize(t - n * n.dot(t));
    const cv::Vec3d b = n.cross(t);
    cv::RNG rng(0x5eed + static_cast<uint64_t>(a));
    cv::Vec3d sum(0, 0, 0);
    for (int k = 0; k < samples; ++k) {
      const double u1 = rng.uniform(0.0, 1.0), u2 = rng.uniform(0.0, 1.0);
      const double r = std::sqrt(u1), phi = 2 * CV_PI * u2;
      const cv::Vec3d d = r * std::cos(phi) * t + r * std::sin(phi) * b + std::sqrt(std::max(0.0, 1 - u1)) * n;
      sum += cv::Vec3d(tracer.trace(cv::Vec3f(p), cv::Vec3f(d), rng, false));
    }
    out[static_cast<size_t>(a)] = E + sum * (CV_PI / samples);
  }
  return out;
}

/// Lights estimated from the room against the truth at the virtual objects' centre: the angle between the
/// strongest lights' directions; the irradiance for the six axis normals against the path-traced truth of
/// the session's room (when it is a synthetic one: `trueE`), the estimate being its lights plus its SH
/// ambient; and against the listed lights plus the listed ambient (which leave out the room's bounce light:
/// a ratio above 1 there is mostly that bounce).
json lightsAgainstTruth(const LightingSetup& est, const reconstruction::RoomLights* room, const LightingSetup& truth,
                        BenchSession& bs) {
  cv::Vec3d c(0, 0, 0);
  for (const auto& o : truth.scene.objects)
    c += capture::transformPoint(capture::Pose(o.T_marker_object),
                                 0.5 * (cv::Vec3d(o.mesh.boundsMin) + cv::Vec3d(o.mesh.boundsMax)));
  if (!truth.scene.objects.empty()) c /= static_cast<double>(truth.scene.objects.size());
  auto strongest = [&](const std::vector<lighting::SceneLight>& ls) {
    cv::Vec3d dir(0, 0, 0);
    double best = -1;
    for (const auto& l : ls) {
      const cv::Vec3d toLight =
          l.type == lighting::LightType::Directional ? -l.direction : cv::normalize(l.position - c);
      const double e =
          capture::luminance(l.type == lighting::LightType::Directional
                                 ? l.irradiance
                                 : l.intensity * (1.0 / std::max((l.position - c).dot(l.position - c), 1e-8)));
      if (e > best) best = e, dir = toLight;
    }
    return dir;
  };
  const cv::Vec3d a = strongest(est.lights), b = strongest(truth.lights);
  // The estimate's irradiance: its lights, and its ambient as the shading pass sees it (the room's whole SH
  // remainder, clamped; else the uniform ambient).
  auto estimated = [&](const cv::Vec3d& n) {
    if (!room) return irradianceAt(est.lights, est.ambient, c, n);
    return irradianceAt(est.lights, {0, 0, 0}, c, n) + reconstruction::ambientShIrradiance(room->ambientSh, n);
  };
  auto compare = [&](const std::string& against, const std::function<cv::Vec3d(int)>& reference, json& out) {
    double ratioErr = 0, worst = 0;
    json perNormal = json::array();
    for (int k = 0; k < 6; ++k) {
      const double e = capture::luminance(estimated(kAxes[k])), t = capture::luminance(reference(k));
      const double r = t > 0 ? e / t : 0.0;
      perNormal.push_back(r);
      ratioErr += std::abs(r - 1) / 6, worst = std::max(worst, std::abs(r - 1));
    }
    out["irradiance_ratio_to_" + against + "_by_axis"] = perNormal;
    out["irradiance_ratio_to_" + against + "_error_mean"] = ratioErr;
    out["irradiance_ratio_to_" + against + "_error_max"] = worst;
  };
  json out = {{"dominant_angle_deg", std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180 / CV_PI},
              {"lights", est.lights.size()}};
  compare(
      "listed", [&](int k) { return irradianceAt(truth.lights, truth.ambient, c, kAxes[k]); }, out);
  if (!bs.trueIrradiance) bs.trueIrradiance = trueIrradianceAt(bs.path, c);
  if (*bs.trueIrradiance) {
    const auto& E = **bs.trueIrradiance;
    compare(
        "true", [&](int k) { return E[static_cast<size_t>(k)]; }, out);
    json axes = json::array();
    for (const auto& e : E) axes.push_back(capture::luminance(e));
    out["true_irradiance_by_axis"] = axes;
  }
  return out;
}

/// The real pixels within `radii` object radii of the objects of the pipeline's last frame (positions: its
/// G-buffer positions); nullopt when the frame has no object.
std::optional<NearObjects> nearObjects(lighting::LightingPipeline& pipe, const cv::Mat& positions, double radii) {
  const auto b = pipe.frame().objectBounds();
  if (!b) return std::nullopt;
  NearObjects near;
  near.positions = positions;
  near.centre = 0.5 * (b->first + b->second);
  near.radius = 0.5 * cv::norm(b->second - b->first);
  near.radii = radii;
  return near;
}

json shadowJson(const ShadowSums& s) { return {{"energy", s.energy()}, {"near_l1", s.nearL1()}, {"pixels", s.pixels}}; }

/// The whole pipeline with these frame options: its times a frame (all stages, the lighting's), and where the
/// session has true reference composites its errors, SSIM and the object's brightness against them ("frames": how
/// many). `truth` (lights from the room): also the lights against the true ones.
json wholePipeline(const LightingSetup& s, const FrameOptions& fo, BenchSession& bs,
                   const LightingSetup* truth = nullptr) {
  FramePipeline rp(s, bs.W, bs.H, fo);
  ErrorSums whole;
  ShadowSums shadow;  // the object's shadow within three object radii
  BrightnessSums brightness;
  double ssim = 0, ms = 0, lightingMs = 0;
  int frames = 0, timed = 0;
  const int n = static_cast<int>(bs.frames.size());
  for (int f = 0; f < n; ++f) {
    capture::Frame frame = bs.frames[f];
    gl::Profiler profiler;
    const FrameResult r = rp.process(frame, *bs.compositor, profiler);
    double frameMs = 0, frameLightingMs = 0;
    for (const auto& [stage, t] : profiler.resolve()) {
      if (stage == "read" || stage == "write") continue;
      frameMs += std::max(t.cpuMs, t.gpuMs);
      if (lighting::isLightingStage(stage)) frameLightingMs += std::max(t.cpuMs, t.gpuMs);
    }
    if (f > 0 || n == 1) ms += frameMs, lightingMs += frameLightingMs, ++timed;
    if (!r.lit) continue;
    if (const auto it = bs.trueRefs.find(f); it != bs.trueRefs.end()) {
      const FrameState st =
          frameState(rp.lighting()->downloadShade(), rp.lighting()->downloadGBuffer(0), *r.T_marker_camera);
      whole.add(errorSums(st.shade, it->second));
      if (const auto three = nearObjects(*rp.lighting(), st.positions, 3))
        shadow.add(shadowSums(st.shade, it->second, *three));
      ssim += ssimOf(r.composite, it->second.composite);
      brightness.add(r.composite, it->second);
      ++frames;
    }
  }
  json out = {{"ms_total", ms / std::max(timed, 1)}, {"ms_lighting", lightingMs / std::max(timed, 1)}};
  if (frames == 0) return out;  // no true reference: the times alone
  out.update({{"frames", frames},
              {"rel_error_delta", whole.relDelta()},
              {"rel_error_delta_interval", whole.relDeltaInterval()},
              {"rel_error_virtual", whole.relVirtual()},
              {"ssim", ssim / frames},
              {"virtual_brightness", brightness.ratio()},
              {"partly_virtual_pixels", whole.partial},
              {"shadow", shadowJson(shadow)}});
  if (truth && rp.setup()) out["lights_vs_truth"] = lightsAgainstTruth(*rp.setup(), rp.roomLights(), *truth, bs);
  return out;
}

/// A configuration's lighting ms a frame in replay over the room fused as the frames come: its per-view stages every
/// frame, and its world-space passes (what a frame with every pass rerun costs beyond them) once per refresh of the
/// room's surface (FrameOptions::fuseRefresh frames).
double replayMs(double viewMs, double everyPassMs) {
  return viewMs + std::max(everyPassMs - viewMs, 0.0) / std::max(FrameOptions{}.fuseRefresh, 1);
}

/// A configuration's measurements on one session.
json measureConfig(const BenchConfig& c, BenchSession& bs, const BenchOptions& o, double errScale,
                   std::vector<ReportImage>* images, std::vector<GalleryRow>* gallery = nullptr) {
  LightingSetup s = bs.setup;
  s.scene.technique = c.technique;
  s.scene.knobs = c.knobs;
  FrameOptions fo;
  fo.pose = o.pose;
  fo.reuse = false;  // every frame pays for every stage: the times are those of a moving camera
  FramePipeline fp(s, bs.W, bs.H, fo);
  const int n = static_cast<int>(bs.frames.size());
  std::map<std::string, double> stageSum;
  int timed = 0;
  ErrorSums err, whole;
  BrightnessSums brightness;
  double ssimSum = 0, wholeSsim = 0, flickNum = 0, flickDen = 0;
  int wholeFrames = 0;
  size_t gpuBytes = 0;
  std::optional<FrameState> prev;
  std::optional<UnbiasedError> unbiased;                     // on the reference frame rendered twice
  ShadowSums shadow, wholeShadow;                            // the object's shadow within three object radii
  nlohmann::json techniqueStats = nlohmann::json::object();  // the last lit frame's (counts: points, voxels, ...)
  const std::string name = c.technique.name;
  for (int f = 0; f < n; ++f) {
    capture::Frame frame = bs.frames[f];
    gl::Profiler profiler;
    const FrameResult r = fp.process(frame, *bs.compositor, profiler);
    const auto stages = profiler.resolve();
    if (f > 0 || n == 1) {
      for (const auto& [stage, t] : stages) stageSum[stage] += std::max(t.cpuMs, t.gpuMs);
      ++timed;
    }
    if (!r.lit) {
      prev.reset();
      continue;
    }
    lighting::LightingPipeline& pipe = *fp.lighting();
    gpuBytes = std::max(gpuBytes, pipe.gpuBytes());
    if (r.info.contains("techniques")) techniqueStats = r.info["techniques"];
    FrameState st = frameState(pipe.downloadShade(), pipe.downloadGBuffer(0), *r.T_marker_camera);
    const std::optional<NearObjects> near = nearObjects(pipe, st.positions, 2);  // the contact shadow and bounce
    // The object's shadow of the room reaches further than its contact shadow.
    const std::optional<NearObjects> three = nearObjects(pipe, st.positions, 3);
    if (prev) {
      const auto [a, b] = flickerSums(*prev, st, frame.rgbd->colourIntrinsics);
      flickNum += a, flickDen += b;
    }
    if (const auto it = bs.truths.find(f); it != bs.truths.end()) {
      const ErrorSums e = errorSums(st.shade, it->second, near ? &*near : nullptr);
      err.add(e);
      if (three) shadow.add(shadowSums(st.shade, it->second, *three));
      if (const auto u = unbiasedDeltaError(st.shade, it->second)) unbiased = u;
      if (gallery && c.varied.empty() && it == bs.truths.begin())
        gallery->push_back({name, r.composite.clone(), st.shade.clone()});
      ssimSum += ssimOf(r.composite, it->second.composite);
      if (images && c.varied.empty() && it == bs.truths.begin()) {
        images->push_back({name + " (defaults), frame " + std::to_string(f), r.composite});
        images->push_back(
            {name + ": error against the reference (real pixels |delta - reference|, red too dark, white = " +
                 std::to_string(errScale).substr(0, 6) + " W/m^2/sr; the object relative, blue too dark, white = 10 %)",
             errorImage(st.shade, it->second, errScale)});
      }
    }
    if (const auto it = bs.trueRefs.find(f); it != bs.trueRefs.end()) {
      whole.add(errorSums(st.shade, it->second));
      if (three) wholeShadow.add(shadowSums(st.shade, it->second, *three));
      wholeSsim += ssimOf(r.composite, it->second.composite);
      brightness.add(r.composite, it->second);
      ++wholeFrames;
    }
    prev = std::move(st);
  }
  // What the configuration costs a frame where the world holds still and the camera moves, as in replay over the
  // room fused as the frames come: the lighting's stages over the session's fused room, whose world-space passes
  // run on the first (untimed) frame only. With --room that run is also measured against the true references, and
  // once more with the lights estimated from the room instead of the session's true ones.
  std::optional<json> roomRecord, roomLightsRecord;
  std::optional<double> viewMs;
  if (bs.room) {
    FrameOptions ro = fo;
    ro.room = bs.room;
    json room = wholePipeline(s, ro, bs);
    viewMs = room["ms_lighting"].get<double>();
    if (o.room && room.contains("frames")) roomRecord = std::move(room);
    if (o.room && !bs.trueRefs.empty() && s.scene.lightSource != lighting::LightSource::Room) {
      LightingSetup rl = s;
      rl.scene.lightSource = lighting::LightSource::Room;
      rl.lights.clear();
      rl.ambient = {0, 0, 0};
      json roomLights = wholePipeline(rl, ro, bs, &s);
      if (roomLights.contains("frames")) roomLightsRecord = std::move(roomLights);
    }
  }
  json msStages = json::object();
  double total = 0, lightingMs = 0;
  for (const auto& [stage, ms] : stageSum) {
    if (stage == "read" || stage == "write") continue;
    const double mean = ms / std::max(timed, 1);
    msStages[stage] = mean;
    total += mean;
    if (lighting::isLightingStage(stage)) lightingMs += mean;
  }
  const double view = viewMs.value_or(lightingMs);  // no room fused: the cost of every pass
  json r = {{"session", bs.path},
            {"ms_total", total},
            {"ms_lighting", lightingMs},
            {"ms_view", view},
            {"ms_replay", replayMs(view, lightingMs)},
            {"ms_stages", msStages},
            {"gpu_mb", static_cast<double>(gpuBytes) / (1024.0 * 1024.0)},
            {"rmse_delta", err.rmse()},
            {"rel_error_delta", err.relDelta()},
            {"rel_error_delta_near", err.relDeltaNear()},
            {"rel_error_virtual", err.relVirtual()},
            {"ssim", bs.truths.empty() ? 0.0 : ssimSum / static_cast<double>(bs.truths.size())},
            {"flicker", flickDen > 0 ? flickNum / flickDen : 0.0},
            {"silhouette_mismatch_pixels", err.mismatched},
            {"partly_virtual_pixels", err.partial},
            {"technique_stats", techniqueStats}};
  if (shadow.pixels > 0) r["shadow"] = shadowJson(shadow);
  // The real-pixel delta's relative RMS error without the reference's noise, with its 95 % interval.
  if (unbiased)
    r["rel_rms_delta_unbiased"] = {
        {"value", unbiased->rel()}, {"lo", unbiased->relLo()}, {"hi", unbiased->relHi()}, {"pixels", unbiased->pixels}};
  if (wholeFrames > 0)
    r["whole_pipeline"] = {{"frames", wholeFrames},
                           {"rel_error_delta", whole.relDelta()},
                           {"rel_error_delta_interval", whole.relDeltaInterval()},
                           {"rel_error_virtual", whole.relVirtual()},
                           {"ssim", wholeSsim / wholeFrames},
                           {"virtual_brightness", brightness.ratio()},
                           {"silhouette_mismatch_pixels", whole.mismatched},
                           {"partly_virtual_pixels", whole.partial},
                           {"shadow", shadowJson(wholeShadow)}};
  if (roomRecord) r["whole_pipeline_room"] = *roomRecord;
  if (roomLightsRecord) r["whole_pipeline_room_lights"] = *roomLightsRecord;
  return r;
}

int runSweep(const BenchOptions& o) {
  std::vector<BenchSession> sessions;
  for (const std::string& path : o.sessions) sessions.push_back(loadBenchSession(path, o));
  int W = 0, H = 0;
  for (const auto& bs : sessions) W = std::max(W, bs.W), H = std::max(H, bs.H);
  gl::ContextConfig cfg;
  cfg.backend = gl::parseBackend(o.gl);
  cfg.width = W;
  cfg.height = H;
  auto context = gl::createContext(cfg);
  for (auto& bs : sessions) bs.compositor = std::make_unique<compositor::Compositor>(bs.W, bs.H);
  std::vector<ReportImage> images;
  std::vector<std::vector<GalleryRow>> galleries(sessions.size());  // --gallery: per session, a row per technique
  const BenchSession& first = sessions.front();
  for (const auto& [f, t] : first.truths)
    images.push_back({"reference composite, frame " + std::to_string(f), t.composite});
  double errScale = 0;  // one error-image scale for all: the reference delta's 99th percentile magnitude
  {
    std::vector<double> mags;
    const Truth& t = first.truths.begin()->second;
    for (int i = 0; i < static_cast<int>(t.delta.total()); ++i)
      if (!t.images.mask.at<uchar>(i))
        mags.push_back(std::abs(capture::luminance(cv::Vec3d(t.delta.at<cv::Vec3f>(i)))));
    errScale = lighting::percentile99(mags);
  }

  json records = json::array();
  // The knobs start from the first session's scene file (the same file for all).
  std::vector<BenchConfig> configs = sweepConfigs(o.technique, o.quick, first.setup.scene.knobs);
  auto measureFrom = [&](size_t from) {
    for (size_t ci = from; ci < configs.size(); ++ci) {
      const BenchConfig& c = configs[ci];
      json perSession = json::array();
      for (size_t si = 0; si < sessions.size(); ++si)
        perSession.push_back(measureConfig(c, sessions[si], o, errScale, si == 0 ? &images : nullptr,
                                           o.gallery.empty() ? nullptr : &galleries[si]));
      // The record: each measure's mean over the sessions (each session weighs the same), per session below.
      json r = {{"technique", c.technique.name}, {"varied", c.varied}, {"knobs", knobsJson(c)}};
      for (const char* key :
           {"ms_total", "ms_lighting", "ms_view", "ms_replay", "gpu_mb", "rmse_delta", "rel_error_delta",
            "rel_error_delta_near", "rel_error_virtual", "ssim", "flicker", "silhouette_mismatch_pixels"}) {
        double sum = 0;
        for (const auto& p : perSession) sum += p[key].get<double>();
        r[key] = sum / static_cast<double>(perSession.size());
      }
      json stages = json::object();
      for (const auto& p : perSession)
        for (const auto& [stage, ms] : p["ms_stages"].items())
          stages[stage] = stages.value(stage, 0.0) + ms.get<double>() / static_cast<double>(perSession.size());
      r["ms_stages"] = stages;
      r["sessions"] = perSession;
      std::string wholeText;
      for (const auto& p : perSession)
        if (p.contains("shadow")) {
          char buf[120];
          std::snprintf(buf, sizeof buf, ", shadow (%s) energy %.2f near L1 %.2f",
                        fs::path(p["session"].get<std::string>()).filename().c_str(),
                        p["shadow"]["energy"].get<double>(), p["shadow"]["near_l1"].get<double>());
          wholeText += buf;
        }
      for (const auto& p : perSession)
        if (p.contains("rel_rms_delta_unbiased")) {
          char buf[120];
          const json& u = p["rel_rms_delta_unbiased"];
          std::snprintf(buf, sizeof buf, ", delta RMS without the reference's noise (%s) %.3f [%.3f, %.3f]",
                        fs::path(p["session"].get<std::string>()).filename().c_str(), u["value"].get<double>(),
                        u["lo"].get<double>(), u["hi"].get<double>());
          wholeText += buf;
        }
      for (const auto& p : perSession)
        if (p.contains("whole_pipeline")) {
          char buf[200];
          const auto interval = [](const json& w) {
            const auto i = w.value("rel_error_delta_interval", std::array<double, 2>{0, 0});
            return std::make_pair(i[0], i[1]);
          };
          const auto [lo, hi] = interval(p["whole_pipeline"]);
          std::snprintf(buf, sizeof buf, ", whole pipeline (%s): delta %.3f [%.3f, %.3f] virtual %.3f SSIM %.4f",
                        fs::path(p["session"].get<std::string>()).filename().c_str(),
                        p["whole_pipeline"]["rel_error_delta"].get<double>(), lo, hi,
                        p["whole_pipeline"]["rel_error_virtual"].get<double>(),
                        p["whole_pipeline"]["ssim"].get<double>());
          wholeText += buf;
          for (const char* mode : {"whole_pipeline_room", "whole_pipeline_room_lights"})
            if (p.contains(mode)) {
              const json& w = p[mode];
              const auto [rlo, rhi] = interval(w);
              std::snprintf(
                  buf, sizeof buf, "; from the room%s: delta %.3f [%.3f, %.3f] virtual %.3f SSIM %.4f (%.0f ms)",
                  std::string(mode) == "whole_pipeline_room" ? "" : ", its lights", w["rel_error_delta"].get<double>(),
                  rlo, rhi, w["rel_error_virtual"].get<double>(), w["ssim"].get<double>(), w["ms_total"].get<double>());
              wholeText += buf;
            }
        }
      // The sweep counts its own configurations; the combined moves that follow it, theirs.
      const std::string counter = (from > 0 ? "[combined " : "[") + std::to_string(ci - from + 1) + "/" +
                                  std::to_string(configs.size() - from) + "]";
      std::printf(
          "%s %-16s %-14s %-70s %7.1f ms (lighting %7.1f, per view %7.1f), delta err %.3f, virtual err %.3f, SSIM "
          "%.4f, flicker %.3f%s\n",
          counter.c_str(), r["technique"].get<std::string>().c_str(), c.varied.c_str(), r["knobs"].dump().c_str(),
          r["ms_total"].get<double>(), r["ms_lighting"].get<double>(), r["ms_view"].get<double>(),
          r["rel_error_delta"].get<double>(), r["rel_error_virtual"].get<double>(), r["ssim"].get<double>(),
          r["flicker"].get<double>(), wholeText.c_str());
      std::fflush(stdout);
      records.push_back(r);
    }
  };
  measureFrom(0);
  // Then each technique's free knob moves together (evaluation::combinedConfigs), measured the same way.
  const size_t swept = configs.size();
  for (BenchConfig& c : combinedConfigs(configs, records)) configs.push_back(std::move(c));
  measureFrom(swept);
  json sessionInfo = json::array();
  for (const auto& bs : sessions) sessionInfo.push_back(bs.refInfo);
  json doc = {{"generated_by", "mrgi bench"},
              {"session", o.sessions.size() == 1 ? json(o.sessions.front()) : json(o.sessions)},
              {"scene", first.scene},
              {"frames", first.frames.size()},
              {"gl", context->renderer()},
              {"reference", first.refInfo},
              {"references", sessionInfo},
              {"process", processSettingsInEffect()},
              {"records", records}};
  if (!o.trackingPixels.empty()) {
    doc["tracking_pixels"] = tagPixelJson(tagPixelTable(o.trackingPixels));
  }
  doc["presets"] = choosePresets(records);
  doc["preset_differences"] = presetDifferences(doc["presets"]);
  auto write = [](const std::string& path, const std::function<void()>& fn) {
    if (path.empty()) return;
    createParentDirectory(path);
    fn();
  };
  write(o.json, [&] { capture::writeFileAtomically(o.json, doc.dump(2) + "\n"); });
  write(o.csv, [&] { writeCsv(o.csv, records); });
  write(o.html, [&] { writeHtml(o.html, doc, images); });
  for (size_t si = 0; si < sessions.size() && !o.gallery.empty(); ++si) {
    const BenchSession& bs = sessions[si];
    if (galleries[si].empty() || bs.truths.empty()) continue;
    const auto& [f, t] = *bs.truths.begin();
    const std::string name = fs::path(bs.path).filename().string();
    const std::string file = (fs::path(o.gallery) / (name + ".png")).string();
    writePng(file,
             galleryImage(name + ", frame " + std::to_string(f) +
                              ": each technique's defaults against the path-traced reference",
                          t.composite, t.delta, t.images.mask, galleries[si]),
             "mrgi bench");
    std::printf("gallery: %s\n", file.c_str());
  }
  write(o.presets, [&] {
    json p = {{"generated_by", "mrgi bench"}, {"session", doc["session"]},
              {"gl", context->renderer()},    {"process", doc["process"]},
              {"presets", doc["presets"]},    {"preset_differences", doc["preset_differences"]}};
    capture::writeFileAtomically(o.presets, p.dump(2) + "\n");
  });
  for (const char* name : {"fast", "balanced", "accurate"})
    if (doc["presets"].contains(name))
      std::printf("preset %-8s: %s %s\n", name, doc["presets"][name]["technique"].get<std::string>().c_str(),
                  doc["presets"][name]["knobs"].dump().c_str());
  // Neighbouring presets told apart by the real-pixel delta only where their 95 % intervals do not overlap.
  for (const char* pair : {"fast_vs_balanced", "balanced_vs_accurate"}) {
    if (!doc["preset_differences"].contains(pair)) continue;
    const json& d = doc["preset_differences"][pair];
    std::string text;
    for (const json& s : d["sessions"]) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "%s%s %.3f [%.3f, %.3f] against %.3f [%.3f, %.3f]", text.empty() ? "" : "; ",
                    fs::path(s["session"].get<std::string>()).filename().c_str(), s["a"][0].get<double>(),
                    s["a"][1].get<double>(), s["a"][2].get<double>(), s["b"][0].get<double>(), s["b"][1].get<double>(),
                    s["b"][2].get<double>());
      text += buf;
    }
    std::printf("presets %s: %s (real-pixel delta without the reference's noise: %s)\n", pair,
                d["resolved"].get<bool>() ? "told apart" : "within each other's 95 % intervals, not told apart",
                text.c_str());
  }
  // Where everything went, one line each, last.
  for (const auto& [what, path] : {std::pair<const char*, const std::string*>{"json", &o.json},
                                   {"csv", &o.csv},
                                   {"html report", &o.html},
                                   {"presets", &o.presets}})
    if (!path->empty()) std::printf("%s: %s\n", what, fs::absolute(*path).string().c_str());
  return 0;
}

}  // namespace

int runBench(const BenchOptions& o) {
  if (o.against == "bruteforce") {
    if (o.technique.empty()) throw std::invalid_argument("--against bruteforce needs --technique");
    return runBruteForce(o);
  }
  return runSweep(o);
}

}  // namespace mrgi::evaluation
