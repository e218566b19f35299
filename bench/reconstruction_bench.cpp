// Depth pipeline at 640x480 on a real frame: guided filter, normals, mesh; and OpenCV's own guided
// filter on the same input, so the ratio is measured in one run on one machine.
#include <benchmark/benchmark.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc/edge_filter.hpp>
#include <optional>

#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/memory.h"
#include "capture/npz.h"
#include "capture/registration.h"
#include "capture/session.h"
#include "capture/v4l2_source.h"
#include "reconstruction/albedo.h"
#include "reconstruction/depth.h"
#include "reconstruction/depth_filter.h"
#include "reconstruction/light_estimation.h"
#include "reconstruction/marker.h"
#include "reconstruction/odometry.h"
#include "reconstruction/room_model.h"

using namespace mrgi;

namespace {

struct Input {
  cv::Mat depth, guide, colour;
  capture::Intrinsics k{640, 480, 525.0, 525.0, 319.5, 239.5};
  Input() {
    const std::string dir = std::string(MRGI_SHARED_DATA) + "/rgbd-open3d-iclnuim/";
    cv::imread(dir + "depth/00000.png", cv::IMREAD_UNCHANGED).convertTo(depth, CV_32F, 1.0 / 1000.0);
    cv::cvtColor(cv::imread(dir + "color/00000.jpg"), colour, cv::COLOR_BGR2RGB);
    guide = reconstruction::guideFromColour(cv::imread(dir + "color/00000.jpg"));
    if (depth.empty() || guide.empty()) throw std::runtime_error("benchmark input missing under " + dir);
  }
};
const Input& input() {
  static const Input in;
  return in;
}

double secondsOf(auto&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void BM_OpenCvGuidedFilter(benchmark::State& state) {
  const int r = static_cast<int>(state.range(0));
  const cv::Mat g255 = input().guide * 255.0;
  cv::Mat out;
  for (auto _ : state) cv::ximgproc::guidedFilter(g255, input().depth, out, r, 1e-3 * 255 * 255);
}

void BM_GuidedFilterDepth(benchmark::State& state) {
  const int r = static_cast<int>(state.range(0));
  reconstruction::DepthFilterOptions o;
  const cv::Mat g255 = input().guide * 255.0;
  double ours = 0, theirs = 0;
  cv::Mat out, ref;
  for (auto _ : state) {
    ours += secondsOf([&] { out = reconstruction::guidedFilterDepth(input().depth, input().guide, r, o); });
    state.PauseTiming();
    theirs += secondsOf([&] { cv::ximgproc::guidedFilter(g255, input().depth, ref, r, 1e-3 * 255 * 255); });
    state.ResumeTiming();
  }
  state.counters["ratio_vs_opencv"] = ours / theirs;
}

void BM_Normals(benchmark::State& state) {
  const cv::Mat p = reconstruction::backProject(input().depth, input().k);
  for (auto _ : state) benchmark::DoNotOptimize(reconstruction::computeNormals(p));
}

void BM_Mesh(benchmark::State& state) {
  const cv::Mat p = reconstruction::backProject(input().depth, input().k);
  const cv::Mat n = reconstruction::computeNormals(p);
  const int stride = static_cast<int>(state.range(0));
  size_t triangles = 0;
  for (auto _ : state) triangles = reconstruction::buildDepthMesh(p, n, stride).triangleCount();
  state.counters["triangles"] = static_cast<double>(triangles);
}

// The per-frame albedo at 640x480 on a real frame (a lamp over the camera, an ambient): its pixels and the
// fill of what it rejects (arg 1: 0 none, else its scale: 1 inpainting at full resolution, the default; 2
// from 2 x 2 blocks, as the frame pipeline fills; 4 from 4 x 4 blocks), on state.range(0) threads (1 and the machine's:
// the ratios in one run).
void BM_Albedo(benchmark::State& state) {
  reconstruction::DepthFilterOptions o;
  const cv::Mat p = reconstruction::backProject(
      reconstruction::guidedFilterDepth(input().depth, input().guide, o.radiusPx, o), input().k);
  const cv::Mat n = reconstruction::computeNormals(p);
  reconstruction::AlbedoLights lights;
  lights.points.push_back({{0.3, -1.0, 0.5}, {4.0, 4.0, 4.0}});
  lights.ambientIrradiance = cv::Vec3d::all(0.3);
  const int threads = cv::getNumThreads();
  cv::setNumThreads(static_cast<int>(state.range(0)));
  reconstruction::AlbedoOptions ao;
  ao.fill = state.range(1) != 0;
  ao.fillScale = static_cast<int>(std::max<int64_t>(1, state.range(1)));
  int rejected = 0;
  for (auto _ : state) {
    const auto r = reconstruction::estimateAlbedo(input().colour, p, n, input().k, lights, ao);
    rejected = cv::countNonZero(r.status != uchar(reconstruction::AlbedoStatus::Measured));
  }
  cv::setNumThreads(threads);
  state.counters["rejected"] = rejected;
}

void BM_DepthPipeline(benchmark::State& state) {
  reconstruction::DepthFilterOptions o;
  for (auto _ : state) {
    const cv::Mat f = reconstruction::guidedFilterDepth(input().depth, input().guide, o.radiusPx, o);
    const cv::Mat p = reconstruction::backProject(f, input().k);
    benchmark::DoNotOptimize(reconstruction::buildDepthMesh(p, reconstruction::computeNormals(p), 1));
  }
}

// The room model's per-frame real-surface cost at 640x480 (issue target: 40 ms median on the 2-core
// machine): a frame's guided depth filter and normals as the frame pipeline runs them, then its fusion
// (TSDF, carving, appearance) into a room that already holds the session's first half. Frames of the
// bundled tabletop-synth session at their ground-truth poses, the second half in turn. Arg 1: the fusion alone.
void BM_RoomSurfaceFrame640(benchmark::State& state) {
  const std::string dir = std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-synth";
  auto source = capture::open(dir);
  const auto manifest = nlohmann::json::parse(std::ifstream(dir + "/manifest.json"));
  const capture::Pose T_marker_world = capture::inversePose(
      capture::poseFromJson(manifest["ground_truth"]["T_world_marker"], "manifest.json", "T_world_marker"));
  std::vector<capture::Frame> frames;
  while (auto f = source->next()) {
    capture::ensureRegistered(*f->rgbd);
    frames.push_back(std::move(*f));
  }
  reconstruction::DepthFilterOptions fo;
  auto surface = [&](const capture::Frame& f) {
    const capture::RgbdFrame& rgbd = *f.rgbd;
    const cv::Mat depth = reconstruction::guidedFilterDepth(
        rgbd.depth, reconstruction::guideFromColour(rgbd.colour),
        reconstruction::filterRadiusPixels(rgbd.depth, rgbd.colourIntrinsics, fo), fo);
    const cv::Mat positions = reconstruction::backProject(depth, rgbd.colourIntrinsics);
    benchmark::DoNotOptimize(reconstruction::computeNormals(positions));
    return depth;
  };
  reconstruction::RoomModel room;
  const size_t half = frames.size() / 2;
  for (size_t i = 0; i < half; ++i)
    room.integrate(surface(frames[i]), frames[i].rgbd->colour, frames[i].rgbd->colourIntrinsics,
                   T_marker_world * *frames[i].groundTruthT_world_camera, frames[i].rgbd->exposure);
  // Arg 1: the fusion alone, each frame's filtered depth made before.
  const bool fusionAlone = state.range(0) != 0;
  std::vector<cv::Mat> filtered(frames.size());
  if (fusionAlone)
    for (size_t i = half; i < frames.size(); ++i) filtered[i] = surface(frames[i]);
  size_t i = half;
  for (auto _ : state) {
    const capture::Frame& f = frames[i];
    room.integrate(fusionAlone ? filtered[i] : surface(f), f.rgbd->colour, f.rgbd->colourIntrinsics,
                   T_marker_world * *f.groundTruthT_world_camera, f.rgbd->exposure);
    i = i + 1 < frames.size() ? i + 1 : half;
  }
  state.counters["width"] = frames.empty() ? 0 : frames[0].rgbd->colour.cols;
  state.counters["blocks"] = static_cast<double>(room.blocks());
}

// PNG encoding of real 640x480 camera frames (rgbd-slambook): arg 0 = OpenCV's encoder, zlib's default strategy at
// level 3 (the first wave's), 2 = OpenCV's encoder with run-length deflate at level 1 (every row filter tried: the
// second wave's), 1 = capture::encodePng as shipped (libpng, the up filter, run-length deflate at level 1). Counter:
// bytes per frame.
void BM_EncodePng(benchmark::State& state) {
  std::vector<cv::Mat> frames;
  for (int i = 1; i <= 5; ++i) {
    cv::Mat bgr =
        cv::imread(std::string(MRGI_SHARED_DATA) + "/rgbd-slambook/joinMap/color/" + std::to_string(i) + ".png");
    cv::cvtColor(bgr, bgr, cv::COLOR_BGR2RGB);
    frames.push_back(bgr);
  }
  size_t bytes = 0, n = 0;
  for (auto _ : state) {
    const cv::Mat& f = frames[n++ % frames.size()];
    std::vector<unsigned char> out;
    if (state.range(0) != 1) {
      cv::Mat bgr;
      cv::cvtColor(f, bgr, cv::COLOR_RGB2BGR);
      cv::imencode(".png", bgr, out,
                   state.range(0) == 0 ? std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 3}
                                       : std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 1, cv::IMWRITE_PNG_STRATEGY,
                                                          cv::IMWRITE_PNG_STRATEGY_RLE});
    } else {
      out = capture::encodePng(f, "bench");
    }
    bytes += out.size();
  }
  state.counters["bytes"] = n ? static_cast<double>(bytes) / static_cast<double>(n) : 0.0;
}

// Marker accuracy and cost on the real ViSP RGB-D sequence (20 frames, 7 tags) against its poses:
// counters report mean/worst translation (mm) and rotation (deg) errors, raw and depth-refined.
void BM_MarkerPoseRealSequence(benchmark::State& state) {
  const std::string dir = std::string(MRGI_SHARED_DATA) + "/rgbd-visp-apriltag/";
  const auto cam = nlohmann::json::parse(std::ifstream(dir + "cam.json"));
  const capture::Intrinsics k{cam["w"], cam["h"], cam["px"], cam["py"], cam["u0"], cam["v0"]};
  const auto data = nlohmann::json::parse(std::ifstream(dir + "apriltag_data.json"));
  const double size = data["tag_size"];
  std::vector<cv::Mat> grey, depth;
  for (int f = 0; f < 20; ++f) {
    char n[16];
    std::snprintf(n, sizeof n, "%04d", f);
    grey.push_back(cv::imread(dir + "color_image_" + n + ".png", cv::IMREAD_GRAYSCALE));
    cv::Mat d;
    capture::readNpzArray(dir + "depth_image_" + n + ".npz", "data.npy").convertTo(d, CV_32F, 0.001);
    depth.push_back(d);
  }
  reconstruction::DetectorOptions o;
  o.decimate = static_cast<float>(state.range(0));
  const reconstruction::TagDetector detector(o);
  double st = 0, sr = 0, wt = 0, wr = 0, sdt = 0, sdr = 0;
  int n = 0, nd = 0;
  for (auto _ : state) {
    st = sr = wt = wr = sdt = sdr = 0, n = nd = 0;
    for (int f = 0; f < 20; ++f)
      for (const auto& d : detector.detect(grey[f])) {
        const auto& g = data["detections"][f];
        if (!g.contains(std::to_string(d.id))) continue;
        capture::Pose gt;
        for (int r = 0; r < 4; ++r)
          for (int c = 0; c < 4; ++c) gt(r, c) = g[std::to_string(d.id)]["cMo"][r][c];
        const auto p = reconstruction::estimateTagPose(d, size, k);
        if (!p) continue;
        const double et = reconstruction::translationError(p->T_camera_tag, gt),
                     er = reconstruction::rotationErrorDeg(p->T_camera_tag, gt);
        st += et, sr += er, wt = std::max(wt, et), wr = std::max(wr, er), ++n;
        if (const auto plane = reconstruction::fitTagPlane(d, depth[f], k)) {
          const auto q = reconstruction::refinePoseWithDepth(*p, *plane);
          if (q.depthRefined)
            sdt += reconstruction::translationError(q.T_camera_tag, gt),
                sdr += reconstruction::rotationErrorDeg(q.T_camera_tag, gt), ++nd;
        }
      }
  }
  state.counters["poses"] = n;
  state.counters["mean_t_mm"] = 1e3 * st / std::max(1, n);
  state.counters["mean_R_deg"] = sr / std::max(1, n);
  state.counters["worst_t_mm"] = 1e3 * wt;
  state.counters["worst_R_deg"] = wr;
  state.counters["depth_mean_t_mm"] = 1e3 * sdt / std::max(1, nd);
  state.counters["depth_mean_R_deg"] = sdr / std::max(1, nd);
  state.counters["ms_per_frame"] =
      benchmark::Counter(20, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

// The odometry stage of tracked poses on the real ViSP frames (640x480, RealSense): preparing each frame's
// pyramid and solving it against the frame before, per method (0 point-to-plane, 1 intensity, 2 hybrid) and
// finest width (320: the default, a 640x480 frame halved first; 640: full resolution) and step (1: sampled between
// pixels, the default; 0: Open3D's nearest-pixel steps) and turn (1: the coarsest level also solved from the start
// turned in place, the default; 0: from the start alone). Beside the marker stage above
// (BM_MarkerPoseRealSequence's ms_per_frame).
void BM_OdometryRealFrame(benchmark::State& state) {
  const std::string dir = std::string(MRGI_SHARED_DATA) + "/rgbd-visp-apriltag/";
  const auto cam = nlohmann::json::parse(std::ifstream(dir + "cam.json"));
  const capture::Intrinsics k{cam["w"], cam["h"], cam["px"], cam["py"], cam["u0"], cam["v0"]};
  std::vector<cv::Mat> colour, depth;
  for (int f = 0; f < 20; ++f) {
    char n[16];
    std::snprintf(n, sizeof n, "%04d", f);
    cv::Mat bgr = cv::imread(dir + "color_image_" + n + ".png", cv::IMREAD_COLOR), rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    colour.push_back(rgb);
    cv::Mat d;
    capture::readNpzArray(dir + "depth_image_" + n + ".npz", "data.npy").convertTo(d, CV_32F, 0.001);
    depth.push_back(d);
  }
  reconstruction::OdometryOptions o;
  o.method = static_cast<reconstruction::OdometryMethod>(state.range(0));
  o.maxWidth = static_cast<int>(state.range(1));
  o.subpixel = state.range(2) != 0;
  o.turnInPlace = state.range(3) != 0;
  double fitness = 0;
  int frames = 0;
  for (auto _ : state) {
    std::optional<reconstruction::OdometryFrame> previous;
    for (int f = 0; f < 20; ++f) {
      reconstruction::OdometryFrame current(depth[f], colour[f], k, o);
      if (previous) {
        const auto r = reconstruction::estimateOdometry(current, *previous, capture::identityPose(), o);
        fitness += r.fitness, ++frames;
      }
      previous = std::move(current);
    }
  }
  state.counters["fitness"] = frames ? fitness / frames : 0.0;
  state.counters["ms_per_frame"] =
      benchmark::Counter(20, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

// Median cut on real HDR maps rendered through the calibrated fisheye: time and the worst relative
// irradiance error (5 normals, 5 maps) against direct integration of the image, per light count.
void BM_MedianCutIrradianceError(benchmark::State& state) {
  static const auto calib =
      capture::readFisheyeCalibration(std::string(MRGI_SHARED_DATA) + "/fisheye-ros-calib/ost.yaml");
  static const auto rays = reconstruction::fisheyeRays(calib);
  static const std::vector<cv::Mat> maps = [] {
    std::vector<cv::Mat> out;
    const cv::Matx33d up(1, 0, 0, 0, 0, -1, 0, 1, 0);
    for (const char* name : {"city", "courtyard", "forest", "interior", "studio"}) {
      cv::Mat m =
          cv::imread(std::string(MRGI_SHARED_DATA) + "/hdr-blender-world/" + name + ".exr", cv::IMREAD_UNCHANGED);
      cv::cvtColor(m, m, cv::COLOR_BGR2RGB);
      out.push_back(reconstruction::renderFisheyeFromLatLong(cv::max(m, 0.0), rays, up));
    }
    return out;
  }();
  reconstruction::MedianCutOptions o;
  o.count = static_cast<int>(state.range(0));
  o.varianceSplit = state.range(1) != 0;
  const std::vector<cv::Vec3d> normals{{0, 0, 1},
                                       cv::normalize(cv::Vec3d(1, 0, 1)),
                                       cv::normalize(cv::Vec3d(0, -1, 1)),
                                       cv::normalize(cv::Vec3d(-1, 1, 0.3)),
                                       {1, 0, 0}};
  std::vector<std::vector<reconstruction::EstimatedLight>> lights(maps.size());
  for (auto _ : state)
    for (size_t i = 0; i < maps.size(); ++i) lights[i] = reconstruction::medianCut(maps[i], rays, o);
  double worst = 0;
  for (size_t i = 0; i < maps.size(); ++i)
    for (const auto& n : normals) {
      const cv::Vec3d ref = reconstruction::irradianceFromImage(maps[i], rays, n);
      worst = std::max(worst, cv::norm(reconstruction::irradianceFromLights(lights[i], n) - ref) / cv::norm(ref));
    }
  state.counters["worst_rel_irradiance_error"] = worst;
}

}  // namespace

BENCHMARK(BM_EncodePng)->Arg(0)->Arg(2)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MarkerPoseRealSequence)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_OdometryRealFrame)
    ->ArgNames({"method", "width", "subpixel", "turn"})
    ->Args({2, 320, 1, 1})
    ->Args({2, 320, 1, 0})  // the start alone, side by side
    ->Args({0, 320, 1, 1})
    ->Args({1, 320, 1, 1})
    ->Args({2, 640, 1, 1})
    ->Args({2, 320, 0, 0})  // Open3D's nearest-pixel steps, side by side
    ->Args({1, 320, 0, 0})
    ->Args({2, 640, 0, 0})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MedianCutIrradianceError)
    ->ArgsProduct({{1, 4, 16, 64, 256}, {0, 1}})
    ->ArgNames({"lights", "variance"})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_OpenCvGuidedFilter)->Arg(4)->Arg(8)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GuidedFilterDepth)->Arg(4)->Arg(8)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Normals)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Mesh)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DepthPipeline)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Albedo)->Args({1, 0})->Args({2, 0})->Args({1, 1})->Args({2, 1})->Args({2, 2})->Args({2, 4})->Unit(
    benchmark::kMillisecond);
BENCHMARK(BM_RoomSurfaceFrame640)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->MinTime(3.0);
int main(int argc, char** argv) {
  mrgi::capture::keepFrameMemory();  // as mrgi runs its frame loop
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
