#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/commands.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/registration.h"
#include "compositor/compositor.h"
#include "gl/context.h"
#include "reconstruction/depth.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::app {
namespace {

struct ReplayOptions {
  std::string source;
  std::string out;
  int frames = 0;
  std::string gl = "osmesa";
};

/// Refuses to write into a folder holding anything but an earlier replay's output.
void prepareOutputDirectory(const std::string& out) {
  std::error_code ec;
  if (fs::exists(out, ec)) {
    if (!fs::is_directory(out, ec)) throw capture::CaptureError(out, "exists and is not a directory");
    if (!fs::is_empty(out, ec) && !fs::exists(fs::path(out) / "summary.json", ec))
      throw capture::CaptureError(out, "is not empty and holds no earlier mrgi output; refusing to overwrite");
  }
  fs::create_directories(out, ec);
  if (ec) throw capture::CaptureError(out, "cannot create output directory: " + ec.message());
}

void writePng(const std::string& path, const cv::Mat& rgb) {
  capture::writeFileAtomically(path, capture::encodePng(rgb, path));
}

int runReplay(const ReplayOptions& o) {
  const gl::Backend backend = gl::parseBackend(o.gl);
  auto source = capture::open(o.source);
  const capture::SourceInfo& info = source->info();
  if (!info.hasRgbd) throw capture::CaptureError(o.source, "has no RGB-D frames to replay");
  const int width = info.colourIntrinsics.width, height = info.colourIntrinsics.height;
  prepareOutputDirectory(o.out);

  gl::ContextConfig cfg;
  cfg.backend = backend;
  cfg.width = width;
  cfg.height = height;
  cfg.title = "mrgi replay: " + o.source;
  auto context = gl::createContext(cfg);
  compositor::Compositor compositor(width, height);
  gl::Profiler profiler;

  const bool tty = isatty(fileno(stdout));
  const int64_t total = info.frameCount ? *info.frameCount : -1;
  const int64_t limit = o.frames > 0 ? (total >= 0 ? std::min<int64_t>(o.frames, total) : o.frames) : total;
  json perFrame = json::array();
  std::map<std::string, std::pair<double, double>> sums;  // stage -> (cpu, gpu) ms
  int64_t done = 0;
  const auto start = std::chrono::steady_clock::now();
  while (limit < 0 || done < limit) {
    std::optional<capture::Frame> frame;
    {
      auto s = profiler.cpu("read");
      frame = source->next();
    }
    if (!frame) break;
    capture::RgbdFrame& rgbd = *frame->rgbd;
    if (!rgbd.depthRegistered) {
      auto s = profiler.cpu("register");
      capture::ensureRegistered(rgbd);
    }
    cv::Mat normals;
    {
      auto s = profiler.cpu("normals");
      normals = reconstruction::computeNormals(reconstruction::backProject(rgbd.depth, rgbd.depthIntrinsics));
    }
    // Until lighting lands the delta is zero: the composite is the background, decoded and re-encoded.
    const cv::Mat composite = compositor.composite(rgbd.colour, cv::Mat(), cv::Mat(), &profiler);
    if (context->backend() == gl::Backend::Window) {
      compositor.present(context->width(), context->height());
      context->swapBuffers();
      if (!context->pollEvents()) break;
    }
    {
      auto s = profiler.cpu("write");
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04lld.png", static_cast<long long>(done));
      writePng((fs::path(o.out) / name).string(), composite);
    }
    json stages;
    for (const auto& [name, t] : profiler.resolve()) {
      stages[name] = {{"cpu_ms", t.cpuMs}, {"gpu_ms", t.gpuMs}};
      sums[name].first += t.cpuMs;
      sums[name].second += t.gpuMs;
    }
    perFrame.push_back({{"frame", done}, {"index", frame->index}, {"t", frame->timestamp}, {"stages", stages}});
    ++done;
    if (tty) {
      std::printf("\rreplay %lld/%lld frames", static_cast<long long>(done), static_cast<long long>(limit));
      std::fflush(stdout);
    }
  }
  if (tty) std::printf("\n");
  if (done == 0) throw capture::CaptureError(o.source, "no frame could be replayed");
  const double wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  json summary;
  summary["source"] = o.source;
  summary["frames"] = done;
  summary["resolution"] = {width, height};
  summary["gl"] = {{"backend", std::string(gl::backendName(backend))},
                   {"renderer", context->renderer()},
                   {"version", context->version()},
                   {"detail", context->detail()}};
  json mean;
  for (const auto& [name, s] : sums) mean[name] = {{"cpu_ms", s.first / done}, {"gpu_ms", s.second / done}};
  summary["stages_ms"] = mean;
  summary["wall_ms_per_frame"] = wallMs / done;
  summary["per_frame"] = perFrame;
  const std::string summaryPath = (fs::path(o.out) / "summary.json").string();
  std::ofstream(summaryPath + ".tmp") << summary.dump(2) << "\n";
  fs::rename(summaryPath + ".tmp", summaryPath);
  std::printf("replayed %lld frames into %s (%.1f ms/frame)\n", static_cast<long long>(done), o.out.c_str(),
              wallMs / done);
  return 0;
}

}  // namespace

Action addReplay(CLI::App& app) {
  auto o = std::make_shared<ReplayOptions>();
  app.add_option("SESSION", o->source, "session directory, TUM directory or .oni file")->required();
  app.add_option("--out", o->out, "output folder for frame_NNNN.png and summary.json")->required();
  app.add_option("--frames", o->frames, "replay at most N frames (0 = all)")->check(CLI::NonNegativeNumber);
  app.add_option("--gl", o->gl, "GL backend: osmesa (headless, default), egl (headless GPU), window")
      ->check(CLI::IsMember({"osmesa", "egl", "window"}));
  return [o] { return runReplay(*o); };
}

}  // namespace mrgi::app
