#include "runtime/insert.h"

#include <cmath>
#include <filesystem>

#include "capture/error.h"
#include "capture/session.h"
#include "lighting/scene_file.h"
#include "reconstruction/plane.h"
#include "runtime/output.h"
#include "runtime/room_fusion.h"
#include "runtime/source.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::runtime {
namespace {

json vec(const cv::Vec3d& v, double round = 1e-6) {
  json a = json::array();
  for (int i = 0; i < 3; ++i) a.push_back(std::round(v[i] / round) * round + 0.0);
  return a;
}

/// The document to extend: `scene`, else the existing save file, else a new scene whose lights come from the
/// session (fisheye estimate or ground truth) or the room.
json baseDocument(const InsertOptions& o, const capture::SessionManifest* manifest) {
  const std::string basePath = !o.scene.empty() ? o.scene : (fs::exists(o.save) ? o.save : std::string());
  if (!basePath.empty()) {
    json doc = lighting::readSceneDocument(basePath);
    // Models in the base are relative to it; rewrite them relative to the file we save.
    lighting::rebaseModelPaths(doc, basePath, o.save);
    return doc;
  }
  json doc = json::object();
  if (manifest && manifest->fisheye)
    doc["lights"] = "fisheye";
  else if (manifest && manifest->truth.listsLights)
    doc["lights"] = "manifest";
  else if (!o.room.empty())
    doc["lights"] = "room";
  else
    doc["lights"] = "auto";  // lit from the room fused from the recording (replay fuses it as the frames come)
  return doc;
}

json toJson(const cv::Vec3d& v) { return {v[0], v[1], v[2]}; }

}  // namespace

Insertion::Insertion(const InsertOptions& o, const std::function<gl::ContextConfig(int, int)>& contextFor) : o_(o) {
  source_ = openSource(o.session, o.open);
  if (!source_->info().hasRgbd) throw capture::CaptureError(o.session, "has no RGB-D frames");
  doc_ = baseDocument(o, source_->sessionManifest());
  if (!doc_.contains("objects")) doc_["objects"] = json::array();
  if (o.replace >= static_cast<int>(doc_["objects"].size()))
    throw std::invalid_argument("--replace " + std::to_string(o.replace) + ": the scene has only " +
                                std::to_string(doc_["objects"].size()) + " objects");
  if (!fs::exists(o.model)) throw capture::CaptureError(o.model, "model file not found");
  const json object = {
      {"model", fs::proximate(fs::absolute(o.model), fs::absolute(o.save).parent_path()).generic_string()},
      {"translate", toJson(o.translate)},
      {"rotate_deg", toJson(o.rotateDeg)},
      {"scale", o.scale},
      {"material", {{"albedo", toJson(o.albedo)}}}};
  index_ = o.replace >= 0 ? static_cast<size_t>(o.replace) : doc_["objects"].size();
  if (o.replace >= 0)
    doc_["objects"][index_] = object;
  else
    doc_["objects"].push_back(object);
  // Parse as if saved already (model paths resolve against the save folder); bad input stops here.
  createParentDirectory(o.save);  // model paths relative to it must resolve
  savePath_ = fs::absolute(o.save).string();
  scene_ = lighting::parseScene(doc_.dump(), savePath_);

  // The frame to measure and preview on.
  const int width = source_->info().colourIntrinsics.width, height = source_->info().colourIntrinsics.height;
  LightingSetup setup = prepareLighting(scene_, savePath_, *source_, o.session, o.pose, !o.room.empty());
  frameOptions_.pose = o.pose;
  if (!o.room.empty())
    frameOptions_.room = std::make_shared<const reconstruction::RoomMesh>(reconstruction::loadRoom(o.room));
  if (setup.lightsFromFusedRoom) {
    // The preview is lit as replay will light it by its end: from the room of every frame. The fusion reads the
    // recording itself (a device's recording plays once at a time): the frame is read after it.
    source_.reset();
    frameOptions_.room = fuseWholeRecording(o.session, o.pose, o.open);
    source_ = openSource(o.session, o.open);
  }
  context_ = gl::createContext(contextFor(width, height));
  compositor_ = std::make_unique<compositor::Compositor>(width, height);
  frames_ = std::make_unique<FramePipeline>(setup, width, height, frameOptions_);
  gl::Profiler profiler;
  for (int64_t i = 0; i <= o.frame; ++i) {
    frame_ = source_->next();
    if (!frame_) throw capture::CaptureError(o.session, "has no frame " + std::to_string(o.frame));
    // Odometry carries the pose frame to frame: every frame before the chosen one is tracked too.
    if (i < o.frame && (o.pose == PoseMode::Marker || o.pose == PoseMode::GroundTruth)) continue;
    result_ = frames_->measure(*frame_, profiler);
  }
  if (!result_.T_marker_camera)
    throw capture::CaptureError(
        o.session, "frame " + std::to_string(o.frame) + " has no camera pose (--pose " + toString(o.pose) +
                       "; marker " + setup.tagFamily +
                       (setup.tagId >= 0 ? " id " + std::to_string(setup.tagId) : " of any id") + " not found)");
  // A recording without a marker: its first frame founded the world; the scene records it so that replay
  // places the objects in the same world.
  if (const auto world = frames_->poses() ? frames_->poses()->foundedWorld() : std::nullopt) {
    json m = json::array();
    for (double v : world->val) m.push_back(v);
    doc_["world"] = {{"first_frame_T_world_camera", m}};
  }
  facts_ = {{"scene", o.save}, {"object", index_}, {"pose", result_.pose.facts()}};
}

json Insertion::report() const {
  json r = facts_;
  const json& placed = doc_["objects"][index_];
  r["translate"] = placed["translate"];
  r["rotate_deg"] = placed["rotate_deg"];
  return r;
}

std::optional<std::string> Insertion::placeAtPixel(int u, int v) {
  const int width = result_.positions.cols, height = result_.positions.rows;
  if (u < 0 || v < 0 || u >= width || v >= height)
    throw std::invalid_argument("--at " + std::to_string(u) + "," + std::to_string(v) + ": outside the " +
                                std::to_string(width) + "x" + std::to_string(height) + " image");
  std::optional<std::string> note;
  cv::Vec3f p = result_.positions.at<cv::Vec3f>(v, u);
  if (!(p[2] > 0)) {
    // Where there is depth instead: the nearest pixel with it, and how much of the frame has it.
    long best = -1, with = 0;
    int bu = 0, bv = 0;
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        if (!(result_.positions.at<cv::Vec3f>(y, x)[2] > 0)) continue;
        ++with;
        const long d = static_cast<long>(x - u) * (x - u) + static_cast<long>(y - v) * (y - v);
        if (best < 0 || d < best) best = d, bu = x, bv = y;
      }
    const std::string at = std::to_string(u) + "," + std::to_string(v);
    const std::string nearest = std::to_string(bu) + "," + std::to_string(bv);
    if (best < 0 || best > kNearestDepthPixels * kNearestDepthPixels) {
      const std::string where =
          best < 0 ? "the frame has no depth at all"
                   : "the nearest pixel with depth is " + nearest + "; " +
                         std::to_string(static_cast<int>(100.0 * static_cast<double>(with) / (width * height))) +
                         " % of the frame has depth";
      throw capture::CaptureError(
          o_.session, "frame " + std::to_string(o_.frame) + ": no depth at pixel " + at + " (" + where + ")");
    }
    // A hole in the depth a few pixels wide (an edge, a dark patch): the nearest pixel with depth stands in.
    p = result_.positions.at<cv::Vec3f>(bv, bu);
    note = "frame " + std::to_string(o_.frame) + ": no depth at pixel " + at + "; placed at " + nearest +
           ", the nearest pixel with depth";
    facts_["at"] = {bu, bv};
  }
  lighting::VirtualObject& obj = scene_.objects[index_];
  const cv::Vec3d t = capture::transformPoint(*result_.T_marker_camera, cv::Vec3d(p));
  obj.T_marker_object = capture::makePose(capture::rotationOf(obj.T_marker_object), t);
  doc_["objects"][index_]["translate"] = vec(t);
  frames_->lighting()->setObjectTransform(index_, obj.T_marker_object);
  return note;
}

std::optional<std::string> Insertion::snap(const SnapUp& upChoice) {
  lighting::VirtualObject& obj = scene_.objects[index_];
  obj = lighting::parseScene(doc_.dump(), savePath_).objects[index_];  // the placement as edited so far
  cv::Mat labels;
  const auto planes = reconstruction::findPlanes(result_.positions, result_.normals, {}, &labels);
  const capture::Pose& T_marker_camera = *result_.T_marker_camera;
  std::vector<reconstruction::Plane> inMarker;
  for (const auto& p : planes) inMarker.push_back(reconstruction::transformPlane(p, T_marker_camera));
  const cv::Vec3d up = upChoice.kind == SnapUp::Kind::Camera
                           ? capture::rotationOf(T_marker_camera) * cv::Vec3d(0, -1, 0)
                       : upChoice.kind == SnapUp::Kind::Marker ? cv::Vec3d(0, 0, 1)
                                                               : upChoice.given;
  const auto plane =
      reconstruction::supportPlane(inMarker, capture::translationOf(obj.T_marker_object), up, labels,
                                   capture::inversePose(T_marker_camera), frame_->rgbd->colourIntrinsics);
  if (!plane)
    return "frame " + std::to_string(o_.frame) + ": no support plane below the object (" +
           std::to_string(planes.size()) + " planes found; try --up)";
  obj.T_marker_object = reconstruction::restOnPlane(obj.T_marker_object, obj.mesh.positions, *plane);
  doc_["objects"][index_]["translate"] = vec(capture::translationOf(obj.T_marker_object));
  doc_["objects"][index_]["rotate_deg"] = vec(lighting::eulerDegrees(capture::rotationOf(obj.T_marker_object)), 1e-4);
  facts_["plane"] = {{"normal", vec(plane->normal)}, {"d", plane->d}, {"pixels", plane->inliers}};
  frames_->lighting()->setObjectTransform(index_, obj.T_marker_object);
  return std::nullopt;
}

cv::Mat Insertion::render(const std::optional<json>& edited) {
  gl::Profiler profiler;
  // Lights from the room are seen from the objects where they now are (placed after the pipeline was built):
  // the scene as placed is rendered by a pipeline of its own, as replay will render it.
  const std::optional<json> scene =
      edited ? edited
             : (frames_->setup()->scene.lightSource == lighting::LightSource::Room ? std::optional<json>(doc_)
                                                                                   : std::nullopt);
  if (!scene) {
    frames_->render(*frame_, result_, *compositor_, profiler);
    return result_.composite;
  }
  // Re-read the edited scene (scale is baked into the mesh) and render the measured frame again.
  LightingSetup setup = *frames_->setup();
  setup.useEditedScene(lighting::parseScene(scene->dump(), savePath_));
  FramePipeline fp(setup, result_.positions.cols, result_.positions.rows, frameOptions_);
  FrameResult r = result_;
  fp.render(*frame_, r, *compositor_, profiler);
  return r.composite.clone();
}

void Insertion::save() const { lighting::writeSceneDocument(o_.save, doc_); }

}  // namespace mrgi::runtime
