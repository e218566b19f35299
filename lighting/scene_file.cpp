#include "lighting/scene_file.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>

#include "capture/json_io.h"
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

/// PLY files are checked before assimp sees them: its reader loops forever on some malformed headers (an
/// element line without a count, found by the model fuzzer), and it accepts a body shorter than the header
/// promises (a truncated file) by reading what is there. Accepts the header grammar only: "ply", one format
/// line, comment/obj_info lines, "element NAME COUNT", "property TYPE NAME" or "property list TYPE TYPE
/// NAME", "end_header"; then the body must hold every element the header declares (ASCII: one line each;
/// binary: walked property by property, list lengths included).
void checkPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  auto bad = [&](std::string why) {
    for (char& c : why)
      if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';  // one printable line
    throw SceneError(path, "malformed PLY header: " + why);
  };
  // A PLY file is one named .ply or one starting with "ply" (assimp recognises it by either): its first line
  // must then be exactly "ply" (a damaged one sent assimp's PLY reader into an endless loop of seeks; found
  // by the model fuzzer). Anything else is left to assimp.
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  char magic[3] = {};
  in.read(magic, 3);
  const bool ply = ext == ".ply" || (in.gcount() == 3 && std::string(magic, 3) == "ply");
  if (!ply) return;
  in.clear();
  in.seekg(0);
  if (!std::getline(in, line) || (line != "ply" && line != "ply\r")) bad("the first line is not 'ply'");
  static const std::map<std::string, int> kTypes{{"char", 1},   {"uchar", 1},   {"short", 2},   {"ushort", 2},
                                                 {"int", 4},    {"uint", 4},    {"float", 4},   {"double", 8},
                                                 {"int8", 1},   {"uint8", 1},   {"int16", 2},   {"uint16", 2},
                                                 {"int32", 4},  {"uint32", 4},  {"float32", 4}, {"float64", 8}};
  struct Property {
    int countBytes = 0, itemBytes = 0;  // countBytes > 0: a list
  };
  struct Element {
    std::string name;
    uint64_t count = 0;
    std::vector<Property> properties;
  };
  std::vector<Element> elements;
  std::string format;
  bool header = false;
  for (int n = 0; n < 10000 && std::getline(in, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string word;
    words >> word;
    if (word == "end_header") {
      if (format.empty()) bad("no format line");
      header = true;
      break;
    }
    if (word == "comment" || word == "obj_info") continue;
    std::vector<std::string> rest;
    for (std::string w; words >> w;) rest.push_back(w);
    if (word == "format") {
      if (rest.size() != 2 || (rest[0] != "ascii" && rest[0] != "binary_little_endian" && rest[0] != "binary_big_endian"))
        bad("format line '" + line + "'");
      format = rest[0];
    } else if (word == "element") {
      if (rest.size() != 2 || rest[1].empty() || rest[1].find_first_not_of("0123456789") != std::string::npos ||
          rest[1].size() > 10)
        bad("element line '" + line + "' needs a name and a count");
      elements.push_back({rest[0], std::stoull(rest[1]), {}});
    } else if (word == "property") {
      if (elements.empty()) bad("a property before any element");
      const bool list = !rest.empty() && rest[0] == "list";
      if (list ? (rest.size() != 4 || !kTypes.count(rest[1]) || !kTypes.count(rest[2]))
               : (rest.size() != 2 || !kTypes.count(rest[0])))
        bad("property line '" + line + "'");
      elements.back().properties.push_back(list ? Property{kTypes.at(rest[1]), kTypes.at(rest[2])} : Property{0, kTypes.at(rest[0])});
    } else {
      bad("unexpected line '" + line.substr(0, 40) + "'");
    }
  }
  if (!header) bad("no end_header");

  auto truncated = [&](const Element& e, uint64_t have) {
    throw SceneError(path, "PLY file is truncated: the header declares " + std::to_string(e.count) + " " + e.name +
                               " elements, the file holds " + std::to_string(have));
  };
  if (format == "ascii") {
    for (const Element& e : elements) {
      if (e.properties.empty()) continue;
      for (uint64_t i = 0; i < e.count; ++i) {
        do {
          if (!std::getline(in, line)) truncated(e, i);
        } while (line.find_first_not_of(" \t\r") == std::string::npos);
        // The line must hold every property: one number each, a list its length and then that many.
        std::istringstream words(line);
        auto number = [&]() {
          std::string word;
          if (!(words >> word)) {
            if (in.peek() == EOF) truncated(e, i);  // the last line, cut short
            throw SceneError(path, "malformed PLY: " + e.name + " element " + std::to_string(i) + " has too few values");
          }
          char* end = nullptr;
          const double value = std::strtod(word.c_str(), &end);
          if (end == word.c_str() || *end != '\0' || !std::isfinite(value))
            throw SceneError(path, "malformed PLY: " + e.name + " element " + std::to_string(i) + " holds '" +
                                       word.substr(0, 20) + "', not a number");
          return value;
        };
        for (const Property& p : e.properties) {
          const double first = number();
          if (p.countBytes > 0) {
            if (!(first >= 0 && first <= 1e6 && first == std::floor(first)))
              throw SceneError(path, "malformed PLY: " + e.name + " element " + std::to_string(i) + " has a list length of " + std::to_string(first));
            for (int k = 0; k < static_cast<int>(first); ++k) number();
          }
        }
      }
    }
    return;
  }
  const bool swap = format == "binary_big_endian";
  const std::string body{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  uint64_t at = 0;
  for (const Element& e : elements) {
    if (e.properties.empty()) continue;
    for (uint64_t i = 0; i < e.count; ++i)
      for (const Property& p : e.properties) {
        uint64_t items = 1;
        if (p.countBytes > 0) {
          if (at + static_cast<uint64_t>(p.countBytes) > body.size()) truncated(e, i);
          items = 0;
          for (int k = 0; k < p.countBytes; ++k)
            items |= uint64_t(static_cast<unsigned char>(body[at + static_cast<uint64_t>(swap ? p.countBytes - 1 - k : k)])) << (8 * k);
          at += static_cast<uint64_t>(p.countBytes);
        }
        if (items > body.size() || at + items * static_cast<uint64_t>(p.itemBytes) > body.size()) truncated(e, i);
        at += items * static_cast<uint64_t>(p.itemBytes);
      }
  }
}

}  // namespace

Mesh loadMesh(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw SceneError(path, "model file not found");
  // The formats we name, by extension, so that assimp picks its reader by name and never by guessing
  // from the content (its PLY reader claims any file with "ply" near the start).
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".obj" && ext != ".ply" && ext != ".gltf" && ext != ".glb")
    throw SceneError(path, "model format must be OBJ, PLY or glTF (.obj, .ply, .gltf, .glb)");
  checkPly(path);
  Assimp::Importer importer;
  // Two steps: the import with assimp's own validation only, then our index check, then the
  // post-processing — which trusts its input (out-of-range or truncated faces crash or abort inside it).
  const aiScene* scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE))
    throw SceneError(path, std::string("cannot read model: ") + importer.GetErrorString());
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
          throw SceneError(path, "model mesh " + std::to_string(m) + " face " + std::to_string(f) + " refers to vertex " +
                                     std::to_string(face.mIndices[k]) + " of " + std::to_string(mesh->mNumVertices));
    }
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw SceneError(path, "model has a non-finite vertex position");
    }
  }
  scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_GenSmoothNormals | aiProcess_JoinIdenticalVertices |
                                       aiProcess_SortByPType | aiProcess_PreTransformVertices);
  if (!scene || !scene->mRootNode) throw SceneError(path, std::string("cannot read model: ") + importer.GetErrorString());
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
        fail(join(key, k), "unknown key (expected one of: " + list + ")");
      }
  }

  static std::string join(const std::string& parent, const std::string& k) {
    return parent.empty() ? k : parent + "." + k;
  }

  double number(const json& v, const std::string& key, double lo, double hi) const {
    if (!v.is_number()) fail(key, "must be a number");
    const double x = v.get<double>();
    if (!std::isfinite(x) || x < lo || x > hi) {
      std::ostringstream s;
      s << "value " << x << " out of range [" << lo << ", " << hi << "]";
      fail(key, s.str());
    }
    return x;
  }

  int integer(const json& v, const std::string& key, int lo, int hi) const {
    if (!v.is_number_integer()) fail(key, "must be an integer");
    const auto x = v.get<long long>();
    if (x < lo || x > hi) fail(key, "value " + std::to_string(x) + " out of range [" + std::to_string(lo) + ", " +
                                        std::to_string(hi) + "]");
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
  const double n = cv::norm(v);
  if (n < 1e-9) r.fail(key, "must not be the zero vector");
  return v / n;
}

}  // namespace

SceneDescription parseScene(const std::string& text, const std::string& path) {
  Reader r(path);
  json doc;
  doc = capture::parseJson(text, path);
  std::set<std::string> topLevel{"objects", "lights", "fisheye_light_count", "ambient_radiance", "technique"};
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
      obj.model = fs::path(model).is_absolute() ? fs::path(model).lexically_normal().string() : (base / model).lexically_normal().string();
      const double scale = o.contains("scale") ? r.number(o["scale"], key + ".scale", 1e-6, 1e6) : 1.0;
      const cv::Vec3d t = o.contains("translate") ? r.vec3(o["translate"], key + ".translate", -1e3, 1e3) : cv::Vec3d();
      const cv::Vec3d rd = o.contains("rotate_deg") ? r.vec3(o["rotate_deg"], key + ".rotate_deg", -3600, 3600) : cv::Vec3d();
      if (o.contains("material")) {
        const json& m = o["material"];
        const std::string materialKey = key + ".material";
        r.allowOnly(m, materialKey, {"albedo", "roughness", "specular"});
        if (m.contains("albedo")) obj.material.albedo = r.vec3(m["albedo"], key + ".material.albedo", 0, 1);
        if (m.contains("roughness"))
          obj.material.roughness = static_cast<float>(r.number(m["roughness"], key + ".material.roughness", 0, 1));
        if (m.contains("specular"))
          obj.material.specular = static_cast<float>(r.number(m["specular"], key + ".material.specular", 0, 1));
        if (obj.material.albedo[0] + obj.material.specular > 1.0f || obj.material.albedo[1] + obj.material.specular > 1.0f ||
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

  if (doc.contains("lights")) {
    const json& l = doc["lights"];
    if (l.is_string()) {
      const std::string v = l.get<std::string>();
      if (v != "manifest" && v != "fisheye") r.fail("lights", "must be \"manifest\", \"fisheye\" or an array of lights");
      s.lightSource = v == "manifest" ? LightSource::Manifest : LightSource::Fisheye;
    } else if (l.is_array()) {
      s.lightSource = LightSource::Scene;
      for (size_t i = 0; i < l.size(); ++i) {
        const std::string key = "lights[" + std::to_string(i) + "]";
        const json& j = l[i];
        r.allowOnly(j, key, {"type", "position", "direction", "intensity", "irradiance", "spot_half_angle_deg"});
        if (!j.contains("type")) r.fail(key + ".type", "missing (point, spot or directional)");
        const std::string type = r.string(j["type"], key + ".type");
        SceneLight light;
        auto need = [&](const char* k) {
          if (!j.contains(k)) r.fail(key + "." + k, std::string("missing (required for a ") + type + " light)");
          return j[k];
        };
        if (type == "point" || type == "spot") {
          light.type = type == "point" ? LightType::Point : LightType::Spot;
          light.position = r.vec3(need("position"), key + ".position", -1e3, 1e3);
          light.intensity = r.vec3(need("intensity"), key + ".intensity", 0, 1e9);
          if (light.type == LightType::Spot) {
            light.direction = unit(r.vec3(need("direction"), key + ".direction", -1e3, 1e3), r, key + ".direction");
            if (j.contains("spot_half_angle_deg"))
              light.spotHalfAngleDeg = r.number(j["spot_half_angle_deg"], key + ".spot_half_angle_deg", 0.1, 89.0);
          }
        } else if (type == "directional") {
          light.type = LightType::Directional;
          light.direction = unit(r.vec3(need("direction"), key + ".direction", -1e3, 1e3), r, key + ".direction");
          light.irradiance = r.vec3(need("irradiance"), key + ".irradiance", 0, 1e9);
        } else {
          r.fail(key + ".type", "unknown light type '" + type + "' (expected point, spot or directional)");
        }
        s.lights.push_back(light);
      }
    } else {
      r.fail("lights", "must be \"manifest\", \"fisheye\" or an array of lights");
    }
  }
  if (doc.contains("fisheye_light_count"))
    s.fisheyeLightCount = r.integer(doc["fisheye_light_count"], "fisheye_light_count", 1, 16);
  if (doc.contains("ambient_radiance")) {
    s.ambientRadiance = r.vec3(doc["ambient_radiance"], "ambient_radiance", 0, 1e6);
    s.ambientFromManifest = false;
  }
  if (doc.contains("technique")) {
    // The technique first: an alias sets knobs that the knob sections below may still override.
    const json& t = doc["technique"];
    try {
      if (t.is_string()) {
        s.technique = parseTechniqueChoice(t.get<std::string>(), &s.knobs);
      } else if (t.is_object()) {
        r.allowOnly(t, "technique", {"real", "virtual"});
        s.technique = parseTechniqueRoles(t.contains("real") ? r.string(t["real"], "technique.real") : "none",
                                          t.contains("virtual") ? r.string(t["virtual"], "technique.virtual") : "none",
                                          &s.knobs);
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
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(path, "cannot open scene file");
  std::stringstream ss;
  ss << in.rdbuf();
  return parseScene(ss.str(), path);
}

}  // namespace mrgi::lighting
