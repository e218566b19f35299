// mrgi bench: speed/accuracy of the lighting techniques' knobs. Kinect-VAL: the sparse method (gather on
// sparse points, occlusion, per-vertex interpolation, per-pixel evaluation) against the brute force (every
// VAL gathered at every visible pixel of the object), both run by the lighting pipeline on a recorded frame:
// its RGB-D pixels are the VALs, its depth mesh occludes the object, and the error is measured on the
// object's pixels.
#include <chrono>
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/registration.h"
#include "capture/session.h"
#include "gl/context.h"
#include "gl/profiler.h"
#include "lighting/pipeline.h"
#include "reconstruction/depth.h"
#include "reconstruction/depth_filter.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::app {
namespace {

struct BenchOptions {
  std::string technique = "kinect-val";
  std::string json;
  std::string session = "recordings/tabletop-synth";
  std::string model = "recordings/models/sphere.ply";
  std::vector<int> valCounts{1024, 4096, 16384, 65536};
  std::vector<int> sparseCounts{256, 1024, 4096};
  int kCache = 128;
  int repeats = 3;
  double scale = 0.06;
  std::string occlusion = "both";
  std::string gl = "osmesa";
};

/// Stage times of one pipeline run (ms, the larger of CPU wall and GPU time per stage).
std::map<std::string, double> stageMs(gl::Profiler& profiler) {
  std::map<std::string, double> out;
  for (const auto& [name, t] : profiler.resolve()) out[name] = std::max(t.cpuMs, t.gpuMs);
  return out;
}

/// Best (per stage) over `repeats` runs of the pipeline.
std::map<std::string, double> bestStages(lighting::LightingPipeline& pipe, const lighting::CameraView& view, int repeats) {
  gl::Profiler profiler;
  std::map<std::string, double> best;
  for (int i = 0; i < repeats; ++i) {
    pipe.run(view, {}, {0, 0, 0}, &profiler);
    for (const auto& [name, ms] : stageMs(profiler)) best[name] = best.count(name) ? std::min(best[name], ms) : ms;
  }
  return best;
}

int runBench(const BenchOptions& o) {
  if (o.technique != "kinect-val")
    throw std::invalid_argument("--technique " + o.technique + ": only kinect-val is benchmarked so far");
  auto source = capture::open(o.session);
  auto frame = source->next();
  if (!frame || !frame->rgbd) throw capture::CaptureError(o.session, "has no RGB-D frame");
  capture::RgbdFrame& rgbd = *frame->rgbd;
  capture::ensureRegistered(rgbd);
  // The camera pose in the object's world (marker frame with ground truth, else the camera frame).
  capture::Pose T_world_camera = capture::identityPose();
  bool onMarker = true;
  if (const auto* s = dynamic_cast<const capture::SessionSource*>(source.get());
      s && frame->groundTruthT_world_camera && s->manifest().groundTruth.contains("T_world_marker")) {
    const auto T_world_marker = capture::poseFromJson(s->manifest().groundTruth["T_world_marker"], o.session, "ground_truth.T_world_marker");
    T_world_camera = capture::inversePose(T_world_marker) * *frame->groundTruthT_world_camera;
  } else {
    onMarker = false;  // no marker frame: 1 m in front of the camera
  }
  const cv::Mat positions = reconstruction::backProject(rgbd.depth, rgbd.colourIntrinsics);
  const cv::Mat normals = reconstruction::computeNormals(positions);
  const auto all = lighting::valsFromRgbd(positions, normals, capture::decodeSrgb(rgbd.colour), rgbd.colourIntrinsics,
                                          T_world_camera, 1);
  if (all.empty()) throw capture::CaptureError(o.session, "frame 0 has no valid depth to make VALs from");

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
    pc.technique = lighting::Technique::KinectVal;
    pc.val.kCache = o.kCache;
    pc.val.sparsePoints = sparse;
    pc.val.occlusion = occlusion;
    pc.val.bruteForce = bruteForce;
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
    auto brute = makePipeline(64, false, true);
    brute->setRealVals(vals);
    const auto bruteStages = bestStages(*brute, view, std::max(1, std::min(o.repeats, 2)));
    const cv::Mat reference = brute->downloadShade();
    const size_t pixels = brute->valStats().receivers;
    const double msBrute = bruteStages.at("val.gather");
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
        const double msPrecompute = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        pipe->setRealVals(vals);
        const auto stages = bestStages(*pipe, view, o.repeats);
        const cv::Mat shade = pipe->downloadShade();
        double err = 0;
        for (int i = 0; i < static_cast<int>(shade.total()); ++i) {
          const cv::Vec4f a = shade.at<cv::Vec4f>(i), b = reference.at<cv::Vec4f>(i);
          if (b[3] > 0.5f) err += std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
        }
        json msStages = json::object();
        double msSparse = 0;
        for (const char* stage : {"val.upload", "val.gather", "val.occlude", "val.shade"})
          if (stages.count(stage)) {
            msStages[stage] = stages.at(stage);
            msSparse += stages.at(stage);
          }
        msStages["val.precompute"] = msPrecompute;  // sparse points + k-d tree weights, once per mesh
        json r = {{"technique", "kinect-val"},
                  {"knobs", {{"vals", vals.size()}, {"sparse_points", sparseCount}, {"k_cache", o.kCache}, {"occlusion", occlusion}}},
                  {"receivers_bruteforce", pixels},
                  {"ms_sparse", msSparse},
                  {"ms_stages", msStages},
                  {"ms_bruteforce", msBrute},
                  {"speedup", msSparse > 0 ? msBrute / msSparse : 0.0},
                  {"rel_error_vs_bruteforce", refSum > 0 ? err / refSum : 0.0}};
        std::printf("kinect-val vals %6zu sparse %5d occlusion %d: sparse %8.2f ms, brute force %9.2f ms over %zu pixels "
                    "(x%.1f), rel. error %.4f\n",
                    vals.size(), sparseCount, occlusion ? 1 : 0, msSparse, msBrute, pixels, r["speedup"].get<double>(),
                    r["rel_error_vs_bruteforce"].get<double>());
        std::fflush(stdout);
        records.push_back(r);
      }
  }
  json out = {{"session", o.session}, {"model", o.model}, {"gl", context->renderer()}, {"records", records}};
  if (!o.json.empty()) {
    if (!fs::path(o.json).parent_path().empty()) fs::create_directories(fs::path(o.json).parent_path());
    capture::writeFileAtomically(o.json, out.dump(2) + "\n");
  }
  return 0;
}

}  // namespace

Action addBench(CLI::App& app) {
  auto o = std::make_shared<BenchOptions>();
  app.add_option("--technique", o->technique, "technique to sweep (kinect-val)");
  app.add_option("--json", o->json, "write one record per configuration (JSON)");
  app.add_option("--session", o->session, "session whose first RGB-D frame provides the VALs");
  app.add_option("--model", o->model, "virtual object, resting on the marker plane at its centre");
  app.add_option("--scale", o->scale, "model scale (the bundled unit sphere: its radius in metres)")
      ->check(CLI::Range(1e-3, 10.0));
  app.add_option("--occlusion", o->occlusion, "sparse runs with disc occlusion off, on or both")
      ->check(CLI::IsMember({"off", "on", "both"}));
  app.add_option("--vals", o->valCounts, "VAL counts to sweep (e.g. 1024,16384,262144)")->delimiter(',');
  app.add_option("--sparse", o->sparseCounts, "sparse point counts to sweep (e.g. 256,4096,16384)")->delimiter(',');
  app.add_option("--k-cache", o->kCache, "VALs per shared-memory tile (16..512)")->check(CLI::Range(16, 512));
  app.add_option("--repeats", o->repeats, "timing repeats (best is kept)")->check(CLI::PositiveNumber);
  app.add_option("--gl", o->gl, "GL backend: osmesa (default), egl")->check(CLI::IsMember({"osmesa", "egl"}));
  return [o] { return runBench(*o); };
}

}  // namespace mrgi::app
