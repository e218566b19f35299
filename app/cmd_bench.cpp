// mrgi bench: speed/accuracy of the lighting techniques' knobs. Kinect-VAL: the sparse method (gather on
// sparse points, occlusion, per-vertex interpolation) against brute force (every VAL at every receiver),
// on VALs from a recorded RGB-D frame lighting a virtual object.
#include <chrono>
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "app/commands.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/frame_source.h"
#include "capture/registration.h"
#include "capture/session.h"
#include "gl/context.h"
#include "lighting/val_gpu.h"
#include "reconstruction/depth.h"

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
  int receivers = 16384;  // brute force: visible pixels of the object
  int repeats = 3;
  std::string gl = "osmesa";
};

double nowMs() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// Best of `repeats` wall times of fn, finished on the GPU (glFinish).
template <class F>
double timeMs(int repeats, F&& fn) {
  double best = 1e300;
  for (int i = 0; i < repeats; ++i) {
    glFinish();
    const double t0 = nowMs();
    fn();
    glFinish();
    best = std::min(best, nowMs() - t0);
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
  cv::Vec3d objectAt(0, 0, 0.06);
  if (const auto* s = dynamic_cast<const capture::SessionSource*>(source.get());
      s && frame->groundTruthT_world_camera && s->manifest().groundTruth.contains("T_world_marker")) {
    const auto T_world_marker = capture::poseFromJson(s->manifest().groundTruth["T_world_marker"], o.session, "ground_truth.T_world_marker");
    T_world_camera = capture::inversePose(T_world_marker) * *frame->groundTruthT_world_camera;
  } else {
    objectAt = {0, 0, 1.0};  // 1 m in front of the camera
  }
  const cv::Mat positions = reconstruction::backProject(rgbd.depth, rgbd.colourIntrinsics);
  const cv::Mat normals = reconstruction::computeNormals(positions);
  const auto all = lighting::valsFromRgbd(positions, normals, capture::decodeSrgb(rgbd.colour), rgbd.colourIntrinsics,
                                          T_world_camera, 1);
  if (all.empty()) throw capture::CaptureError(o.session, "frame 0 has no valid depth to make VALs from");

  lighting::Mesh mesh = lighting::loadMesh(o.model);
  const float scale = 0.06f;
  for (auto& p : mesh.positions) p = p * scale + cv::Vec3f(objectAt);
  mesh.computeBounds();
  const cv::Vec3f eye(capture::translationOf(T_world_camera));
  const float exponent = lighting::phongExponent(0.5f);
  const cv::Vec3f albedo(0.8f, 0.8f, 0.8f), specular(0.2f, 0.2f, 0.2f);
  auto receiverAt = [&](const cv::Vec3f& p, const cv::Vec3f& n) {
    return lighting::Receiver{p, n, cv::normalize(eye - p), exponent};
  };
  std::vector<lighting::Receiver> vertexReceivers;
  for (size_t v = 0; v < mesh.positions.size(); ++v) vertexReceivers.push_back(receiverAt(mesh.positions[v], mesh.normals[v]));
  const auto dense = lighting::sampleSparsePoints(mesh, o.receivers);
  std::vector<lighting::Receiver> pixels;
  for (size_t i = 0; i < dense.positions.size(); ++i) pixels.push_back(receiverAt(dense.positions[i], dense.normals[i]));

  gl::ContextConfig cfg;
  cfg.backend = gl::parseBackend(o.gl);
  cfg.width = cfg.height = 16;
  auto context = gl::createContext(cfg);
  lighting::ValGpu gpu(o.kCache);
  json records = json::array();
  for (int valCount : o.valCounts) {
    // An even subsample of the frame's VALs, each carrying its share of the frame's light.
    std::vector<lighting::Val> vals;
    const size_t n = std::min<size_t>(valCount, all.size());
    for (size_t i = 0; i < n; ++i) {
      lighting::Val v = all[i * all.size() / n];
      const float share = static_cast<float>(all.size()) / static_cast<float>(n);
      v.area *= share;
      v.flux *= share;
      vals.push_back(v);
    }
    lighting::setValWeights(vals);
    gpu.setVals(vals);
    // Brute force at the vertices (error reference) and at `receivers` pixel-like points (its cost).
    gpu.gather(vertexReceivers);
    std::vector<cv::Vec3f> bruteE, bruteS;
    gpu.downloadSums(bruteE, bruteS);
    const double msBrute = timeMs(o.repeats, [&] { gpu.gather(pixels); });
    double bruteSum = 0;
    for (size_t v = 0; v < bruteE.size(); ++v) bruteSum += cv::norm(lighting::valRadiance(bruteE[v], bruteS[v], albedo, specular, exponent), cv::NORM_L1);
    for (int sparseCount : o.sparseCounts)
      for (bool occlusion : {false, true}) {
        auto points = lighting::sampleSparsePoints(mesh, sparseCount);
        const auto weights = lighting::vertexWeights(mesh, points);
        std::vector<lighting::Receiver> sparse;
        for (size_t i = 0; i < points.positions.size(); ++i) sparse.push_back(receiverAt(points.positions[i], points.normals[i]));
        const double msGather = timeMs(o.repeats, [&] { gpu.gather(sparse); });
        const double msOcclusion = occlusion ? timeMs(o.repeats, [&] {
          gpu.gather(sparse);
          gpu.occlude(points.positions, points.normals, points.discRadius);
        }) - msGather : 0.0;
        // The last timed run left this configuration's VPLs on the GPU.
        const auto vpls = gpu.downloadVpls();
        double err = 0;
        for (size_t v = 0; v < mesh.positions.size(); ++v) {
          cv::Vec3f E, S;
          lighting::evaluateVpl(lighting::interpolateVpl(weights, v, vpls), vertexReceivers[v], E, S);
          const cv::Vec3f L = lighting::valRadiance(E, S, albedo, specular, exponent);
          const cv::Vec3f B = lighting::valRadiance(bruteE[v], bruteS[v], albedo, specular, exponent);
          err += cv::norm(L - B, cv::NORM_L1);
        }
        const double msSparse = msGather + msOcclusion;
        json r = {{"technique", "kinect-val"},
                  {"knobs", {{"vals", vals.size()}, {"sparse_points", sparseCount}, {"k_cache", o.kCache}, {"occlusion", occlusion}}},
                  {"receivers_bruteforce", pixels.size()},
                  {"ms_sparse", msSparse},
                  {"ms_stages", {{"val.gather", msGather}, {"val.occlusion", msOcclusion}}},
                  {"ms_bruteforce", msBrute},
                  {"speedup", msSparse > 0 ? msBrute / msSparse : 0.0},
                  {"rel_error_vs_bruteforce", bruteSum > 0 ? err / bruteSum : 0.0}};
        std::printf("kinect-val vals %6zu sparse %5d occlusion %d: sparse %8.2f ms, brute force %9.2f ms (x%.1f), rel. error %.4f\n",
                    vals.size(), sparseCount, occlusion ? 1 : 0, msSparse, msBrute, r["speedup"].get<double>(),
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
  app.add_option("--model", o->model, "virtual object (placed 6 cm above the marker, 6 cm radius for the sphere)");
  app.add_option("--vals", o->valCounts, "VAL counts to sweep (e.g. 1024,16384,262144)")->delimiter(',');
  app.add_option("--sparse", o->sparseCounts, "sparse point counts to sweep (e.g. 256,4096,16384)")->delimiter(',');
  app.add_option("--k-cache", o->kCache, "VALs per shared-memory tile (16..512)")->check(CLI::Range(16, 512));
  app.add_option("--receivers", o->receivers, "brute-force receivers (visible object pixels)")->check(CLI::PositiveNumber);
  app.add_option("--repeats", o->repeats, "timing repeats (best is kept)")->check(CLI::PositiveNumber);
  app.add_option("--gl", o->gl, "GL backend: osmesa (default), egl")->check(CLI::IsMember({"osmesa", "egl"}));
  return [o] { return runBench(*o); };
}

}  // namespace mrgi::app
