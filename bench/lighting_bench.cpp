// Lighting techniques' cost on the GL backend of this machine (OSMesa/llvmpipe unless MRGI_GL=egl): the
// imperfect volumes' stages against their work, and splatting's against its light count. Run e.g.
//   build/bench/lighting_bench --benchmark_counters_tabular=true
// Each run lights a floor 2 m wide with a red wall and a sphere of radius 6 cm on it (the region around the
// sphere: 48 cm), one point light and an ambient, at 320 x 240. Counters: the mean wall milliseconds of each
// imperfect-volume stage per run (the GPU finishes each stage before the next begins), the points voxelised, the voxels
// gathered, and `work` = voxels gathered x rays x passes (the gather's unit of work; passes = max(1, bounces) per scene
// version, two versions). Splatting: the mean milliseconds of its importance, sampling and splat passes, the
// lights splatted and the overdraw (splats per pixel, mean and largest; the splat_overdraw view).
// Precomputed illuminance composition: its precompute's parts (ms, once per configuration: surfels,
// hierarchy, receivers, caches), the mean ms of its per-run stages (surfel lighting with the bounce and the
// pull-up, the caches' gather, the read-out), caches x links and its GPU memory.
// The shading pass's footprint (CPU): its time over a frame's mesh against the mesh's triangles and the lights.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>

#include "gl/context.h"
#include "lighting/pipeline.h"
#include "lighting/scene_file.h"
#include "lighting/shadow_footprint.h"
#include "lighting/techniques/registry.h"

using namespace mrgi;
using namespace mrgi::lighting;

namespace {

std::unique_ptr<gl::Context> benchContext() {
  gl::ContextConfig cc;
  cc.width = 320;
  cc.height = 240;
  if (const char* b = std::getenv("MRGI_GL")) cc.backend = gl::parseBackend(b);
  return gl::createContext(cc);
}

PipelineConfig benchConfig(const std::string& technique) {
  PipelineConfig cfg;
  cfg.width = 320;
  cfg.height = 240;
  cfg.technique = parseTechniqueChoice(technique, &cfg.knobs);
  return cfg;
}

/// Runs the bench scene with `cfg` once to warm up, then once per iteration with every stage timed; the
/// stages' mean wall milliseconds. `after` runs after each timed run.
std::map<std::string, double> runScene(benchmark::State& state, const PipelineConfig& cfg,
                                       const std::function<void(const LightingPipeline&)>& after = {}) {
  VirtualObject sphere;
  sphere.mesh = loadMesh(std::string(MRGI_SOURCE_DIR) + "/recordings/models/sphere.ply");
  for (auto& p : sphere.mesh.positions) p *= 0.06f;
  sphere.mesh.computeBounds();
  sphere.material.albedo = {0.8f, 0.8f, 0.8f};
  sphere.T_marker_object = capture::makePose(cv::Matx33d::eye(), {-0.2, 0.0, 0.06});
  LightingPipeline pipe(cfg, {sphere});
  std::vector<MeshVertex> v;
  std::vector<uint32_t> idx;
  appendGridQuad(v, idx, {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, {0.5f, 0.5f, 0.5f},
                 200);  // 1 cm triangles, like a depth mesh
  appendGridQuad(v, idx, {-0.4f, -1, 0}, {0, 2, 0}, {0, 0, 1.5f}, {0.8f, 0.1f, 0.1f}, 150);
  pipe.setRealMesh(v, idx);
  CameraView cam;
  cam.intrinsics = {320, 240, 300, 300, 159.5, 119.5};
  cam.T_world_camera = capture::lookAtPose({0.4, -0.6, 0.5}, {-0.2, 0.0, 0.05});
  SceneLight lamp;
  lamp.position = {0.3, -0.3, 1.0};
  lamp.intensity = {3, 3, 3};
  pipe.run(cam, {lamp}, {0.2, 0.2, 0.2}, nullptr);  // warm-up: buffers allocated, shaders compiled
  std::map<std::string, double> sum;
  int runs = 0;
  for (auto _ : state) {
    pipe.invalidate();
    gl::Profiler profiler(true);  // each stage's own wall time (llvmpipe's timestamps mix deferred stages)
    pipe.run(cam, {lamp}, {0.2, 0.2, 0.2}, &profiler);
    for (const auto& [name, t] : profiler.resolve()) sum[name] += t.cpuMs;
    ++runs;
    if (after) after(pipe);
  }
  for (auto& [name, t] : sum) t /= std::max(runs, 1);
  return sum;
}

/// args: resolution, rays, bounces, points per triangle.
void BM_ImperfectVolumes(benchmark::State& state) {
  auto context = benchContext();
  PipelineConfig cfg = benchConfig("imperfect-volumes");
  cfg.set("iv", "resolution", static_cast<double>(state.range(0)));
  cfg.set("iv", "rays", static_cast<double>(state.range(1)));
  cfg.set("iv", "bounces", static_cast<double>(state.range(2)));
  cfg.set("iv", "points", static_cast<double>(state.range(3)));
  nlohmann::json stats;
  const auto ms = runScene(state, cfg, [&](const LightingPipeline& pipe) {
    stats = pipe.stats().value("imperfect-volumes", nlohmann::json::object());
  });
  for (const char* stage : {"iv.points", "iv.inject", "iv.gather", "iv.cone", "iv.readout"})
    state.counters[std::string(stage).substr(3) + "_ms"] = ms.count(stage) ? ms.at(stage) : 0.0;
  const double gathered = stats.value("voxels_gathered", 0.0);
  if (!(gathered > 0) || !(stats.value("points", 0.0) > 0)) state.SkipWithError("imperfect volumes gathered nothing");
  state.counters["points"] = stats.value("points", 0.0);
  state.counters["voxels_gathered"] = gathered;
  state.counters["work"] =
      gathered * static_cast<double>(state.range(1)) * static_cast<double>(std::max<int64_t>(1, state.range(2))) * 2.0;
}

/// args: pixel lights (splat.vpls), i_low, far levels.
void BM_Splatting(benchmark::State& state) {
  auto context = benchContext();
  PipelineConfig cfg = benchConfig("splatting");
  cfg.set("splat", "vpls", static_cast<double>(state.range(0)));
  cfg.set("splat", "i_low", static_cast<double>(state.range(1)));
  cfg.set("splat", "far_levels", static_cast<double>(state.range(2)));
  double meanOverdraw = 0, maxOverdraw = 0, lights = 0;
  int runs = 0;
  const auto ms = runScene(state, cfg, [&](const LightingPipeline& pipe) {
    nlohmann::json info;
    pipe.technique("splatting")->debugImage("splat_overdraw", {}, info);
    meanOverdraw += info.value("mean_splats_per_pixel", 0.0);
    maxOverdraw = std::max(maxOverdraw, info.value("max_splats_per_pixel", 0.0));
    const nlohmann::json stats = pipe.stats().value("splatting", nlohmann::json::object());
    lights = stats.value("delta_lights", 0.0) + stats.value("object_lights", 0.0);
    ++runs;
  });
  for (const char* stage : {"splat.importance", "splat.sample", "splat.splat"})
    state.counters[std::string(stage).substr(6) + "_ms"] = ms.count(stage) ? ms.at(stage) : 0.0;
  state.counters["lights"] = lights;
  state.counters["overdraw_mean"] = meanOverdraw / std::max(runs, 1);
  state.counters["overdraw_max"] = maxOverdraw;
}

/// args: surfels, grid, links, bands, chroma bands (0: as bands), rgb9e5.
void BM_Pic(benchmark::State& state) {
  auto context = benchContext();
  PipelineConfig cfg = benchConfig("pic");
  cfg.set("pic", "surfels", static_cast<double>(state.range(0)));
  cfg.set("pic", "grid", static_cast<double>(state.range(1)));
  cfg.set("pic", "links", static_cast<double>(state.range(2)));
  cfg.set("pic", "bands", static_cast<double>(state.range(3)));
  cfg.set("pic", "chroma_bands", static_cast<double>(state.range(4)));
  cfg.set("pic", "rgb9e5", static_cast<double>(state.range(5)));
  nlohmann::json stats;
  double bytes = 0;
  const auto ms = runScene(state, cfg, [&](const LightingPipeline& pipe) {
    stats = pipe.stats().value("pic", nlohmann::json::object());
    bytes = static_cast<double>(pipe.technique("pic")->gpuBytes());
  });
  for (const char* part : {"surfels", "hierarchy", "receivers", "caches"})
    state.counters[std::string("pre_") + part + "_ms"] = stats.value(std::string("precompute_ms_") + part, 0.0);
  for (const char* stage : {"pic.light", "pic.gather", "pic.readout"})
    state.counters[std::string(stage).substr(4) + "_ms"] = ms.count(stage) ? ms.at(stage) : 0.0;
  const double g = static_cast<double>(state.range(1));
  state.counters["cache_links"] = g * g * g * static_cast<double>(state.range(2));
  state.counters["gpu_mb"] = bytes / 1048576.0;
  state.counters["precomputes"] = stats.value("precomputes", 0.0);
}

/// The shading pass's footprint (lighting::objectsFootprint) over a frame's depth mesh: a floor grid of
/// range(0) x 3/4 range(0) vertices (two triangles a cell; 640: a 640 x 480 frame's own mesh, 612 k triangles)
/// seen from 1.6 m, a sphere of 6 cm on it, range(1) lights: a sphere lamp, a sun with extent, then point
/// lights on a ring. Counters: triangles and the box's share of the image.
void BM_ObjectsFootprint(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = w * 3 / 4;
  std::vector<MeshVertex> vertices;
  std::vector<uint32_t> indices;
  vertices.reserve(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      vertices.push_back(
          {cv::Vec3f(2.0f * x / (w - 1) - 1.0f, 1.5f * y / (h - 1) - 0.75f, 0.0f), {0, 0, 1}, {0.5f, 0.5f, 0.5f}});
  for (int y = 0; y + 1 < h; ++y)
    for (int x = 0; x + 1 < w; ++x) {
      const uint32_t a = static_cast<uint32_t>(y * w + x), b = a + 1, c = a + static_cast<uint32_t>(w), d = c + 1;
      indices.insert(indices.end(), {a, b, c, b, d, c});
    }
  CameraView camera;
  camera.intrinsics = {640, 480, 576, 576, 319.5, 239.5};
  camera.T_world_camera = capture::lookAtPose({0.0, -0.25, 1.6}, {0, 0, 0});
  std::vector<SceneLight> lights;
  for (int64_t i = 0; i < state.range(1); ++i) {
    SceneLight l;
    if (i == 1) {
      l.type = LightType::Directional;
      l.direction = cv::normalize(cv::Vec3d(0.3, 0.2, -1.0));
      l.extent = 0.05;
    } else {
      const double a = 0.7 * static_cast<double>(i);
      l.type = LightType::Point;
      l.position = {1.2 * std::cos(a), 1.2 * std::sin(a), 1.8};
      l.extent = i == 0 ? 0.1 : 0.0;
    }
    lights.push_back(l);
  }
  cv::Rect box;
  for (auto _ : state) {
    box = objectsFootprint(camera, {0.0, 0.0, 0.06}, 0.06, lights, 0.01, vertices, indices);
    benchmark::DoNotOptimize(box);
  }
  state.counters["triangles"] = static_cast<double>(indices.size() / 3);
  state.counters["image_share"] = box.area() / (640.0 * 480.0);
}

}  // namespace

/// Rows around the knob table's defaults (the registry's): first the defaults, then resolution (voxels
/// gathered), rays, bounces and points per triangle one at a time.
void imperfectVolumesRows(benchmark::internal::Benchmark* b) {
  const KnobGroup& group = findTechnique("imperfect-volumes")->knobs;
  const auto def = [&](const std::string& name) -> int64_t {
    for (const KnobInfo& k : group.knobs)
      if (k.name == name) return static_cast<int64_t>(k.def);
    throw std::logic_error("lighting_bench: imperfect volumes have no knob " + name);
  };
  const int64_t r = def("resolution"), n = def("rays"), bounces = def("bounces"), points = def("points");
  b->Args({r, n, bounces, points});
  for (int64_t v : {16, 48, 64}) b->Args({v, n, bounces, points});
  for (int64_t v : {16, 128, 256}) b->Args({r, v, bounces, points});
  for (int64_t v : {1, 3}) b->Args({r, n, v, points});
  for (int64_t v : {3, 19}) b->Args({r, n, bounces, v});
}
// A frame's view mesh of the fused room (~75 k vertices: 320) and its own depth mesh (640), 1, 2 and 16 lights.
BENCHMARK(BM_ObjectsFootprint)
    ->Args({320, 1})
    ->Args({640, 1})
    ->Args({640, 2})
    ->Args({640, 16})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ImperfectVolumes)->Apply(imperfectVolumesRows)->Unit(benchmark::kMillisecond)->Iterations(3);
// Light count 64 .. 16384 at the defaults (I_low 16, 2 far levels); at 1024 lights the splat size (I_low 4
// and 64) and far levels 0, 1 and 3.
BENCHMARK(BM_Splatting)
    ->Args({64, 16, 2})
    ->Args({256, 16, 2})
    ->Args({1024, 16, 2})
    ->Args({4096, 16, 2})
    ->Args({16384, 16, 2})
    ->Args({1024, 4, 2})
    ->Args({1024, 64, 2})
    ->Args({1024, 16, 0})
    ->Args({1024, 16, 1})
    ->Args({1024, 16, 3})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);
// Surfels and caches (precompute), caches x links (gather), bands with full and compressed chroma, RGBA32F flux.
BENCHMARK(BM_Pic)
    ->Args({1024, 6, 128, 4, 0, 1})
    ->Args({4096, 6, 128, 4, 0, 1})
    ->Args({16384, 6, 128, 4, 0, 1})
    ->Args({4096, 4, 128, 4, 0, 1})
    ->Args({4096, 10, 128, 4, 0, 1})
    ->Args({4096, 6, 32, 4, 0, 1})
    ->Args({4096, 6, 512, 4, 0, 1})
    ->Args({4096, 6, 128, 1, 0, 1})
    ->Args({4096, 6, 128, 2, 0, 1})
    ->Args({4096, 6, 128, 6, 0, 1})
    ->Args({4096, 6, 128, 8, 0, 1})
    ->Args({4096, 6, 128, 4, 2, 1})
    ->Args({4096, 6, 128, 6, 2, 1})
    ->Args({4096, 6, 128, 8, 2, 1})
    ->Args({4096, 6, 128, 4, 0, 0})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);
BENCHMARK_MAIN();
