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
#include "app/window_ui.h"
#include "capture/checks.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/live_source.h"
#include "capture/session.h"
#include "compositor/compositor.h"
#include "gl/context.h"
#include "gl/error.h"
#include "lighting/scene_file.h"
#include "lighting/techniques/registry.h"
#include "runtime/debug_view.h"
#include "runtime/frame_pipeline.h"
#include "runtime/live_session.h"
#include "runtime/output.h"
#include "runtime/presets.h"
#include "runtime/room_fusion.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::app {
namespace {

struct LiveOptions {
  capture::LiveSourceOptions in;
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

/// The panel's technique section: a combo per role, the preset and every knob of the techniques in use; true
/// when the scene changed (the pipeline is rebuilt).
bool techniquePanel(lighting::SceneDescription& scene, int& presetIndex, const SceneChoice& choice) {
  const char* presetNames[] = {"scene file", "fast", "balanced", "accurate", "custom"};
  lighting::TechniqueChoice& technique = scene.technique;
  bool changed = false;
  const bool realChanged = roleCombo("real pixels", technique.real, true);
  const bool virtualChanged = roleCombo("virtual object", technique.virtualObject, false);
  if (realChanged || virtualChanged) technique.name = lighting::canonicalName(technique), changed = true;
  if (ImGui::Combo("preset", &presetIndex, presetNames, 5) && presetIndex < 4) {
    if (presetIndex == 0)
      scene = lighting::loadScene(choice.scene);
    else
      applyPreset(loadPreset(choice.presets, presetNames[presetIndex]), scene);
    changed = true;
  }
  // Every knob of the shared resources and of the techniques in use, from their declarations.
  bool edited = false;
  std::vector<const lighting::KnobGroup*> groups{&lighting::frameKnobGroup()};
  for (const auto& a : lighting::assignRoles(scene.technique)) groups.push_back(&a.info->knobs);
  for (const lighting::KnobGroup* g : groups) {
    ImGui::Separator();
    ImGui::TextUnformatted(g->key.c_str());
    ImGui::PushID(g->key.c_str());
    for (const lighting::KnobInfo& k : g->knobs) edited |= knobWidget(k, scene.knobs[g->key][k.name]);
    ImGui::PopID();
  }
  if (edited) presetIndex = 4, changed = true;
  return changed;
}

/// The panel's stage times (ms, CPU and GPU) and the stages skipped on this frame.
void stagesPanel(const std::map<std::string, gl::StageTime>& stages, const json& info) {
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
  if (info.contains("skipped")) {
    std::string s;
    for (const auto& k : info["skipped"]) s += (s.empty() ? "" : ", ") + k.get<std::string>();
    ImGui::TextWrapped("skipped (inputs unchanged): %s", s.c_str());
  }
}

/// The panel's status: source, frame, rate, marker, how the frame was posed, lights.
void statusPanel(LiveSession& live, const std::string& status, double fps, PoseMode mode) {
  const FrameResult& result = live.result();
  const FramePipeline& frames = live.frames();
  ImGui::Text("%s", live.source().name().c_str());
  ImGui::Text("frame %lld  %s", live.frame() ? static_cast<long long>(live.frame()->index) : -1LL, status.c_str());
  ImGui::Text("%.1f fps, pipeline %.1f ms", fps, live.frameMs());
  const std::string marker = result.info.value("marker", std::string(frames.setup() ? "-" : "no scene"));
  ImGui::Text("marker: %s", marker.c_str());
  if (!frames.setup()) return;
  // How this frame was posed; a lost frame is drawn without the objects (ARKit's "not available").
  if (result.pose.tracked())
    ImGui::Text("pose: %s (%s)", toString(result.pose.by), toString(mode));
  else
    ImGui::TextColored(ImVec4(1.f, 0.35f, 0.3f, 1.f), "pose: LOST - objects hidden (%s)", toString(mode));
  if (result.pose.fitness >= 0)
    ImGui::Text("tracking: fitness %.2f, rmse %.1f mm", result.pose.fitness, 1e3 * result.pose.inlierRmse);
  ImGui::Text("lights: %zu", live.lightCount());
  // Lit from the room: how much of it the objects see (it grows as a sensor's room is fused).
  if (live.roomCoverage() >= 0) ImGui::Text("room seen: %.0f %% of the directions", 100 * live.roomCoverage());
}

/// The view: the compositor's texture (with the marker's axes) for the composite, else the debug view read back.
void showView(WindowUi& ui, LiveSession& live, const DebugView& v, bool axes, bool fresh, cv::Mat& view) {
  FrameResult& result = live.result();
  const auto& frame = live.frame();
  if (v == Views::kComposite && frame) {
    std::vector<WindowUi::Line> lines;
    if (axes && result.T_marker_camera) {
      const LightingSetup* setup = live.frames().setup();
      const auto p =
          markerAxesPixels(frame->rgbd->colourIntrinsics, *result.T_marker_camera, setup ? setup->tagSize : 0.1);
      const cv::Vec3b colours[3] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}};
      for (int i = 0; i < 3; ++i) lines.push_back({{p[0].x, p[0].y, p[i + 1].x, p[i + 1].y}, colours[i]});
    }
    const gl::Texture& out = live.compositor().output();
    ui.showTexture(out.id(), out.width(), out.height(), debugViewName(v), lines);
    return;
  }
  if (frame && result.composite.empty()) result.composite = live.compositor().readOutput();  // left on the GPU
  if (fresh || view.empty() || ImGui::IsAnyItemActive())
    view = frame ? renderDebugView(v, live.frames(), result, frame->rgbd->colourIntrinsics, live.lastFisheye())
                 : cv::Mat();
  ui.showImage(view, std::string(debugViewName(v)) + (view.empty() ? " (nothing to show on this frame)" : ""));
}

int runLive(const LiveOptions& o) {
  checkReplaceable(o.screenshot, "--screenshot", "mrgi live");
  LiveSessionOptions so;
  so.in = o.in, so.scene = o.scene, so.pose = o.pose, so.rooms = o.rooms, so.record = o.record;
  so.recordNow = o.recordNow;
  so.room = openRoom(so.rooms, !o.scene.scene.empty());
  LiveSession live(so, [&](int width, int height) {
    const cv::Size win = WindowUi::windowSize(width, height);
    gl::ContextConfig cfg;
    cfg.backend = gl::parseBackend(o.gl);
    cfg.width = win.width;
    cfg.height = win.height;
    cfg.title = "mrgi live: " + (o.in.source.empty() ? o.in.device : o.in.source);
    try {
      return gl::createContext(cfg);
    } catch (const gl::GlError& e) {
      // The backend suggests a headless backend; the live demo has none (mrgi replay is its headless twin).
      std::string why = e.what();
      why = why.substr(0, why.find("; use --gl"));
      throw gl::GlError(why + "; the live demo needs a display (mrgi replay runs headless)");
    }
  });
  WindowUi ui(live.context());
  std::vector<DebugView> views = debugViews(live.frames());
  int viewIndex = -1;
  for (size_t i = 0; i < views.size(); ++i)
    if (o.view == debugViewName(views[i])) viewIndex = static_cast<int>(i);
  if (viewIndex < 0) {  // a misspelt view is an error, not the composite shown instead
    std::string names;
    std::vector<std::string> list;
    for (const auto& v : views)
      names += (names.empty() ? "" : ", ") + std::string(debugViewName(v)), list.push_back(debugViewName(v));
    throw FlagError("--view", "no view '" + o.view + "' here" + capture::didYouMean(o.view, list) +
                                  " (this scene and technique have: " + names + ")");
  }
  bool axes = true, paused = false, step = false, needRebuild = false;
  int presetIndex = 0;  // 0 = the scene file's knobs
  cv::Mat view;
  double fps = 0;
  std::string status = "starting";
  std::string screenshot;  // the file written, once it is
  InterruptGuard guard;
  const double fpsSource = live.source().info().fps, period = fpsSource > 0 ? 1.0 / fpsSource : 0.0;
  auto last = std::chrono::steady_clock::now();
  while (!InterruptGuard::interrupted() && ui.beginFrame()) {
    const bool composite = views[viewIndex] == Views::kComposite;
    if (!composite || paused || needRebuild) live.join();  // the pipeline is read or replaced between frames
    if (needRebuild) {
      live.rebuild();
      views = debugViews(live.frames());
      viewIndex = std::min(viewIndex, static_cast<int>(views.size()) - 1);
      needRebuild = false;
    }
    bool fresh = false;
    if (!paused || step) {
      fresh = live.advance(views[viewIndex] == Views::kComposite, !paused);
      if (fresh) status = "playing";
      if (live.ended()) status = "end of " + live.source().name(), paused = true;
      step = false;
    }
    showView(ui, live, views[viewIndex], axes, fresh, view);
    ui.beginPanel("mrgi live");
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - last).count();
    last = now;
    if (dt > 0) fps = fps > 0 ? 0.9 * fps + 0.1 / dt : 1.0 / dt;
    statusPanel(live, status, fps, o.pose);
    ImGui::Checkbox("pause", &paused);
    ImGui::SameLine();
    if (ImGui::Button("step")) step = true;
    ImGui::SameLine();
    bool recording = live.recording();
    if (ImGui::Checkbox("record", &recording))
      if (std::string said = live.setRecording(recording); !said.empty()) status = said;
    if (live.recording())
      ImGui::Text("recording into %s (%lld frames)", live.recordDir().c_str(),
                  static_cast<long long>(live.framesRecorded()));
    if (ImGui::CollapsingHeader("View", ImGuiTreeNodeFlags_DefaultOpen)) {
      for (size_t i = 0; i < views.size(); ++i)
        if (ImGui::RadioButton(debugViewName(views[i]), viewIndex == static_cast<int>(i)))
          viewIndex = static_cast<int>(i), view.release();
      ImGui::Checkbox("marker axes", &axes);
    }
    if (live.frames().setup() && ImGui::CollapsingHeader("Technique and knobs", ImGuiTreeNodeFlags_DefaultOpen))
      needRebuild |= techniquePanel(live.scene(), presetIndex, o.scene);
    if (ImGui::CollapsingHeader("Stages (ms)", ImGuiTreeNodeFlags_DefaultOpen))
      stagesPanel(live.stages(), live.result().info);
    ui.endPanel();
    // A scripted run never waits on a closed source.
    const bool done = o.frames > 0 && (live.processed() >= o.frames || live.ended());
    cv::Mat shot;
    ui.endFrame(done && !o.screenshot.empty() ? &shot : nullptr);
    if (fresh) live.shown();
    if (done) {
      if (!o.screenshot.empty()) {
        createParentDirectory(o.screenshot);
        writePng(o.screenshot, shot, "mrgi live");
        screenshot = o.screenshot;
      }
      break;
    }
    // A recording plays no faster than it was recorded.
    if (fresh && live.source().recording() && period > 0 && o.frames == 0) {
      const double spent = std::chrono::duration<double>(std::chrono::steady_clock::now() - now).count();
      if (spent < period) std::this_thread::sleep_for(std::chrono::duration<double>(period - spent));
    }
  }
  const json summary = live.finish(screenshot);
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
