#include "lighting/scene_file.h"

#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <set>
#include <sstream>

#include "capture/checks.h"
#include "capture/image_io.h"
#include "capture/json_io.h"
#include "capture/ply_check.h"
#include "capture/types.h"
#include "lighting/techniques/registry.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::lighting {

void Mesh::computeBounds() {
  if (positions.empty()) {
    boundsMin = boundsMax = {0, 0, 0};
    return;
  }
  boundsMin = boundsMax = positions[0];
  for (const auto& p : positions)
    for (int k = 0; k < 3; ++k) {
      boundsMin[k] = std::min(boundsMin[k], p[k]);
      boundsMax[k] = std::max(boundsMax[k], p[k]);
    }
}

namespace {

void appendNode(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent, Mesh& out) {
  const aiMatrix4x4 m = parent * node->mTransformation;
  aiMatrix3x3 nm(m);
  nm.Inverse().Transpose();
  for (unsigned i = 0; i < node->mNumMeshes; ++i) {
    const aiMesh* mesh = scene->mMeshes[node->mMeshes[i]];
    if (!(mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    const auto base = static_cast<uint32_t>(out.positions.size());
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D p = m * mesh->mVertices[v];
      aiVector3D n = mesh->mNormals ? nm * mesh->mNormals[v] : aiVector3D(0, 0, 1);
      n.Normalize();
      out.positions.emplace_back(p.x, p.y, p.z);
      out.normals.emplace_back(n.x, n.y, n.z);
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;
      for (int k = 0; k < 3; ++k) out.indices.push_back(base + face.mIndices[k]);
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) appendNode(scene, node->mChildren[c], m, out);
}

}  // namespace

namespace {

/// The content must be what the extension says, in the way assimp's reader for that format recognises it:
/// when that reader declines a file, assimp tries every other reader on it (its PLY reader claims any file
/// with "ply" near the start, whatever the name, and loops forever on some; found by the model fuzzer).
void checkModelContent(const std::string& path, const std::string& ext) {
  std::ifstream in(path, std::ios::binary);
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  std::string lower = head;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower.rfind("ply", 0) == 0 && ext != ".ply") throw SceneError(path, "holds a PLY file but is named " + ext);
  if (ext == ".glb") {
    if (head.size() < 12 || head.compare(0, 4, "glTF") != 0 || head[4] != 2 || head[5] != 0 || head[6] != 0 ||
        head[7] != 0)
      throw SceneError(path, "not a binary glTF 2 file (no 'glTF' header of version 2)");
  } else if (ext == ".gltf") {
    // Parsed here with our depth bound (assimp's JSON reader recurses without one), then its asset version.
    const nlohmann::json j =
        capture::parseJson(capture::readFileBounded(path, capture::kMaxTextFileBytes, "glTF file"), path);
    if (!j.is_object() || !j.contains("asset") || !j["asset"].is_object() || !j["asset"].contains("version") ||
        !j["asset"]["version"].is_string() || j["asset"]["version"].get<std::string>().rfind("2", 0) != 0)
      throw SceneError(path, "not a glTF 2 file (asset.version \"2.x\" missing)");
  } else if (ext == ".obj") {
    // assimp's OBJ reader claims a file by one of these tokens in its first 200 bytes.
    static const char* kTokens[] = {"mtllib", "usemtl", "v ", "vt ", "vn ", "o ", "g ", "s ", "f "};
    const std::string first = lower.substr(0, 200);
    bool found = false;
    for (const char* t : kTokens) found |= first.find(t) != std::string::npos;
    if (!found) throw SceneError(path, "not an OBJ file (no vertex, face or group statement near the start)");
  }
}

}  // namespace

Mesh loadMesh(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw SceneError(path, "model file not found");
  capture::checkFileBounded(path, capture::kMaxBinaryFileBytes, "model");
  // The formats we name, by extension, so that assimp picks its reader by name and never by guessing
  // from the content (its PLY reader claims any file with "ply" near the start).
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".obj" && ext != ".ply" && ext != ".gltf" && ext != ".glb")
    throw SceneError(path, "model format must be OBJ, PLY or glTF (.obj, .ply, .gltf, .glb)");
  checkModelContent(path, ext);
  capture::checkPlyFile(path);
  Assimp::Importer importer;
  // Two steps: the import with assimp's own validation only, then our index check, then the
  // post-processing — which trusts its input (out-of-range or truncated faces crash or abort inside it).
  const aiScene* scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE))
    throw SceneError(path, "cannot read model: " + capture::excerpt(importer.GetErrorString()));
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    if (!mesh || !mesh->mVertices) throw SceneError(path, "model mesh " + std::to_string(m) + " has no vertices");
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      // A face of no vertex passes assimp's validation and aborts its triangulation (ai_assert).
      if (face.mNumIndices == 0 || !face.mIndices)
        throw SceneError(path, "model mesh " + std::to_string(m) + " face " + std::to_string(f) + " has no vertices");
      for (unsigned k = 0; k < face.mNumIndices; ++k)
        if (face.mIndices[k] >= mesh->mNumVertices)
          throw SceneError(path, "model mesh " + std::to_string(m) + " face " + std::to_string(f) +
                                     " refers to vertex " + std::to_string(face.mIndices[k]) + " of " +
                                     std::to_string(mesh->mNumVertices));
    }
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw SceneError(path, "model has a non-finite vertex position");
    }
  }
  scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_GenSmoothNormals |
                                       aiProcess_JoinIdenticalVertices | aiProcess_SortByPType |
                                       aiProcess_PreTransformVertices);
  if (!scene || !scene->mRootNode)
    throw SceneError(path, "cannot read model: " + capture::excerpt(importer.GetErrorString()));
  Mesh mesh;
  appendNode(scene, scene->mRootNode, aiMatrix4x4(), mesh);
  if (mesh.indices.empty()) throw SceneError(path, "model holds no triangles");
  for (const auto& p : mesh.positions)
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw SceneError(path, "model has a non-finite vertex position");
  mesh.computeBounds();
  return mesh;
}

namespace {

/// Walks a JSON document keeping the key path for messages ("objects[0].material.albedo").
class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& problem) const {
    throw SceneError(file_, key + ": " + problem);
  }

  void allowOnly(const json& obj, const std::string& key, const std::set<std::string>& allowed) const {
    if (!obj.is_object()) fail(key.empty() ? "(top level)" : key, "must be an object");
    for (const auto& [k, v] : obj.items())
      if (!allowed.count(k)) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(join(key, k), "unknown key" + capture::didYouMean(k, {allowed.begin(), allowed.end()}) +
                               " (expected one of: " + list + ")");
      }
  }

  static std::string join(const std::string& parent, const std::string& k) {
    return parent.empty() ? k : parent + "." + k;
  }

  double number(const json& v, const std::string& key, double lo, double hi) const {
    if (!v.is_number()) fail(key, "must be a number");
    const double x = v.get<double>();
    const std::string problem = capture::numberProblem(x, lo, hi);
    if (!problem.empty()) fail(key, problem);
    return x;
  }

  int integer(const json& v, const std::string& key, int lo, int hi) const {
    if (!v.is_number_integer()) fail(key, "must be an integer");
    const auto x = v.get<long long>();
    if (x < lo || x > hi)
      fail(key,
           "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], not " + std::to_string(x));
    return static_cast<int>(x);
  }

  cv::Vec3d vec3(const json& v, const std::string& key, double lo, double hi) const {
    if (!v.is_array() || v.size() != 3) fail(key, "must be an array of 3 numbers");
    cv::Vec3d out;
    for (int i = 0; i < 3; ++i) out[i] = number(v[i], key + "[" + std::to_string(i) + "]", lo, hi);
    return out;
  }

  bool boolean(const json& v, const std::string& key) const {
    if (!v.is_boolean()) fail(key, "must be true or false");
    return v.get<bool>();
  }

  std::string string(const json& v, const std::string& key) const {
    if (!v.is_string()) fail(key, "must be a string");
    return v.get<std::string>();
  }

 private:
  std::string file_;
};

cv::Vec3d unit(const cv::Vec3d& v, const Reader& r, const std::string& key) {
  const std::string problem = capture::directionProblem(v);
  if (!problem.empty()) r.fail(key, problem);
  return v / cv::norm(v);
}

}  // namespace

SceneDescription parseScene(const std::string& text, const std::string& path) {
  Reader r(path);
  json doc;
  doc = capture::parseJson(text, path);
  std::set<std::string> topLevel{"objects",
                                 "lights",
                                 "fisheye_light_count",
                                 "room_light_count",
                                 "room_saturated_gain",
                                 "room_white_albedo",
                                 "ambient_radiance",
                                 "technique",
                                 "world"};
  for (const KnobGroup* g : knobGroups()) topLevel.insert(g->key);
  r.allowOnly(doc, "", topLevel);
  SceneDescription s;
  completeKnobs(s.knobs);
  s.technique = parseTechniqueChoice(defaultTechniqueName(), &s.knobs);
  s.path = path;
  const fs::path base = fs::path(path).parent_path();

  if (doc.contains("objects")) {
    const json& objs = doc["objects"];
    if (!objs.is_array()) r.fail("objects", "must be an array");
    for (size_t i = 0; i < objs.size(); ++i) {
      const std::string key = "objects[" + std::to_string(i) + "]";
      const json& o = objs[i];
      r.allowOnly(o, key, {"model", "translate", "rotate_deg", "scale", "material"});
      if (!o.contains("model")) r.fail(key + ".model", "missing (a path to an OBJ, PLY or glTF file)");
      VirtualObject obj;
      const std::string model = r.string(o["model"], key + ".model");
      obj.model = fs::path(model).is_absolute() ? fs::path(model).lexically_normal().string()
                                                : (base / model).lexically_normal().string();
      const double scale =
          o.contains("scale") ? r.number(o["scale"], key + ".scale", kObjectScale.lo, kObjectScale.hi) : 1.0;
      const cv::Vec3d t = o.contains("translate")
                              ? r.vec3(o["translate"], key + ".translate", kObjectTranslateM.lo, kObjectTranslateM.hi)
                              : cv::Vec3d();
      const cv::Vec3d rd = o.contains("rotate_deg")
                               ? r.vec3(o["rotate_deg"], key + ".rotate_deg", kObjectRotateDeg.lo, kObjectRotateDeg.hi)
                               : cv::Vec3d();
      if (o.contains("material")) {
        const json& m = o["material"];
        const std::string materialKey = key + ".material";
        r.allowOnly(m, materialKey, {"albedo", "roughness", "specular"});
        if (m.contains("albedo"))
          obj.material.albedo = r.vec3(m["albedo"], key + ".material.albedo", kAlbedo.lo, kAlbedo.hi);
        if (m.contains("roughness"))
          obj.material.roughness = static_cast<float>(r.number(m["roughness"], key + ".material.roughness", 0, 1));
        if (m.contains("specular"))
          obj.material.specular = static_cast<float>(r.number(m["specular"], key + ".material.specular", 0, 1));
        if (obj.material.albedo[0] + obj.material.specular > 1.0f ||
            obj.material.albedo[1] + obj.material.specular > 1.0f ||
            obj.material.albedo[2] + obj.material.specular > 1.0f)
          r.fail(materialKey, "albedo + specular exceeds 1 in a channel (the surface would create energy)");
      }
      try {
        obj.mesh = loadMesh(obj.model);
      } catch (const SceneError& e) {
        r.fail(key + ".model", e.what());
      }
      for (auto& p : obj.mesh.positions) p *= static_cast<float>(scale);
      obj.mesh.computeBounds();
      // A model reaching kilometres (3e38 in a file's units) is not an object on a table: every pass that looks
      // from or at it would overflow. Said here, naming the model, before anything is lit.
      const double reach = std::max(cv::norm(cv::Vec3d(obj.mesh.boundsMin), cv::NORM_INF),
                                    cv::norm(cv::Vec3d(obj.mesh.boundsMax), cv::NORM_INF));
      if (!(reach <= capture::kMaxLightPositionM))
        r.fail(key + ".model", obj.model + ": its vertices reach " + capture::formatNumber(reach) +
                                   " m from its origin (scaled by " + capture::formatNumber(scale) + "), more than " +
                                   capture::formatNumber(capture::kMaxLightPositionM) +
                                   " m: check its units or the scale");
      // Rotation: x, then y, then z (extrinsic, degrees), about the marker axes.
      const double d2r = CV_PI / 180.0;
      cv::Matx33d R = cv::Matx33d::eye();
      for (int axis = 0; axis < 3; ++axis) {
        cv::Vec3d rv(0, 0, 0);
        rv[axis] = rd[axis] * d2r;
        cv::Matx33d Ra;
        cv::Rodrigues(rv, Ra);
        R = Ra * R;
      }
      obj.T_marker_object = capture::makePose(R, t);
      s.objects.push_back(std::move(obj));
    }
  }

  if (doc.contains("lights") && !(doc["lights"].is_string() && doc["lights"].get<std::string>() == "auto")) {
    s.lightsGiven = true;
    const json& l = doc["lights"];
    if (l.is_string()) {
      const std::string v = l.get<std::string>();
      if (v != "manifest" && v != "fisheye" && v != "room")
        r.fail("lights", "must be \"auto\", \"manifest\", \"fisheye\", \"room\" or an array of lights");
      s.lightSource = v == "manifest"  ? LightSource::Manifest
                      : v == "fisheye" ? LightSource::Fisheye
                                       : LightSource::Room;
    } else if (l.is_array()) {
      s.lightSource = LightSource::Scene;
      if (l.size() > static_cast<size_t>(capture::kMaxLightCount))
        r.fail("lights", std::to_string(l.size()) + " lights, at most " + std::to_string(capture::kMaxLightCount) +
                             " are supported");
      for (size_t i = 0; i < l.size(); ++i) {
        const std::string key = "lights[" + std::to_string(i) + "]";
        const json& j = l[i];
        r.allowOnly(j, key,
                    {"type", "position", "direction", "intensity", "irradiance", "spot_half_angle_deg", "radius_m",
                     "angular_radius_deg"});
        if (!j.contains("type")) r.fail(key + ".type", "missing (point, spot or directional)");
        const std::string type = r.string(j["type"], key + ".type");
        SceneLight light;
        auto need = [&](const char* k) {
          if (!j.contains(k)) r.fail(key + "." + k, std::string("missing (required for a ") + type + " light)");
          return j[k];
        };
        if (type == "point" || type == "spot") {
          light.type = type == "point" ? LightType::Point : LightType::Spot;
          light.position =
              r.vec3(need("position"), key + ".position", -capture::kMaxLightPositionM, capture::kMaxLightPositionM);
          light.intensity = r.vec3(need("intensity"), key + ".intensity", 0, capture::kMaxLightPower);
          if (j.contains("angular_radius_deg"))
            r.fail(key + ".angular_radius_deg", "is for directional lights (a point or spot light takes radius_m)");
          if (j.contains("radius_m")) light.extent = r.number(j["radius_m"], key + ".radius_m", 0, 10);
          if (light.type == LightType::Spot) {
            light.direction = unit(r.vec3(need("direction"), key + ".direction", -1e3, 1e3), r, key + ".direction");
            if (j.contains("spot_half_angle_deg"))
              light.spotHalfAngleDeg = r.number(j["spot_half_angle_deg"], key + ".spot_half_angle_deg",
                                                capture::kMinSpotHalfAngleDeg, capture::kMaxSpotHalfAngleDeg);
          }
        } else if (type == "directional") {
          light.type = LightType::Directional;
          light.direction = unit(r.vec3(need("direction"), key + ".direction", -1e3, 1e3), r, key + ".direction");
          light.irradiance = r.vec3(need("irradiance"), key + ".irradiance", 0, capture::kMaxLightPower);
          if (j.contains("radius_m"))
            r.fail(key + ".radius_m", "is for point and spot lights (a directional light takes angular_radius_deg)");
          if (j.contains("angular_radius_deg"))
            light.extent = r.number(j["angular_radius_deg"], key + ".angular_radius_deg", 0, 80) * CV_PI / 180;
        } else {
          r.fail(key + ".type", "unknown light type '" + type + "' (expected point, spot or directional)");
        }
        s.lights.push_back(light);
      }
    } else {
      r.fail("lights", "must be \"auto\", \"manifest\", \"fisheye\", \"room\" or an array of lights");
    }
  }
  if (doc.contains("room_light_count"))
    s.roomLightCount = r.integer(doc["room_light_count"], "room_light_count", 1, 16);
  if (doc.contains("room_saturated_gain"))
    s.roomSaturatedGain = r.number(doc["room_saturated_gain"], "room_saturated_gain", 0, 1e4);
  if (doc.contains("room_white_albedo"))
    s.roomWhiteAlbedo = r.number(doc["room_white_albedo"], "room_white_albedo", 0.05, 1);
  if (doc.contains("fisheye_light_count"))
    s.fisheyeLightCount = r.integer(doc["fisheye_light_count"], "fisheye_light_count", 1, 16);
  if (doc.contains("ambient_radiance")) {
    s.ambientRadiance = r.vec3(doc["ambient_radiance"], "ambient_radiance", 0, 1e6);
    s.ambientFromManifest = false;
  }
  if (doc.contains("world")) {
    const json& w = doc["world"];
    r.allowOnly(w, "world", {"first_frame_T_world_camera"});
    const std::string key = "world.first_frame_T_world_camera";
    if (!w.contains("first_frame_T_world_camera")) r.fail(key, "missing");
    const json& m = w["first_frame_T_world_camera"];
    if (!m.is_array() || m.size() != 16) r.fail(key, "must be an array of 16 numbers (row-major 4x4)");
    cv::Matx44d T;
    for (int i = 0; i < 16; ++i)
      T.val[i] = r.number(m[static_cast<size_t>(i)], key + "[" + std::to_string(i) + "]", -1e6, 1e6);
    const cv::Matx33d R = T.get_minor<3, 3>(0, 0);
    if (cv::norm(R.t() * R - cv::Matx33d::eye()) > 1e-4 || std::abs(cv::determinant(R) - 1) > 1e-4 || T(3, 0) != 0 ||
        T(3, 1) != 0 || T(3, 2) != 0 || T(3, 3) != 1)
      r.fail(key, "is not a rigid transform (its rotation must be orthonormal, its last row 0 0 0 1)");
    s.firstFrameT_world_camera = T;
  }
  if (doc.contains("technique")) {
    // The technique first: an alias sets knobs that the knob sections below may still override.
    const json& t = doc["technique"];
    try {
      if (t.is_string()) {
        s.technique = parseTechniqueChoice(t.get<std::string>(), &s.knobs);
      } else if (t.is_object()) {
        r.allowOnly(t, "technique", {"real", "virtual"});
        s.technique =
            parseTechniqueRoles(t.contains("real") ? r.string(t["real"], "technique.real") : "none",
                                t.contains("virtual") ? r.string(t["virtual"], "technique.virtual") : "none", &s.knobs);
      } else {
        r.fail("technique", "must be a technique name or {\"real\": ..., \"virtual\": ...}");
      }
    } catch (const std::invalid_argument& e) {
      r.fail("technique", e.what());
    }
  }
  // Knob sections, one per group (the shared "frame" and each technique's), every value checked against the
  // group's table. The frame's knobs are also read inside a technique's section, where older files have them.
  const KnobGroup& frame = *findKnobGroup("frame");
  const KnobFail fail = [&r](const std::string& key, const std::string& problem) { r.fail(key, problem); };
  for (const KnobGroup* g : knobGroups()) {
    if (!doc.contains(g->key)) continue;
    const json& section = doc[g->key];
    std::set<std::string> allowed;
    for (const KnobInfo& k : g->knobs) allowed.insert(k.name);
    for (const KnobInfo& k : frame.knobs) allowed.insert(k.name);
    r.allowOnly(section, g->key, allowed);
    for (const auto& [name, value] : section.items()) {
      const KnobInfo* k = g->find(name);
      const KnobGroup& owner = k ? *g : frame;
      if (!k) k = frame.find(name);
      s.knobs[owner.key][name] = owner.read(*k, value, g->key + "." + name, fail);
    }
  }
  return s;
}

SceneDescription loadScene(const std::string& path) {
  return parseScene(capture::readFileBounded(path, capture::kMaxTextFileBytes, "scene file"), path);
}

json readSceneDocument(const std::string& path) {
  const std::string text = capture::readFileBounded(path, capture::kMaxTextFileBytes, "scene file");
  parseScene(text, path);  // validates with key-named errors
  return capture::parseJson(text, path);
}

void rebaseModelPaths(json& doc, const std::string& from, const std::string& to) {
  if (!doc.contains("objects")) return;
  for (auto& obj : doc["objects"]) {
    fs::path m = obj["model"].get<std::string>();
    if (m.is_relative()) m = fs::absolute(from).parent_path() / m;
    obj["model"] = fs::proximate(m, fs::absolute(to).parent_path()).generic_string();
  }
}

void writeSceneDocument(const std::string& path, const json& doc) {
  capture::writeFileAtomically(path, doc.dump(2) + "\n");
}

cv::Vec3d eulerDegrees(const cv::Matx33d& R) {
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

}  // namespace mrgi::lighting
