// mrgi insert: the flags of placing a virtual object relative to the marker (runtime/insert.h), and the
// window that moves, turns, scales and snaps it and saves the scene file.
#include <imgui.h>

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "app/window_ui.h"
#include "runtime/debug_view.h"
#include "runtime/insert.h"
#include "runtime/output.h"

using nlohmann::json;

namespace mrgi::app {
namespace {

/// The flags that are not the library's options.
struct InsertFlags {
  InsertOptions o;
  std::vector<double> translate{0, 0, 0}, rotateDeg{0, 0, 0}, albedo{0.8, 0.8, 0.8};
  bool snap = false;
  std::string up = "camera";
  std::vector<double> at;  // pixel u,v: translate = the surface point seen there
  std::string preview;
  std::string gl = "osmesa";
  int frames = 0;          ///< window: close after N UI frames (scripted runs, tests)
  std::string screenshot;  ///< window: save its last frame
};

cv::Vec3d vec3(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

/// The window: sliders move, turn and scale the object, the composite follows when a slider is let go;
/// "snap" rests it on the table, "save" writes the scene file (so does closing after --frames N).
int interactive(const InsertFlags& f, Insertion& in, const SnapUp& up) {
  WindowUi ui(in.context());
  json& doc = in.document();
  json& obj = doc["objects"][in.index()];
  auto get3 = [&](const char* key, float* v, double fallback) {
    for (int i = 0; i < 3; ++i) v[i] = static_cast<float>(obj.contains(key) ? obj[key][i].get<double>() : fallback);
  };
  float t[3], r[3], albedo[3], scale = static_cast<float>(obj.value("scale", 1.0));
  get3("translate", t, 0.0);
  get3("rotate_deg", r, 0.0);
  for (int i = 0; i < 3; ++i) albedo[i] = static_cast<float>(obj["material"]["albedo"][i].get<double>());
  cv::Mat view;
  bool dirty = true, unsaved = true;
  std::string status = "drag a slider, then let go to see the composite";
  int shown = 0;
  const std::string& save = f.o.save;
  auto saveNow = [&] {
    in.save();
    unsaved = false;
    status = "saved " + save;
  };
  while (!InterruptGuard::interrupted() && ui.beginFrame()) {
    // A scripted run (--frames N) saves before drawing its last frame: its screenshot shows what was saved.
    const bool last = f.frames > 0 && shown + 1 >= f.frames;
    if (last) saveNow();
    if (dirty) {
      view = in.render(doc);
      drawMarkerAxes(view, in.frame().rgbd->colourIntrinsics, *in.measured().T_marker_camera, in.setup().tagSize);
      dirty = false;
    }
    ui.showImage(view, "object " + std::to_string(in.index()) + " of " + save + (unsaved ? " (unsaved)" : ""));
    ui.beginPanel("mrgi insert");
    ImGui::TextWrapped("%s", f.o.model.c_str());
    bool edited = false;
    ImGui::DragFloat3("translate (m)", t, 0.002f, -10.f, 10.f, "%.3f");
    edited |= ImGui::IsItemDeactivatedAfterEdit();
    ImGui::DragFloat3("rotate (deg)", r, 0.5f, -360.f, 360.f, "%.1f");
    edited |= ImGui::IsItemDeactivatedAfterEdit();
    ImGui::DragFloat("scale", &scale, 0.002f, 1e-3f, 100.f, "%.3f");
    edited |= ImGui::IsItemDeactivatedAfterEdit();
    ImGui::ColorEdit3("albedo", albedo);
    edited |= ImGui::IsItemDeactivatedAfterEdit();
    if (edited) {
      obj["translate"] = {t[0], t[1], t[2]};
      obj["rotate_deg"] = {r[0], r[1], r[2]};
      obj["scale"] = scale;
      obj["material"]["albedo"] = {albedo[0], albedo[1], albedo[2]};
      dirty = unsaved = true;
    }
    if (ImGui::Button("snap to the table")) {
      if (const auto why = in.snap(up)) {
        status = *why;
      } else {
        get3("translate", t, 0.0);
        get3("rotate_deg", r, 0.0);
        dirty = unsaved = true;
        status = "resting on the plane below";
      }
    }
    ImGui::SameLine();
    if (ImGui::Button("save")) saveNow();
    ImGui::TextWrapped("%s", status.c_str());
    ui.endPanel();
    ++shown;
    cv::Mat shot;
    ui.endFrame(last && !f.screenshot.empty() ? &shot : nullptr);
    if (last) {
      if (!f.screenshot.empty()) writePng(f.screenshot, shot, "mrgi insert");
      break;
    }
  }
  if (unsaved) std::fprintf(stderr, "mrgi: insert window closed without saving; %s unchanged\n", save.c_str());
  json report = in.report();  // the placement as the window left it
  report["saved"] = !unsaved;
  std::printf("%s\n", jsonText(report, f.o.session).c_str());
  return 0;
}

int runInsert(InsertFlags& f) {
  checkReplaceable(f.preview, "--preview", "mrgi insert");
  checkReplaceable(f.screenshot, "--screenshot", "mrgi insert");
  SnapUp up;
  if (f.up == "marker") {
    up.kind = SnapUp::Kind::Marker;
  } else if (f.up != "camera") {
    up.kind = SnapUp::Kind::Given;
    up.given = vec3(parseNumbers(f.up));  // three finite numbers, checked by the flag's validator
  }
  f.o.translate = vec3(f.translate), f.o.rotateDeg = vec3(f.rotateDeg), f.o.albedo = vec3(f.albedo);
  const gl::Backend backend = gl::parseBackend(f.gl);
  const bool window = backend == gl::Backend::Window;
  if (up.kind == SnapUp::Kind::Given && (f.snap || window) && cv::norm(up.given) < 1e-9)
    throw FlagError("--up", "must not be the zero vector");
  Insertion in(f.o, [&](int width, int height) {
    gl::ContextConfig cfg;
    cfg.backend = backend;
    const cv::Size win = WindowUi::windowSize(width, height);
    cfg.width = window ? win.width : width;
    cfg.height = window ? win.height : height;
    cfg.title = "mrgi insert: " + f.o.session;
    return cfg;
  });
  if (!f.at.empty())
    if (const auto note =
            in.placeAtPixel(static_cast<int>(std::lround(f.at[0])), static_cast<int>(std::lround(f.at[1]))))
      std::fprintf(stderr, "note: %s\n", note->c_str());
  if (f.snap)
    if (const auto why = in.snap(up)) throw capture::CaptureError(f.o.session, *why);
  if (window) return interactive(f, in, up);
  json report = in.report();
  if (!f.preview.empty()) {
    writePng(f.preview, in.render(), "mrgi insert");
    report["preview"] = f.preview;
  }
  in.save();
  std::printf("%s\n", jsonText(report, f.o.session).c_str());
  return 0;
}

}  // namespace

Action addInsert(CLI::App& app) {
  auto f = std::make_shared<InsertFlags>();
  InsertOptions* o = &f->o;
  app.add_option("--session", o->session, "session (or TUM / Open3D folder / .oni) whose marker anchors the object")
      ->required();
  app.add_option("--model", o->model, "model file: OBJ, PLY or glTF")->required();
  app.add_option("--translate", f->translate, "x,y,z in metres in the marker frame")
      ->delimiter(',')
      ->expected(3)
      ->check(numberIn(lighting::kObjectTranslateM.lo, lighting::kObjectTranslateM.hi));
  app.add_option("--rotate-deg", f->rotateDeg, "x,y,z rotation in degrees about the marker axes (x, then y, then z)")
      ->delimiter(',')
      ->expected(3)
      ->check(numberIn(lighting::kObjectRotateDeg.lo, lighting::kObjectRotateDeg.hi));
  app.add_option("--scale", o->scale, "uniform scale of the model")
      ->check(numberIn(lighting::kObjectScale.lo, lighting::kObjectScale.hi));
  app.add_option("--albedo", f->albedo, "r,g,b diffuse albedo in [0, 1]")
      ->delimiter(',')
      ->expected(3)
      ->check(numberIn(lighting::kAlbedo.lo, lighting::kAlbedo.hi));
  app.add_option("--scene", o->scene,
                 "base scene file (lights, technique, other objects); default: --save if it exists");
  app.add_option("--room", o->room, "room model (from mrgi room) as the real scene of the preview's lighting");
  app.add_option("--save", o->save, "scene file to write (written atomically; existing objects are kept)")->required();
  app.add_option("--replace", o->replace, "replace object N of the base scene instead of appending")
      ->check(numberIn(0, 1e6));
  app.add_option("--at", f->at,
                 "u,v: put the object's origin on the surface seen at this pixel (overrides --translate)")
      ->delimiter(',')
      ->expected(2);
  app.add_flag("--snap", f->snap, "rest the object on the plane below it (planes from the frame's depth)");
  addPoseOption(app, o->pose);
  addFolderCalibration(app, o->open);
  app.add_option(
         "--up", f->up,
         "up direction for --snap: camera (image up, default), marker (tag normal) or x,y,z in the marker frame")
      ->check(numberList(3, -1e6, 1e6, {"camera", "marker"}));
  app.add_option("--frame", o->frame, "frame of the session to measure and preview on")->check(numberIn(0, 1e9));
  app.add_option("--preview", f->preview, "write the composite of that frame with the placed object (PNG)");
  app.add_option("--gl", f->gl, "GL backend: osmesa (default), egl, window (interactive: sliders, snap, save)")
      ->check(CLI::IsMember({"osmesa", "egl", "window"}));
  app.add_option("--frames", f->frames, "--gl window: close after N frames, saving the placement (scripted runs)")
      ->check(numberIn(0, 1e9));
  app.add_option("--screenshot", f->screenshot, "--gl window with --frames: save the window's last frame (PNG)");
  return [f] { return runInsert(*f); };
}

}  // namespace mrgi::app
