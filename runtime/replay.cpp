#include "runtime/replay.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <deque>
#include <exception>
#include <filesystem>
#include <functional>
#include <future>
#include <iostream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/session.h"
#include "compositor/compositor.h"
#include "gl/context.h"
#include "lighting/pipeline.h"
#include "lighting/scene_file.h"
#include "lighting/techniques/registry.h"
#include "runtime/background_writer.h"
#include "runtime/debug_view.h"
#include "runtime/frame_pipeline.h"
#include "runtime/output.h"
#include "runtime/presets.h"
#include "runtime/room_fusion.h"
#include "runtime/source.h"
#include "runtime/threads.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::runtime {
namespace {

/// Per-frame latencies (ms), added from the writer thread.
class Latency {
 public:
  void add(double ms) {
    std::lock_guard lock(mutex_);
    ms_.push_back(ms);
  }
  json summary() const {
    std::lock_guard lock(mutex_);
    if (ms_.empty()) return {{"mean", 0.0}, {"max", 0.0}, {"frames", 0}};
    double sum = 0, peak = 0;
    for (double v : ms_) sum += v, peak = std::max(peak, v);
    std::vector<double> sorted = ms_;
    std::sort(sorted.begin(), sorted.end());
    return {{"mean", sum / static_cast<double>(ms_.size())},
            {"median", sorted[sorted.size() / 2]},
            {"max", peak},
            {"first", ms_.front()},
            {"last", ms_.back()},
            {"frames", ms_.size()}};
  }

 private:
  mutable std::mutex mutex_;
  std::vector<double> ms_;
};

}  // namespace

int replay(const ReplayOptions& o) {
  const gl::Backend backend = gl::parseBackend(o.gl);
  auto source = openSource(o.source, o.open);
  const capture::SourceInfo info = source->info();  // a copy: the source is opened again after a first pass
  if (!info.hasRgbd) throw capture::CaptureError(o.source, "has no RGB-D frames to replay");
  const int width = info.colourIntrinsics.width, height = info.colourIntrinsics.height;
  // A bad scene file stops here, before anything is written.
  std::optional<LightingSetup> setup;
  if (!o.scene.scene.empty())
    setup = prepareLighting(loadChosenScene(o.scene), o.scene.scene, *source, o.source, o.pose, o.rooms.any());
  std::shared_ptr<const reconstruction::RoomMesh> room = o.room;
  if (!o.mp4.empty()) checkInsideOutput(o.mp4, "--mp4");
  const OutputClaim claim = prepareOutputDirectory(o.out, "summary.json", "mrgi replay");
  // Lit from the room this recording shows (its lights left to the room, no saved room given, no --fuse-room
  // asked for): the whole recording is fused first, as insert's preview is lit, so that every frame, the first
  // included, is lit by the whole room. --fuse-room lights each frame by the room fused up to it instead.
  std::optional<RoomFusion> fusedFirst;
  if (setup && fusesRecordingFirst(*setup, o.rooms, room != nullptr)) {
    source.reset();  // the fusion reads the recording itself (a device's recording plays once at a time)
    ProgressBar fuseBar("room");
    fusedFirst.emplace();
    const int64_t total = info.frameCount.value_or(-1);
    room = fuseWholeRecording(o.source, o.pose, o.open, &*fusedFirst, [&](const json& line, const auto&) {
      if (total > 0) fuseBar(static_cast<double>(line["frame"].get<int64_t>() + 1) / static_cast<double>(total));
    });
    setup->lightsFromFusedRoom = false;
    source = openSource(o.source, o.open);
  }

  gl::ContextConfig cfg;
  cfg.backend = backend;
  cfg.width = width;
  cfg.height = height;
  cfg.title = "mrgi replay: " + o.source;
  auto context = gl::createContext(cfg);
  compositor::Compositor compositor(width, height);
  gl::Profiler profiler(o.finishStages);  // with finishStages each GL stage is waited for before the next

  FrameOptions fo;
  fo.pose = o.pose;
  fo.meshStride = o.meshStride;
  fo.reuse = !o.recomputeAll;
  fo.room = room;
  fo.cacheDir = o.rooms.room;  // techniques keep what they precompute beside the saved room
  fo.progress = precomputeProgress();
  const bool fuse = !fusedFirst && (o.rooms.fuse || (setup && setup->lightsFromFusedRoom));
  if (fuse) fo.fuse = std::make_shared<reconstruction::RoomModel>();
  fo.fuseRefresh = o.rooms.fuseRefresh;
  fo.fuseEvery = o.rooms.fuseEvery;
  fo.trackFusedRoom = o.rooms.track;
  FramePipeline frames(std::move(setup), width, height, fo);
  lighting::LightingPipeline* pipeline = frames.lighting();

  // The video plays at the recording's rate: its median frame interval (30 fps without timestamps).
  double fps = o.fps;
  if (fps <= 0) fps = info.fps > 0 ? info.fps : 30.0;
  std::optional<Mp4Writer> video;
  if (!o.mp4.empty()) video.emplace((fs::path(o.out) / o.mp4).string(), width, height, fps);
  // The composites are encoded (PNG, video) on a writer thread while the next frame is worked on; at most 4
  // wait. Declared after the video: on the way out it finishes its writes before the video closes.
  Latency latency;  // frame in (read and decoded) -> its composite on disk, ms (written by the writer thread)
  runtime::BackgroundWriter writer(4);
  InterruptGuard guard;
  bool interrupted = false;
  ProgressBar bar("replay");

  const int64_t total = info.frameCount ? *info.frameCount : -1;
  const int64_t limit = o.frames > 0 ? (total >= 0 ? std::min<int64_t>(o.frames, total) : o.frames) : total;
  json perFrame = json::array();
  cv::Mat lastFisheye;  // --debug: the environment the lights were last estimated from
  std::map<std::string, std::pair<double, double>> sums;  // stage -> (cpu, gpu) ms
  std::map<std::string, int64_t> skipped;                 // stage -> frames it was skipped on
  int64_t done = 0, posed = 0;
  std::map<std::string, int64_t> posedBy;  ///< frames by how they were posed (marker, odometry, ..., lost)
  const auto start = std::chrono::steady_clock::now();
  // Frame n + 1 is read, decoded and prepared (marker, depth filter, normals, albedo, real mesh and the techniques' own
  // inputs: the CPU half of the frame pipeline) on a worker thread while GL works on frame n; only a frame the loop
  // will take (a damaged frame past --frames is never touched). Its error surfaces when the loop takes it.
  // With the room fused as the frames come, the worker fuses frame n + 1 and hands a refreshed surface to its
  // render. --debug's views read the pipeline's state between frames: there, and with --sequential, the worker
  // only reads and the frame is worked on in the loop, one stage after another.
  const bool overlap = !o.sequential && !o.debug;
  using Clock = std::chrono::steady_clock;
  const auto readNext = [&source, &frames, overlap] {
    return runtime::readAhead([&source] { return source->next(); }, overlap ? &frames : nullptr);
  };
  std::future<runtime::FrameAhead> ahead = readNext();
  // The frame loop never waits for the GPU unless an output asks for it (--dump-delta, --debug): each
  // composite is read into a pixel buffer and handed to the writer when the read has finished (typically
  // while the next frame is worked on), and each frame's GPU stage times are taken when its timestamps have
  // arrived. --debug draws on the composite, so it reads it at once.
  compositor.setReadback(o.debug ? compositor::Compositor::Readback::Now : compositor::Compositor::Readback::Later);
  std::deque<std::pair<std::string, Clock::time_point>> awaiting;  // composites drawn, not yet read: file, frame in
  const auto write = [&](const cv::Mat& composite) {
    // The frame loop's share of the writing: the wait for a free slot in the writer's queue.
    auto s = profiler.cpu("write");
    const std::string path = awaiting.front().first;  // not a structured binding: clang 15 cannot capture one
    const Clock::time_point frameStart = awaiting.front().second;
    awaiting.pop_front();
    writer.push([path, image = composite, v = video ? &*video : nullptr, frameStart, &latency] {
      writePng(path, image, "mrgi replay");
      if (v) v->write(image);
      latency.add(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - frameStart).count());
    });
  };
  // Leaving through an error (a damaged frame, a full disk), the composites still being read are written
  // too (the writer, declared before, then finishes its queue): every frame before the error is on disk.
  struct WriteInFlight {
    std::function<void()> write;
    ~WriteInFlight() {
      if (std::uncaught_exceptions() > 0) try {
          write();
        } catch (...) {
        }
    }
  } inFlight{[&] {
    for (const cv::Mat& c : compositor.takeComposites(true)) write(c);
  }};
  const auto timesArrived = [&](std::vector<gl::Profiler::FrameTimes> frames) {
    for (const auto& [index, times, order] : frames) {
      json stages;
      std::string line;
      const bool frameOfItsOwn = index < perFrame.size();  // else the writes after the last frame
      for (const auto& [name, t] : times) {
        stages[name] = {{"cpu_ms", t.cpuMs}, {"gpu_ms", t.gpuMs}};
        sums[name].first += t.cpuMs;
        sums[name].second += t.gpuMs;
      }
      if (!frameOfItsOwn) continue;
      perFrame[index]["stages"] = stages;
      if (!o.verbose) continue;
      // Per-stage timings of every frame (ms; the larger of CPU wall and GPU time), when they are known.
      for (const std::string& name : inPipelineOrder(order)) {
        const gl::StageTime& t = times.at(name);
        char buf[64];
        std::snprintf(buf, sizeof buf, " %s %.1f", name.c_str(), std::max(t.cpuMs, t.gpuMs));
        line += buf;
      }
      std::printf("frame %lld/%lld:%s ms\n", static_cast<long long>(index + 1), static_cast<long long>(limit),
                  line.c_str());
    }
    std::fflush(stdout);
  };
  while (limit < 0 || done < limit) {
    if (InterruptGuard::interrupted()) {
      interrupted = true;
      break;
    }
    std::optional<capture::Frame> frame;
    Clock::time_point frameStart;
    std::optional<PreparedFrame> prepared;
    {
      // The loop's wait for the worker (0 when the frame was ready).
      auto s = profiler.cpu("read");
      runtime::FrameAhead a = ahead.get();
      frame = std::move(a.frame), frameStart = a.in, prepared = std::move(a.prepared);
      if (a.stages) profiler.adopt(*a.stages);  // the worker's stages count as this frame's
      if (frame && (limit < 0 || done + 1 < limit)) ahead = readNext();
    }
    if (!frame) break;
    FrameResult result;
    if (prepared) {
      frames.render(*frame, *prepared, compositor, profiler);
      result = std::move(prepared->result);
    } else {
      result = frames.process(*frame, compositor, profiler);
    }
    if (result.T_marker_camera) ++posed;
    if (frames.setup()) ++posedBy[result.T_marker_camera ? toString(result.pose.by) : "lost"];
    if (frame->fisheye) lastFisheye = frame->fisheye->image;  // the lights are estimated from it, lit frame or not
    json frameInfo = result.info;
    if (frameInfo.contains("skipped"))
      for (const auto& stage : frameInfo["skipped"]) ++skipped[stage.get<std::string>()];
    const cv::Mat& composite = result.composite;
    if (pipeline) {
      cv::Mat shade;
      if (o.dumpDelta && result.lit) {
        auto s = profiler.cpu("readback");
        shade = pipeline->downloadShade();
      }
      if (o.debug && result.lit) {
        auto s = profiler.cpu("debug");
        char prefix[32];
        std::snprintf(prefix, sizeof prefix, "debug_%04lld_", static_cast<long long>(done));
        const std::string base = (fs::path(o.out) / prefix).string();
        for (const DebugView& v : debugViews(frames)) {
          if (v == Views::kComposite) continue;  // frame_NNNN.png
          const cv::Mat img =
              renderDebugView(v, frames, result, frame->rgbd->colourIntrinsics, lastFisheye, &frameInfo);
          if (!img.empty()) writePng(base + debugViewName(v) + ".png", img, "mrgi replay");
        }
      }
      if (o.dumpDelta) {
        auto s = profiler.cpu("dump");
        if (shade.empty()) shade = cv::Mat(height, width, CV_32FC4, cv::Scalar::all(0));
        cv::Mat delta(height, width, CV_32FC3), mask(height, width, CV_8UC1);
        for (int y = 0; y < height; ++y)
          for (int x = 0; x < width; ++x) {
            const cv::Vec4f v = shade.at<cv::Vec4f>(y, x);
            const bool virt = v[3] > 0.5f;
            delta.at<cv::Vec3f>(y, x) = virt ? cv::Vec3f(0, 0, 0) : cv::Vec3f(v[0], v[1], v[2]);
            mask.at<uchar>(y, x) = virt ? 255 : 0;
          }
        char name[32];
        std::snprintf(name, sizeof name, "delta_%04lld.exr", static_cast<long long>(done));
        writeExr((fs::path(o.out) / name).string(), delta);
        std::snprintf(name, sizeof name, "mask_%04lld.png", static_cast<long long>(done));
        writePng((fs::path(o.out) / name).string(), mask, "mrgi replay");
      }
    }
    if (context->backend() == gl::Backend::Window) {
      compositor.present(context->width(), context->height());
      context->swapBuffers();
      if (!context->pollEvents()) break;
    }
    {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04lld.png", static_cast<long long>(done));
      awaiting.emplace_back((fs::path(o.out) / name).string(), frameStart);
      if (!composite.empty()) write(composite.clone());
      for (const cv::Mat& c : compositor.takeComposites(false)) write(c);
    }
    json record = {{"frame", done}, {"index", frame->index}, {"t", frame->timestamp}, {"stages", json::object()}};
    for (const auto& [k, v] : frameInfo.items()) record[k] = v;
    perFrame.push_back(record);
    ++done;
    profiler.endFrame();
    timesArrived(profiler.collect(false));
    if (limit > 0) bar(static_cast<double>(done) / static_cast<double>(limit));
  }
  for (const cv::Mat& c : compositor.takeComposites(true)) write(c);  // the reads still in flight
  profiler.endFrame();                                                // the last writes' waits, which are no frame's
  timesArrived(profiler.collect(true));
  writer.finish();  // every composite is on disk (and in the video) before the summary says so
  if (done == 0 && !interrupted) throw capture::CaptureError(o.source, "no frame could be replayed");
  int videoFrames = 0;
  if (video) videoFrames = video->close();
  const double wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  json summary;
  summary["generated_by"] = "mrgi replay";  // how a later replay into --out recognises its own output
  summary["source"] = o.source;
  summary["frames"] = done;
  summary["resolution"] = {width, height};
  summary["gl"] = {{"backend", std::string(gl::backendName(backend))},
                   {"renderer", context->renderer()},
                   {"version", context->version()},
                   {"detail", context->detail()}};
  summary["process"] = processSettingsInEffect();  // how it took its cores and memory: the timings depend on them
  json mean;
  for (const auto& [name, s] : sums)
    mean[name] = {{"cpu_ms", s.first / done}, {"gpu_ms", s.second / done}};  // done > 0 when sums has entries
  summary["stages_ms"] = mean;  // means over all frames: a skipped stage costs 0 on its frame
  summary["skipped_frames"] = skipped;
  summary["reuse"] = !o.recomputeAll;
  // Whether each frame's CPU half ran on the worker while GL worked on the frame before (its stages' times
  // then overlap the loop's and do not add up to the frame's).
  summary["overlapped"] = overlap;
  summary["finish_stages"] = o.finishStages;  // each GL stage waited for: its GPU time its own, the frame slower
  if (const LightingSetup* setup = frames.setup()) {
    summary["scene"] = o.scene.scene;
    summary["technique"] = setup->scene.technique.name;
    summary["roles"] = {{"real", setup->scene.technique.real}, {"virtual", setup->scene.technique.virtualObject}};
    if (!o.scene.preset.empty()) summary["preset"] = o.scene.preset;
    summary["knobs"] = lighting::usedKnobsJson(setup->scene.technique, setup->scene.knobs);
    // Per technique, the mean of its per-frame flicker where it reports one.
    std::map<std::string, std::pair<double, int>> flicker;
    for (const auto& f : perFrame)
      if (f.contains("techniques"))
        for (const auto& [name, st] : f["techniques"].items())
          if (st.contains("flicker")) flicker[name].first += st["flicker"].get<double>(), ++flicker[name].second;
    for (const auto& [name, sum] : flicker) summary["flicker_mean"][name] = sum.first / sum.second;
    summary["lights"] = setup->lights.size();
  }
  summary["wall_ms_per_frame"] = done ? wallMs / done : 0.0;
  // The writer thread: its encoding time per frame (off the frame loop), the loop's waits for it, and the
  // most composites that waited at once.
  summary["writer"] = {{"encode_ms_per_frame", done ? 1e3 * writer.busySeconds() / done : 0.0},
                       {"waited_ms_per_frame", done ? 1e3 * writer.blockedSeconds() / done : 0.0},
                       {"peak_queued", writer.peakQueued()}};
  // Throughput and latency: frames a second over the whole run, and per frame the time from its arrival (read
  // and decoded) to its composite on disk (a queue that grows would show here).
  summary["fps"] = wallMs > 0 ? 1e3 * done / wallMs : 0.0;
  summary["latency_ms"] = latency.summary();
  summary["interrupted"] = interrupted;
  if (video) summary["video"] = {{"file", o.mp4}, {"frames", videoFrames}, {"fps", fps}};
  summary["per_frame"] = perFrame;
  summary["frames_with_pose"] = posed;
  summary["pose"] = {{"mode", toString(o.pose)}, {"frames", posedBy}};
  const reconstruction::RoomModel* fusedRoom = fusedFirst ? &fusedFirst->model : frames.liveRoom();
  if (fusedRoom) {
    summary["room"] = {{"integrated", fusedRoom->framesIntegrated()},
                       {"refused", fusedRoom->framesRefused()},
                       {"blocks", fusedRoom->blocks()},
                       {"fused", fusedFirst ? "before the replay, from every frame" : "as the frames came"}};
    if (!o.rooms.save.empty() && fusedRoom->framesIntegrated() > 0 &&
        !runtime::saveRoomModel(o.rooms.save, *fusedRoom, o.source).positions.empty())
      summary["room"]["saved"] = o.rooms.save;
  }
  capture::writeFileAtomically(fs::path(o.out) / "summary.json", jsonText(summary, o.source, 2) + "\n");
  if (const LightingSetup* setup = frames.setup(); setup && posed == 0 && done > 0 && !interrupted)
    // The frames are written (the camera images), but nothing could be placed: say so and fail.
    throw capture::CaptureError(
        o.source, "no frame could be placed in " + std::to_string(done) + " frames (--pose " + toString(o.pose) +
                      ": marker " + setup->tagFamily +
                      (setup->tagId >= 0 ? " id " + std::to_string(setup->tagId) : " of any id") + " never seen)");
  // Lights from the room see what it covers around the objects; said once, from the last estimate.
  for (auto it = perFrame.rbegin(); it != perFrame.rend(); ++it)
    if (it->contains("room") && (*it)["room"].contains("lights")) {
      warnIfRoomCoverageLow(o.source, (*it)["room"]["lights"].value("coverage", 1.0), "the objects");
      break;
    }
  if (const int64_t lost = posedBy.count("lost") ? posedBy["lost"] : 0; lost > 0 && !interrupted)
    std::fprintf(stderr, "warning: %s: %lld of %lld frames lost (no trusted camera pose): drawn without the objects\n",
                 o.source.c_str(), static_cast<long long>(lost), static_cast<long long>(done));
  std::printf("%s %lld frames (%.1f ms/frame); wrote %s: %s\n", interrupted ? "interrupted: replayed" : "replayed",
              static_cast<long long>(done), done ? wallMs / done : 0.0, o.out.c_str(), describeFolder(o.out).c_str());
  return interrupted ? 130 : 0;
}

}  // namespace mrgi::runtime
