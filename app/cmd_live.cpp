// mrgi live: the interactive AR demo. A depth sensor (OpenNI2) and optionally a V4L2 fisheye camera, or a
// recording played through the same window; a Dear ImGui panel with the technique, presets and every
// knob, debug views, per-stage timings, marker status and a record toggle.
#include <imgui.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "app/live_source.h"
#include "app/window_ui.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/session.h"
#include "compositor/compositor.h"
#include "gl/context.h"
#include "gl/error.h"
#include "lighting/scene_file.h"
#include "lighting/techniques/registry.h"
#include "runtime/debug_view.h"
#include "runtime/frame_pipeline.h"
#include "runtime/output.h"
#include "runtime/presets.h"
#include "runtime/room_fusion.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::app {
namespace {

struct LiveOptions {
  LiveSourceOptions in;
  SceneChoice scene{"", "", MRGI_DEFAULT_PRESETS, ""};
  std::string gl = "window";
  int frames = 0;
  std::string screenshot;
  std::string record;
  bool recordNow = false;
  bool noLoop = false;
  PoseMode pose = PoseMode::Tracked;
  std::string view = "composite";
  RoomFlags rooms;  ///< --room, --fuse-room and their company
};

std::string defaultRecordDir() {
  char buf[64];
  const std::time_t t = std::time(nullptr);
  std::strftime(buf, sizeof buf, "live-%Y%m%d-%H%M%S", std::localtime(&t));
  return buf;
}

/// A knob's widget from its declaration (slider over its declared range, logarithmic where declared, or a
/// checkbox); true once the user lets go of it after a change (the pipeline is rebuilt then, not on every
/// pixel of a drag).
bool knobWidget(const lighting::KnobInfo& k, double& value) {
  const char* label = k.name.c_str();
  switch (k.type) {
    case lighting::KnobType::Bool: {
      bool b = value != 0.0;
      const bool changed = ImGui::Checkbox(label, &b);
      value = b ? 1.0 : 0.0;
      if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", k.description.c_str());
      return changed;
    }
    case lighting::KnobType::Int: {
      int v = static_cast<int>(value);
      ImGui::SliderInt(label, &v, static_cast<int>(k.lo), static_cast<int>(k.hi), "%d",
                       k.logScale ? ImGuiSliderFlags_Logarithmic : 0);
      value = v;
      break;
    }
    case lighting::KnobType::Real: {
      float v = static_cast<float>(value);
      ImGui::SliderFloat(label, &v, static_cast<float>(k.lo), static_cast<float>(k.hi), "%.3f",
                         k.logScale ? ImGuiSliderFlags_Logarithmic : 0);
      value = v;
      break;
    }
  }
  if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", k.description.c_str());
  return ImGui::IsItemDeactivatedAfterEdit();
}

/// A combo of "none" and every technique that can serve the role; true when the choice changed.
bool roleCombo(const char* label, std::string& name, bool real) {
  std::vector<std::string> items{"none"};
  for (const auto& t : lighting::techniques())
    if (real ? t.real : t.virtualObject) items.push_back(t.name);
  int current = 0;
  for (size_t i = 0; i < items.size(); ++i)
    if (items[i] == name) current = static_cast<int>(i);
  std::vector<const char*> cstr;
  for (const auto& i : items) cstr.push_back(i.c_str());
  if (!ImGui::Combo(label, &current, cstr.data(), static_cast<int>(cstr.size()))) return false;
  name = items[static_cast<size_t>(current)];
  return true;
}

int runLive(const LiveOptions& o) {
  checkReplaceable(o.screenshot, "--screenshot", "mrgi live");
  LiveSource live(o.in);
  const capture::SourceInfo& info = live.source().info();
  const int width = info.colourIntrinsics.width, height = info.colourIntrinsics.height;

  std::optional<LightingSetup> base;
  lighting::SceneDescription scene;
  if (!o.scene.scene.empty()) {
    scene = loadChosenScene(o.scene);
    if (scene.lightSource == lighting::LightSource::Fisheye && o.in.source.empty()) {
      // Live: the lights come from the V4L2 fisheye camera, not from a session manifest.
      if (o.in.fisheye.empty())
        throw capture::CaptureError(o.scene.scene, "lights: \"fisheye\" needs --fisheye /dev/videoN live");
      scene.lightSource = lighting::LightSource::Scene;
      base = prepareLighting(scene, o.scene.scene, live.source(), live.name(), o.pose);
      base->fisheye = live.fisheyeCalibration();
      if (!base->fisheye) throw capture::CaptureError(o.in.fisheye, "delivered no fisheye frame");
      base->scene.ambientFromManifest = false;
    } else {
      base = prepareLighting(scene, o.scene.scene, live.source(), live.name(), o.pose, o.rooms.any());
    }
  }

  const std::shared_ptr<const reconstruction::RoomMesh> room = openRoom(o.rooms, static_cast<bool>(base));

  const cv::Size win = WindowUi::windowSize(width, height);
  gl::ContextConfig cfg;
  cfg.backend = gl::parseBackend(o.gl);
  cfg.width = win.width;
  cfg.height = win.height;
  cfg.title = "mrgi live: " + live.name();
  std::unique_ptr<gl::Context> context;
  try {
    context = gl::createContext(cfg);
  } catch (const gl::GlError& e) {
    // The backend suggests a headless backend; the live demo has none (mrgi replay is its headless twin).
    std::string why = e.what();
    why = why.substr(0, why.find("; use --gl"));
    throw gl::GlError(why + "; the live demo needs a display (mrgi replay runs headless)");
  }
  WindowUi ui(*context);
  compositor::Compositor compositor(width, height);

  FrameOptions fo;
  fo.pose = o.pose;
  fo.foundWorldAnew = true;  // a scene placed in a recording's first-frame world is placed in this camera's first frame
  fo.room = room;
  fo.cacheDir = o.rooms.room;  // techniques keep what they precompute beside the saved room
  fo.progress = precomputeProgress();
  if (o.rooms.fuse) fo.fuse = std::make_shared<reconstruction::RoomModel>();  // kept across rebuilds of the pipeline
  fo.fuseRefresh = o.rooms.fuseRefresh;
  fo.trackFusedRoom = o.rooms.track;
  fo.techniqueStats = false;  // the window shows none: nothing of them is read back
  std::unique_ptr<FramePipeline> frames;
  auto rebuild = [&] {
    std::optional<LightingSetup> s = base;
    if (s) s->scene = scene;
    // Lights and ambient estimated from the last fisheye frame carry over (the next one may be many frames
    // away).
    if (s && frames && frames->setup()) {
      s->lights = frames->setup()->lights;
      s->ambient = frames->setup()->ambient;
      s->ambientSh = frames->setup()->ambientSh;
    }
    frames = std::make_unique<FramePipeline>(std::move(s), width, height, fo);
  };
  rebuild();

  std::vector<DebugView> views = debugViews(*frames);
  int viewIndex = 0;
  for (size_t i = 0; i < views.size(); ++i)
    if (o.view == debugViewName(views[i])) viewIndex = static_cast<int>(i);
  bool axes = true, paused = false, step = false, needRebuild = false, ended = false;
  int presetIndex = 0;  // 0 = the scene file's knobs
  const char* presetNames[] = {"scene file", "fast", "balanced", "accurate", "custom"};
  std::optional<capture::SessionWriter> recorder;
  std::string recordDir = o.record.empty() ? defaultRecordDir() : o.record;
  bool recording = o.recordNow;

  std::optional<capture::Frame> frame;
  FrameResult result;
  cv::Mat lastFisheye, view;
  std::map<std::string, gl::StageTime> stages;
  double fps = 0, frameMs = 0, pipelineMs = 0;
  std::chrono::steady_clock::time_point loopStart, loopEnd;  // the first frame's start, the last frame's end
  int64_t processed = 0;
  std::map<std::string, int64_t> posedBy;  // frames by how they were posed (marker, odometry, ..., lost)
  std::string status = "starting";
  InterruptGuard guard;
  const double period = info.fps > 0 ? 1.0 / info.fps : 0.0;
  auto last = std::chrono::steady_clock::now();
  gl::Profiler profiler;
  const auto gpuView = [&] { return views[viewIndex] == Views::kComposite; };

  // While the composite view plays, frame n + 1 is read and prepared (marker, depth filter, albedo, real mesh
  // and VALs: FramePipeline::prepare) on a worker while GL renders frame n. The other views read the
  // pipeline between frames, a rebuild replaces it, fusion refreshes what rendering reads and a paused demo
  // reads nothing: then the worker is joined first and frames are worked on in the loop.
  std::future<runtime::FrameAhead> ahead;
  std::optional<runtime::FrameAhead> pending;  // a frame the worker delivered that the loop has not taken yet
  const auto overlap = [&] { return gpuView() && !o.rooms.fuse && !paused && !needRebuild; };
  const auto join = [&] {
    if (ahead.valid()) pending = ahead.get();
  };
  size_t lightCount = 0;      // of the frame shown (the worker may be changing the setup's)
  int64_t preparedAhead = 0;  // frames the worker prepared

  while (!InterruptGuard::interrupted() && ui.beginFrame()) {
    if (!overlap()) join();
    if (needRebuild) {
      rebuild();
      if (pending) pending->prepared.reset();  // prepared by the pipeline just replaced: worked on again
      views = debugViews(*frames);
      viewIndex = std::min(viewIndex, static_cast<int>(views.size()) - 1);
      needRebuild = false;
    }
    bool fresh = false;
    if (!paused || step) {
      step = false;
      join();
      runtime::FrameAhead next;
      if (pending) {
        next = std::move(*pending);
        pending.reset();
      } else {
        next.frame = live.next();
      }
      if (next.frame && next.frame->rgbd) {
        if (recording) {
          const capture::Frame& arrived = next.arrived ? *next.arrived : *next.frame;  // before registration
          if (!recorder) recorder.emplace(recordDir, manifestFor(live.source(), arrived));
          recorder->append(arrived);
        }
        frame = std::move(next.frame);
        // The composite view shows the compositor's texture as it is (the marker axes drawn over it): nothing
        // is read back. Every other view reads what it shows.
        compositor.setReadback(gpuView() ? compositor::Compositor::Readback::None
                                         : compositor::Compositor::Readback::Now);
        const auto t0 = std::chrono::steady_clock::now();
        if (processed == 0) loopStart = t0;
        if (next.stages) profiler.adopt(*next.stages);
        if (next.prepared) ++preparedAhead;
        std::optional<PreparedFrame> prepared = std::move(next.prepared);
        if (!prepared && !o.rooms.fuse)
          prepared = frames->prepare(*frame, profiler);  // before the worker prepares the next
        if (overlap()) ahead = runtime::readAhead([&live] { return live.next(); }, frames.get());
        if (prepared) {
          lightCount = prepared->lights.size();
          frames->render(*frame, *prepared, compositor, profiler);
          result = std::move(prepared->result);
        } else {
          result = frames->process(*frame, compositor, profiler);
          lightCount = frames->setup() ? frames->setup()->lights.size() : 0;
        }
        frameMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        pipelineMs += frameMs;
        // Stage times a frame late, when their GPU timestamps have arrived (the loop never waits for them).
        profiler.endFrame();
        for (auto& t : profiler.collect(false)) stages = std::move(t.stages);
        if (frame->fisheye) lastFisheye = frame->fisheye->image;
        ++processed;
        if (frames->setup()) ++posedBy[result.pose.tracked() ? toString(result.pose.by) : "lost"];
        fresh = true;
        status = "playing";
      } else if (!next.frame) {
        status = "end of " + live.name();
        paused = ended = true;
      }
    }
    if (gpuView() && frame) {
      std::vector<WindowUi::Line> lines;
      if (axes && result.T_marker_camera) {
        const auto p = markerAxesPixels(frame->rgbd->colourIntrinsics, *result.T_marker_camera,
                                        frames->setup() ? frames->setup()->tagSize : 0.1);
        const cv::Vec3b colours[3] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}};
        for (int i = 0; i < 3; ++i) lines.push_back({{p[0].x, p[0].y, p[i + 1].x, p[i + 1].y}, colours[i]});
      }
      ui.showTexture(compositor.output().id(), compositor.output().width(), compositor.output().height(),
                     debugViewName(views[viewIndex]), lines);
    } else {
      if (frame && result.composite.empty()) result.composite = compositor.readOutput();  // left on the GPU before
      if (fresh || view.empty() || ImGui::IsAnyItemActive())
        view = frame ? renderDebugView(views[viewIndex], *frames, result, frame->rgbd->colourIntrinsics, lastFisheye)
                     : cv::Mat();
      ui.showImage(view, std::string(debugViewName(views[viewIndex])) +
                             (view.empty() ? " (nothing to show on this frame)" : ""));
    }

    ui.beginPanel("mrgi live");
    ImGui::Text("%s", live.name().c_str());
    ImGui::Text("frame %lld  %s", frame ? static_cast<long long>(frame->index) : -1LL, status.c_str());
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - last).count();
    last = now;
    if (dt > 0) fps = fps > 0 ? 0.9 * fps + 0.1 / dt : 1.0 / dt;
    ImGui::Text("%.1f fps, pipeline %.1f ms", fps, frameMs);
    const std::string marker = result.info.value("marker", std::string(frames->setup() ? "-" : "no scene"));
    ImGui::Text("marker: %s", marker.c_str());
    if (frames->setup()) {
      // How this frame was posed; a lost frame is drawn without the objects (ARKit's "not available").
      if (result.pose.tracked())
        ImGui::Text("pose: %s (%s)", toString(result.pose.by), toString(o.pose));
      else
        ImGui::TextColored(ImVec4(1.f, 0.35f, 0.3f, 1.f), "pose: LOST - objects hidden (%s)", toString(o.pose));
      if (result.pose.fitness >= 0)
        ImGui::Text("tracking: fitness %.2f, rmse %.1f mm", result.pose.fitness, 1e3 * result.pose.inlierRmse);
    }
    if (frames->setup()) ImGui::Text("lights: %zu", lightCount);
    ImGui::Checkbox("pause", &paused);
    ImGui::SameLine();
    if (ImGui::Button("step")) step = true;
    ImGui::SameLine();
    if (ImGui::Checkbox("record", &recording) && !recording && recorder) {
      status = "recorded " + std::to_string(recorder->framesWritten()) + " frames into " + recordDir;
      recorder.reset();
      recordDir = o.record.empty() ? defaultRecordDir() : o.record + "-" + std::to_string(processed);
    }
    if (recording)
      ImGui::Text("recording into %s (%lld frames)", recordDir.c_str(),
                  static_cast<long long>(recorder ? recorder->framesWritten() : 0));

    if (ImGui::CollapsingHeader("View", ImGuiTreeNodeFlags_DefaultOpen)) {
      for (size_t i = 0; i < views.size(); ++i)
        if (ImGui::RadioButton(debugViewName(views[i]), viewIndex == static_cast<int>(i)))
          viewIndex = static_cast<int>(i), view.release();
      ImGui::Checkbox("marker axes", &axes);
    }
    if (frames->setup() && ImGui::CollapsingHeader("Technique and knobs", ImGuiTreeNodeFlags_DefaultOpen)) {
      lighting::TechniqueChoice& choice = scene.technique;
      const bool realChanged = roleCombo("real pixels", choice.real, true);
      const bool virtualChanged = roleCombo("virtual object", choice.virtualObject, false);
      if (realChanged || virtualChanged) choice.name = lighting::canonicalName(choice), needRebuild = true;
      if (ImGui::Combo("preset", &presetIndex, presetNames, 5) && presetIndex < 4) {
        if (presetIndex == 0)
          scene = lighting::loadScene(o.scene.scene);
        else
          applyPreset(loadPreset(o.scene.presets, presetNames[presetIndex]), scene);
        needRebuild = true;
      }
      // Every knob of the shared resources and of the techniques in use, from their declarations.
      bool edited = false;
      std::vector<const lighting::KnobGroup*> groups{&lighting::frameKnobGroup()};
      for (const auto& a : lighting::assignRoles(choice)) groups.push_back(&a.info->knobs);
      for (const lighting::KnobGroup* g : groups) {
        ImGui::Separator();
        ImGui::TextUnformatted(g->key.c_str());
        ImGui::PushID(g->key.c_str());
        for (const lighting::KnobInfo& k : g->knobs) edited |= knobWidget(k, scene.knobs[g->key][k.name]);
        ImGui::PopID();
      }
      if (edited) presetIndex = 4, needRebuild = true;
    }
    if (ImGui::CollapsingHeader("Stages (ms)", ImGuiTreeNodeFlags_DefaultOpen)) {
      if (ImGui::BeginTable("stages", 3)) {
        ImGui::TableSetupColumn("stage");
        ImGui::TableSetupColumn("cpu");
        ImGui::TableSetupColumn("gpu");
        ImGui::TableHeadersRow();
        for (const auto& [name, t] : stages) {
          ImGui::TableNextRow();
          ImGui::TableNextColumn();
          ImGui::TextUnformatted(name.c_str());
          ImGui::TableNextColumn();
          ImGui::Text("%.1f", t.cpuMs);
          ImGui::TableNextColumn();
          ImGui::Text("%.1f", t.gpuMs);
        }
        ImGui::EndTable();
      }
      if (result.info.contains("skipped")) {
        std::string s;
        for (const auto& k : result.info["skipped"]) s += (s.empty() ? "" : ", ") + k.get<std::string>();
        ImGui::TextWrapped("skipped (inputs unchanged): %s", s.c_str());
      }
    }
    ui.endPanel();

    const bool done =
        o.frames > 0 && (processed >= o.frames || ended);  // a scripted run never waits on a closed source
    cv::Mat shot;
    ui.endFrame(done && !o.screenshot.empty() ? &shot : nullptr);
    if (fresh) loopEnd = std::chrono::steady_clock::now();
    if (done) {
      if (!o.screenshot.empty()) {
        createParentDirectory(o.screenshot);
        writePng(o.screenshot, shot, "mrgi live");
      }
      break;
    }
    // A recording plays no faster than it was recorded.
    if (fresh && live.recording() && period > 0 && o.frames == 0) {
      const double spent = std::chrono::duration<double>(std::chrono::steady_clock::now() - now).count();
      if (spent < period) std::this_thread::sleep_for(std::chrono::duration<double>(period - spent));
    }
  }
  json summary = {{"source", live.name()},
                  {"frames", processed},
                  {"pose", {{"mode", toString(o.pose)}, {"frames", posedBy}}},
                  {"window", {context->width(), context->height()}},
                  {"renderer", context->renderer()}};
  // Throughput of the window loop (frame, UI and swap; no writes), from the first frame's start to the last's
  // end, and the mean time of the frame pipeline alone within it.
  if (processed > 0) {
    const double wallMs = std::chrono::duration<double, std::milli>(loopEnd - loopStart).count();
    summary["wall_ms_per_frame"] = wallMs / static_cast<double>(processed);
    summary["fps"] = wallMs > 0 ? 1e3 * static_cast<double>(processed) / wallMs : 0.0;
    summary["pipeline_ms_per_frame"] = pipelineMs / static_cast<double>(processed);
    summary["prepared_ahead"] = preparedAhead;
  }
  if (!o.screenshot.empty() && o.frames > 0 && (processed >= o.frames || ended)) summary["screenshot"] = o.screenshot;
  if (recorder) summary["recorded"] = {{"session", recordDir}, {"frames", recorder->framesWritten()}};
  if (fo.fuse) {
    summary["room"] = {{"integrated", fo.fuse->framesIntegrated()},
                       {"refused", fo.fuse->framesRefused()},
                       {"blocks", fo.fuse->blocks()}};
    if (!o.rooms.save.empty() && fo.fuse->framesIntegrated() > 0 &&
        !runtime::saveRoomModel(o.rooms.save, *fo.fuse, live.name()).positions.empty())
      summary["room"]["saved"] = o.rooms.save;
  }
  std::printf("%s\n", jsonText(summary, o.in.source.empty() ? o.in.device : o.in.source).c_str());
  return InterruptGuard::interrupted() ? 130 : 0;
}

}  // namespace

Action addLive(CLI::App& app) {
  auto o = std::make_shared<LiveOptions>();
  app.add_option("--source", o->in.source,
                 "play a session, TUM sequence or .oni file in the window instead of the sensor");
  app.add_option("--device", o->in.device, "depth sensor URI")->capture_default_str();
  app.add_option("--fisheye", o->in.fisheye, "V4L2 fisheye camera for live light estimation (e.g. /dev/video0)");
  app.add_option("--fisheye-calibration", o->in.fisheyeCalibration,
                 "its calibration (YAML from mrgi calibrate-fisheye)");
  app.add_option("--fisheye-every", o->in.fisheyeEvery, "grab a fisheye frame every N depth frames")
      ->check(numberIn(1, 1e6));
  app.add_option("--scene", o->scene.scene,
                 "scene file: virtual objects relative to the marker, lights, technique, knobs");
  addRoomFlags(app, o->rooms, "when the demo ends");
  app.add_option("--technique", o->scene.technique, "lighting technique, overrides the scene file's")
      ->check(techniqueValidator());
  app.add_option("--preset", o->scene.preset, "measured preset (overrides the scene file's knobs)")
      ->check(CLI::IsMember({"fast", "balanced", "accurate"}));
  app.add_option("--presets", o->scene.presets, "presets file written by mrgi bench --presets")->capture_default_str();
  app.add_option("--gl", o->gl, "GL backend (the live demo needs a window; use mrgi replay headless)")
      ->check(CLI::IsMember({"window"}));
  app.add_option("--frames", o->frames, "stop after N frames (0 = until the window closes)")->check(numberIn(0, 1e9));
  app.add_option("--screenshot", o->screenshot, "with --frames: save the window's last frame (PNG)");
  app.add_option("--record", o->record, "folder the record toggle writes a session into (default: live-DATE-TIME)");
  app.add_flag("--record-now", o->recordNow, "start recording with the first frame (as if the toggle were on)");
  app.add_flag("--no-loop", o->noLoop, "stop at the end of a recording instead of playing it again");
  addPoseOption(app, o->pose);
  app.add_option("--view", o->view, "initial view: composite, delta, gbuffer_albedo, dlpv_slices, fisheye_lights, ...");
  return [o] {
    o->in.loop = !o->noLoop;
    if (!o->screenshot.empty() && o->frames == 0) throw std::invalid_argument("--screenshot needs --frames N");
    return runLive(*o);
  };
}

}  // namespace mrgi::app
