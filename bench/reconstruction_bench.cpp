// Depth pipeline at 640x480 on a real frame: guided filter, normals, mesh; and OpenCV's own guided
// filter on the same input, so the ratio is measured in one run on one machine.
#include <benchmark/benchmark.h>

#include <chrono>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/ximgproc/edge_filter.hpp>

#include "reconstruction/depth.h"
#include "reconstruction/depth_filter.h"

using namespace mrgi;

namespace {

struct Input {
  cv::Mat depth, guide;
  capture::Intrinsics k{640, 480, 525.0, 525.0, 319.5, 239.5};
  Input() {
    const std::string dir = std::string(MRGI_SHARED_DATA) + "/rgbd-open3d-iclnuim/";
    cv::imread(dir + "depth/00000.png", cv::IMREAD_UNCHANGED).convertTo(depth, CV_32F, 1.0 / 1000.0);
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

void BM_DepthPipeline(benchmark::State& state) {
  reconstruction::DepthFilterOptions o;
  for (auto _ : state) {
    const cv::Mat f = reconstruction::guidedFilterDepth(input().depth, input().guide, o.radiusPx, o);
    const cv::Mat p = reconstruction::backProject(f, input().k);
    benchmark::DoNotOptimize(reconstruction::buildDepthMesh(p, reconstruction::computeNormals(p), 1));
  }
}

}  // namespace

BENCHMARK(BM_OpenCvGuidedFilter)->Arg(4)->Arg(8)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GuidedFilterDepth)->Arg(4)->Arg(8)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Normals)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Mesh)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DepthPipeline)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
