// mrgi insert: place a virtual object relative to the marker (flags, optional snap onto the support plane
// from depth), preview the composite, and save the placement into a scene file replay and live read.
#include <imgui.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <sstream>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "app/window_ui.h"
#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"
#include "capture/session.h"
#include "gl/context.h"
#include "reconstruction/plane.h"
#include "runtime/debug_view.h"
#include "runtime/frame_pipeline.h"
#include "runtime/output.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::app {
namespace {

struct InsertOptions {
  std::string session;
  std::string model;
  std::vector<double> translate{0, 0, 0};
  std::vector<double> rotateDeg{0, 0, 0};
  double scale = 1.0;
  std::vector<double> albedo{0.8, 0.8, 0.8};
  std::string scene;  // base scene (lights, technique); default: --save if it exists
  std::string room;   // mrgi room output: the real scene of the preview's lighting
  std::string save;
  int replace = -1;
  bool snap = false;
  std::string up = "camera";
  PoseMode pose = PoseMode::Tracked;
  int64_t frame = 0;
  std::vector<double> at;  // pixel u,v: translate = the surface point seen there
  std::string preview;
  std::string gl = "osmesa";
  int frames = 0;          ///< window: close after N UI frames (scripted runs, tests)
  std::string screenshot;  ///< window: save its last frame
};

json readJson(const std::string& path) {
  const std::string text = capture::readFileBounded(path, capture::kMaxTextFileBytes, "scene file");
  lighting::parseScene(text, path);  // validates with key-named errors
  return capture::parseJson(text, path);
}

/// Euler angles (degrees) of R = Rz Ry Rx, the scene file's rotate_deg convention.
cv::Vec3d eulerDeg(const cv::Matx33d& R) {
  const double r2d = 180.0 / CV_PI;
  const double sy = std::clamp(-R(2, 0), -1.0, 1.0);
  const double b = std::asin(sy);
  double a, c;
  if (std::abs(sy) < 1 - 1e-9) {
    a = std::atan2(R(2, 1), R(2, 2));
    c = std::atan2(R(1, 0), R(0, 0));
  } else {  // gimbal lock: x and z turn about the same axis
    a = 0;
    c = std::atan2(-R(0, 1), R(1, 1));
  }
  return {a * r2d, b * r2d, c * r2d};
}

json vec(const cv::Vec3d& v, double round = 1e-6) {
  json a = json::array();
  for (int i = 0; i < 3; ++i) a.push_back(std::round(v[i] / round) * round + 0.0);
  return a;
}

/// Writes the scene file atomically (runInsert created its folder before resolving model paths).
void saveScene(const std::string& path, const json& doc) { capture::writeFileAtomically(path, doc.dump(2) + "\n"); }

/// The window: sliders move, turn and scale the object, the composite follows when a slider is let go;
/// "snap" rests it on the table, "save" writes the scene file (so does closing after --frames N).
int interactive(const InsertOptions& o, std::unique_ptr<gl::Context>& context, json& doc, size_t index,
                const std::string& savePath, const LightingSetup& base, const FrameOptions& frameOptions,
                const capture::Frame& frame, const FrameResult& measured, const std::function<bool(std::string*)>& snap,
                json& report) {
  WindowUi ui(*context);
  const int width = frame.rgbd->colour.cols, height = frame.rgbd->colour.rows;
  compositor::Compositor compositor(width, height);
  json& obj = doc["objects"][index];
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
  auto save = [&] {
    saveScene(o.save, doc);
    unsaved = false;
    status = "saved " + o.save;
  };
  while (!InterruptGuard::interrupted() && ui.beginFrame()) {
    if (dirty) {
      // Re-read the edited scene (scale is baked into the mesh) and render the measured frame again.
      LightingSetup setup = base;
      setup.scene = lighting::parseScene(doc.dump(), savePath);
      FramePipeline fp(setup, width, height, frameOptions);
      gl::Profiler profiler;
      FrameResult r = measured;
      fp.render(frame, r, compositor, profiler);
      view = r.composite.clone();
      drawMarkerAxes(view, frame.rgbd->colourIntrinsics, *r.T_marker_camera, setup.tagSize);
      dirty = false;
    }
    ui.showImage(view, "object " + std::to_string(index) + " of " + o.save + (unsaved ? " (unsaved)" : ""));
    ui.beginPanel("mrgi insert");
    ImGui::TextWrapped("%s", o.model.c_str());
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
      std::string why;
      if (snap(&why)) {
        get3("translate", t, 0.0);
        get3("rotate_deg", r, 0.0);
        dirty = unsaved = true;
        status = "resting on the plane below";
      } else {
        status = why;
      }
    }
    ImGui::SameLine();
    if (ImGui::Button("save")) save();
    ImGui::TextWrapped("%s", status.c_str());
    ui.endPanel();
    const bool done = o.frames > 0 && ++shown >= o.frames;
    cv::Mat shot;
    ui.endFrame(done && !o.screenshot.empty() ? &shot : nullptr);
    if (done) {
      if (!o.screenshot.empty()) writePng(o.screenshot, shot, "mrgi insert");
      save();
      break;
    }
  }
  if (unsaved) std::fprintf(stderr, "mrgi: insert window closed without saving; %s unchanged\n", o.save.c_str());
  report["translate"] = obj["translate"];
  report["rotate_deg"] = obj["rotate_deg"];
  report["saved"] = !unsaved;
  std::printf("%s\n", jsonText(report, o.session).c_str());
  return 0;
}

int runInsert(const InsertOptions& o) {
  checkReplaceable(o.preview, "--preview", "mrgi insert");
  checkReplaceable(o.screenshot, "--screenshot", "mrgi insert");
  auto source = capture::open(o.session);
  if (!source->info().hasRgbd) throw capture::CaptureError(o.session, "has no RGB-D frames");
  const capture::SessionManifest* manifest = source->sessionManifest();

  // The document to extend: --scene, else the existing --save file, else a new scene whose lights come from
  // the session (fisheye estimate or ground truth).
  json doc;
  const std::string basePath = !o.scene.empty() ? o.scene : (fs::exists(o.save) ? o.save : std::string());
  if (!basePath.empty()) {
    doc = readJson(basePath);
    // Models in the base are relative to it; rewrite them relative to the file we save.
    if (doc.contains("objects"))
      for (auto& obj : doc["objects"]) {
        fs::path m = obj["model"].get<std::string>();
        if (m.is_relative()) m = fs::absolute(fs::path(basePath).parent_path() / m);
        obj["model"] = fs::proximate(m, fs::absolute(fs::path(o.save).parent_path())).generic_string();
      }
  } else {
    doc = json::object();
    if (manifest && manifest->fisheye)
      doc["lights"] = "fisheye";
    else if (manifest && manifest->truth.listsLights)
      doc["lights"] = "manifest";
    else if (!o.room.empty())
      doc["lights"] = "room";
    else
      throw capture::CaptureError(
          o.session, "has neither a fisheye camera nor ground-truth lights; pass --scene with lights or --room");
  }
  if (!doc.contains("objects")) doc["objects"] = json::array();
  if (o.replace >= static_cast<int>(doc["objects"].size()))
    throw std::invalid_argument("--replace " + std::to_string(o.replace) + ": the scene has only " +
                                std::to_string(doc["objects"].size()) + " objects");
  if (!fs::exists(o.model)) throw capture::CaptureError(o.model, "model file not found");
  json object = {
      {"model", fs::proximate(fs::absolute(o.model), fs::absolute(fs::path(o.save).parent_path())).generic_string()},
      {"translate", o.translate},
      {"rotate_deg", o.rotateDeg},
      {"scale", o.scale},
      {"material", {{"albedo", o.albedo}}}};
  const size_t index = o.replace >= 0 ? static_cast<size_t>(o.replace) : doc["objects"].size();
  if (o.replace >= 0)
    doc["objects"][index] = object;
  else
    doc["objects"].push_back(object);
  // Parse as if saved already (model paths resolve against the save folder); bad input stops here.
  createParentDirectory(o.save);  // model paths relative to it must resolve
  const std::string savePath = fs::absolute(o.save).string();
  lighting::SceneDescription scene = lighting::parseScene(doc.dump(), savePath);

  // The frame to measure and preview on.
  const capture::SourceInfo& info = source->info();
  const int width = info.colourIntrinsics.width, height = info.colourIntrinsics.height;
  LightingSetup setup = prepareLighting(scene, savePath, *source, o.session, o.pose, !o.room.empty());
  FrameOptions frameOptions;
  frameOptions.pose = o.pose;
  if (!o.room.empty())
    frameOptions.room = std::make_shared<const reconstruction::RoomMesh>(reconstruction::loadRoom(o.room));
  gl::ContextConfig cfg;
  cfg.backend = gl::parseBackend(o.gl);
  const bool window = cfg.backend == gl::Backend::Window;
  const cv::Size win = WindowUi::windowSize(width, height);
  cfg.width = window ? win.width : width;
  cfg.height = window ? win.height : height;
  cfg.title = "mrgi insert: " + o.session;
  auto context = gl::createContext(cfg);
  compositor::Compositor compositor(width, height);
  gl::Profiler profiler;
  FramePipeline frames(setup, width, height, frameOptions);
  std::optional<capture::Frame> frame;
  FrameResult result;
  for (int64_t i = 0; i <= o.frame; ++i) {
    frame = source->next();
    if (!frame) throw capture::CaptureError(o.session, "has no frame " + std::to_string(o.frame));
    // Odometry carries the pose frame to frame: every frame before the chosen one is tracked too.
    if (i < o.frame && (o.pose == PoseMode::Marker || o.pose == PoseMode::GroundTruth)) continue;
    result = frames.measure(*frame, profiler);
  }
  if (!result.T_marker_camera)
    throw capture::CaptureError(o.session, "frame " + std::to_string(o.frame) + " has no camera pose (--pose " +
                                               toString(o.pose) + "; marker " + setup.tagFamily +
                                               (setup.tagId >= 0 ? " id " + std::to_string(setup.tagId) : "") +
                                               " not found)");

  // A recording without a marker: its first frame founded the world; the scene records it so that replay
  // places the objects in the same world.
  if (const auto world = frames.poses() ? frames.poses()->foundedWorld() : std::nullopt) {
    json m = json::array();
    for (double v : world->val) m.push_back(v);
    doc["world"] = {{"first_frame_T_world_camera", m}};
  }
  lighting::VirtualObject& obj = scene.objects[index];
  json report = {{"scene", o.save}, {"object", index}};
  report["pose"] = result.pose.facts();
  if (!o.at.empty()) {
    const int u = static_cast<int>(std::lround(o.at[0])), v = static_cast<int>(std::lround(o.at[1]));
    if (u < 0 || v < 0 || u >= width || v >= height)
      throw std::invalid_argument("--at " + std::to_string(u) + "," + std::to_string(v) + ": outside the " +
                                  std::to_string(width) + "x" + std::to_string(height) + " image");
    const cv::Vec3f p = result.positions.at<cv::Vec3f>(v, u);
    if (!(p[2] > 0))
      throw capture::CaptureError(o.session, "frame " + std::to_string(o.frame) + ": no depth at pixel " +
                                                 std::to_string(u) + "," + std::to_string(v));
    const cv::Vec3d t = capture::transformPoint(*result.T_marker_camera, cv::Vec3d(p));
    obj.T_marker_object = capture::makePose(capture::rotationOf(obj.T_marker_object), t);
    doc["objects"][index]["translate"] = vec(t);
    frames.lighting()->setObjectTransform(index, obj.T_marker_object);
  }
  // Rests the object on the plane below it (planes from the frame's depth); false when there is none.
  auto snap = [&](std::string* why) {
    obj = lighting::parseScene(doc.dump(), savePath).objects[index];  // the placement as edited so far
    cv::Mat labels;
    const auto planes = reconstruction::findPlanes(result.positions, result.normals, {}, &labels);
    const capture::Pose& T_marker_camera = *result.T_marker_camera;
    std::vector<reconstruction::Plane> inMarker;
    for (const auto& p : planes) inMarker.push_back(reconstruction::transformPlane(p, T_marker_camera));
    cv::Vec3d up;
    if (o.up == "camera") {
      up = capture::rotationOf(T_marker_camera) * cv::Vec3d(0, -1, 0);
    } else if (o.up == "marker") {
      up = {0, 0, 1};
    } else {
      const std::vector<double> v = parseNumbers(o.up);  // three finite numbers, checked by the flag's validator
      up = {v[0], v[1], v[2]};
      if (cv::norm(up) < 1e-9) throw FlagError("--up", "must not be the zero vector");
    }
    const auto plane =
        reconstruction::supportPlane(inMarker, capture::translationOf(obj.T_marker_object), up, labels,
                                     capture::inversePose(T_marker_camera), frame->rgbd->colourIntrinsics);
    if (!plane) {
      *why = "frame " + std::to_string(o.frame) + ": no support plane below the object (" +
             std::to_string(planes.size()) + " planes found; try --up)";
      return false;
    }
    obj.T_marker_object = reconstruction::restOnPlane(obj.T_marker_object, obj.mesh.positions, *plane);
    doc["objects"][index]["translate"] = vec(capture::translationOf(obj.T_marker_object));
    doc["objects"][index]["rotate_deg"] = vec(eulerDeg(capture::rotationOf(obj.T_marker_object)), 1e-4);
    report["plane"] = {{"normal", vec(plane->normal)}, {"d", plane->d}, {"pixels", plane->inliers}};
    frames.lighting()->setObjectTransform(index, obj.T_marker_object);
    return true;
  };
  if (o.snap) {
    std::string why;
    if (!snap(&why)) throw capture::CaptureError(o.session, why);
  }
  report["translate"] = doc["objects"][index]["translate"];
  report["rotate_deg"] = doc["objects"][index]["rotate_deg"];

  if (window)
    return interactive(o, context, doc, index, savePath, *frames.setup(), frameOptions, *frame, result, snap, report);
  if (!o.preview.empty()) {
    frames.render(*frame, result, compositor, profiler);
    writePng(o.preview, result.composite, "mrgi insert");
    report["preview"] = o.preview;
  }
  saveScene(o.save, doc);
  std::printf("%s\n", jsonText(report, o.session).c_str());
  return 0;
}

}  // namespace

Action addInsert(CLI::App& app) {
  auto o = std::make_shared<InsertOptions>();
  app.add_option("--session", o->session, "session (or TUM / .oni) whose marker anchors the object")->required();
  app.add_option("--model", o->model, "model file: OBJ, PLY or glTF")->required();
  app.add_option("--translate", o->translate, "x,y,z in metres in the marker frame")
      ->delimiter(',')
      ->expected(3)
      ->check(numberIn(lighting::kObjectTranslateM.lo, lighting::kObjectTranslateM.hi));
  app.add_option("--rotate-deg", o->rotateDeg, "x,y,z rotation in degrees about the marker axes (x, then y, then z)")
      ->delimiter(',')
      ->expected(3)
      ->check(numberIn(lighting::kObjectRotateDeg.lo, lighting::kObjectRotateDeg.hi));
  app.add_option("--scale", o->scale, "uniform scale of the model")
      ->check(numberIn(lighting::kObjectScale.lo, lighting::kObjectScale.hi));
  app.add_option("--albedo", o->albedo, "r,g,b diffuse albedo in [0, 1]")
      ->delimiter(',')
      ->expected(3)
      ->check(numberIn(lighting::kAlbedo.lo, lighting::kAlbedo.hi));
  app.add_option("--scene", o->scene,
                 "base scene file (lights, technique, other objects); default: --save if it exists");
  app.add_option("--room", o->room, "room model (from mrgi room) as the real scene of the preview's lighting");
  app.add_option("--save", o->save, "scene file to write (written atomically; existing objects are kept)")->required();
  app.add_option("--replace", o->replace, "replace object N of the base scene instead of appending")
      ->check(numberIn(0, 1e6));
  app.add_option("--at", o->at,
                 "u,v: put the object's origin on the surface seen at this pixel (overrides --translate)")
      ->delimiter(',')
      ->expected(2);
  app.add_flag("--snap", o->snap, "rest the object on the plane below it (planes from the frame's depth)");
  addPoseOption(app, o->pose);
  app.add_option(
         "--up", o->up,
         "up direction for --snap: camera (image up, default), marker (tag normal) or x,y,z in the marker frame")
      ->check(numberList(3, -1e6, 1e6, {"camera", "marker"}));
  app.add_option("--frame", o->frame, "frame of the session to measure and preview on")->check(numberIn(0, 1e9));
  app.add_option("--preview", o->preview, "write the composite of that frame with the placed object (PNG)");
  app.add_option("--gl", o->gl, "GL backend: osmesa (default), egl, window (interactive: sliders, snap, save)")
      ->check(CLI::IsMember({"osmesa", "egl", "window"}));
  app.add_option("--frames", o->frames, "--gl window: close after N frames, saving the placement (scripted runs)")
      ->check(numberIn(0, 1e9));
  app.add_option("--screenshot", o->screenshot, "--gl window with --frames: save the window's last frame (PNG)");
  return [o] { return runInsert(*o); };
}

}  // namespace mrgi::app
