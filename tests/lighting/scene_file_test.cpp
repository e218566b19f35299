// Scene files and model loading: the three formats load with the right geometry; every bad input names
// the file and the key.
#include "lighting/scene_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>

using namespace mrgi::lighting;

namespace {
const std::string kModels = std::string(MRGI_SOURCE_DIR) + "/recordings/models/";
const std::string kScenePath = kModels + "../scenes/test.json";  // models resolve relative to it

std::string errorOf(const std::string& text) {
  try {
    parseScene(text, kScenePath);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Models, ObjPlyGltfLoadWithTheirBounds) {
  const Mesh cube = loadMesh(kModels + "cube.obj");
  EXPECT_EQ(cube.triangleCount(), 12u);
  EXPECT_EQ(cube.boundsMin, cv::Vec3f(-0.5f, -0.5f, -0.5f));
  EXPECT_EQ(cube.boundsMax, cv::Vec3f(0.5f, 0.5f, 0.5f));
  const Mesh sphere = loadMesh(kModels + "sphere.ply");
  EXPECT_EQ(sphere.positions.size(), 642u);
  for (size_t i = 0; i < sphere.positions.size(); ++i) {
    EXPECT_NEAR(cv::norm(sphere.positions[i]), 1.0, 1e-5);
    EXPECT_GT(sphere.normals[i].dot(sphere.positions[i]), 0.99f);  // outward normals
  }
  const Mesh torus = loadMesh(kModels + "torus.gltf");
  EXPECT_EQ(torus.triangleCount(), 32u * 16u * 2u);
  EXPECT_NEAR(torus.boundsMax[0], 1.35f, 1e-5f);
  EXPECT_NEAR(torus.boundsMax[2], 0.35f, 1e-5f);
}

TEST(Models, BadModelFilesNameTheFile) {
  EXPECT_THROW(loadMesh(kModels + "missing.obj"), SceneError);
  try {
    loadMesh(kModels + "../FORMAT.md");
    FAIL() << "a text file loaded as a model";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("FORMAT.md"), std::string::npos) << e.what();
  }
}

/// Writes a model file into the temp folder.
std::string writeModel(const std::string& name, const std::string& bytes) {
  const std::string path = (std::filesystem::temp_directory_path() / name).string();
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

TEST(Models, BrokenPlyFilesAreRefusedNeverCrash) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const std::string vertices = "0 0 0\n1 0 0\n0 1 0\n";
  struct Case {
    const char* name;
    std::string bytes;
  };
  const Case cases[] = {
      {"index_past_end.ply", header + vertices + "3 0 1 5\n"},
      {"index_negative.ply", header + vertices + "3 0 1 -5\n"},
      {"index_huge.ply", header + vertices + "3 0 1 2000000000\n"},
      {"truncated_ascii.ply", header + "0 0 0\n1 0"},
      {"truncated_faces.ply", header + vertices + "3 0"},
      {"truncated_binary.ply", std::string("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                                           "property float y\nproperty float z\nelement face 1\n"
                                           "property list uchar int vertex_indices\nend_header\n") +
                                   std::string(20, '\x01')},
  };
  for (const Case& c : cases) {
    const std::string path = writeModel(std::string("mrgi_") + c.name, c.bytes);
    try {
      const Mesh m = loadMesh(path);
      // Whatever assimp recovers must be sound.
      for (uint32_t i : m.indices) EXPECT_LT(i, m.positions.size()) << c.name;
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
    std::filesystem::remove(path);
  }
  // Found by the model fuzzer: a face line "# 83 312 559" gives a face of no vertex, which assimp's
  // validation lets through and its triangulation aborts on (SIGABRT before the check).
  // The body check now refuses that line before assimp reads it; a face whose list length is 0 still
  // reaches assimp and gives the same face of no vertex.
  const std::string fuzzed = std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/model_face_without_vertices.ply";
  try {
    loadMesh(fuzzed);
    ADD_FAILURE() << "accepted a face of no vertex";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("face element 982 holds '#', not a number"), std::string::npos) << e.what();
  }
  const std::string empty = writeModel("mrgi_empty_face.ply", header + vertices + "0\n");
  try {
    loadMesh(empty);
    ADD_FAILURE() << "accepted a face of no vertex";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("face 0 has 0 vertex indices (at least 3)"), std::string::npos) << e.what();
  }
  std::filesystem::remove(empty);
  // Found by the model fuzzer: an element line without a count sends assimp's PLY reader into an endless
  // loop; the header is checked first.
  const std::string hang = std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/model_ply_header_hang.ply";
  try {
    loadMesh(hang);
    ADD_FAILURE() << "accepted a malformed PLY header";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("malformed PLY header: element line"), std::string::npos) << e.what();
  }
  // Found by the model fuzzer: a file named .ply whose first line is "ply" and then garbage sent assimp's
  // PLY reader into an endless loop of seeks.
  const std::string loop = std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/model_ply_garbage_first_line.ply";
  try {
    loadMesh(loop);
    ADD_FAILURE() << "accepted a PLY whose first line is not 'ply'";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("the first line is not 'ply'"), std::string::npos) << e.what();
  }
  // Found by the model fuzzer: a PLY (first line "Ply") named .glb: the glTF reader declined it, assimp
  // then tried its other readers and the PLY one looped. Content must match the name.
  const std::string glb = std::string(MRGI_SOURCE_DIR) + "/tests/data/fuzz/model_ply_named_glb.glb";
  try {
    loadMesh(glb);
    ADD_FAILURE() << "accepted a PLY named .glb";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("holds a PLY file but is named .glb"), std::string::npos) << e.what();
  }
  const std::pair<const char*, std::string> mismatched[] = {
      {"mrgi_not.obj", "hello world\n"},
      {"mrgi_not.gltf", "{\"asset\": {\"version\": \"1.0\"}}"},
      {"mrgi_deep.gltf", std::string(5000, '[') + std::string(5000, ']')},
      {"mrgi_not.glb", "glTF\x01\0\0\0\x0c\0\0\0"},
  };
  for (const auto& [name, bytes] : mismatched) {
    const std::string path = writeModel(name, bytes);
    try {
      loadMesh(path);
      ADD_FAILURE() << "accepted " << name;
    } catch (const SceneError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
    }
    std::filesystem::remove(path);
  }
  // Other extensions are refused by name rather than left to assimp's guess from the content.
  const std::string other = writeModel("mrgi_model.stl", "solid x\nendsolid x\n");
  try {
    loadMesh(other);
    ADD_FAILURE() << "accepted a .stl";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("model format must be OBJ, PLY or glTF"), std::string::npos) << e.what();
  }
  std::filesystem::remove(other);
  // An index past the vertex count is named.
  const std::string path = writeModel("mrgi_named.ply", header + vertices + "3 0 1 9999\n");
  try {
    loadMesh(path);
    ADD_FAILURE() << "accepted an index past the vertices";
  } catch (const SceneError& e) {
    const std::string what = e.what();
    EXPECT_TRUE(what.find("vertex 9999 of 3") != std::string::npos || what.find("out of range") != std::string::npos)
        << what;
  }
  std::filesystem::remove(path);
}

TEST(Models, PlyBodiesShorterThanTheirHeaderAreRefusedAndWholeOnesLoad) {
  // A tetrahedron: 4 vertices, 4 triangles, in ASCII, little- and big-endian binary. assimp alone reads a
  // cut-off body as far as it goes and returns fewer faces without a word.
  const std::string props =
      "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 4\nproperty list uchar int vertex_indices\nend_header\n";
  const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const int f[4][3] = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
  auto binary = [&](bool big) {
    std::string body;
    auto put = [&](const void* p, size_t n) {
      std::string b(static_cast<const char*>(p), n);
      if (big) std::reverse(b.begin(), b.end());
      body += b;
    };
    for (const auto& p : v)
      for (float x : p) put(&x, 4);
    for (const auto& t : f) {
      body += '\x03';
      for (int i : t) put(&i, 4);
    }
    return std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") + " 1.0\n" + props + body;
  };
  const std::string ascii =
      "ply\nformat ascii 1.0\n" + props + "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n";
  for (const std::string& whole : {ascii, binary(false), binary(true)}) {
    const std::string path = writeModel("mrgi_tetra.ply", whole);
    EXPECT_EQ(loadMesh(path).triangleCount(), 4u);
    // Cut inside the faces (ASCII: inside the last line, not just its newline): refused, naming the file
    // and what the header promised.
    const size_t last = whole == ascii ? 3 : 1;
    for (size_t keep : {whole.size() - last, whole.size() - 6, whole.size() - 14}) {
      const std::string cut = writeModel("mrgi_tetra_cut.ply", whole.substr(0, keep));
      try {
        const Mesh m = loadMesh(cut);
        ADD_FAILURE() << "a PLY cut to " << keep << " of " << whole.size() << " bytes loaded with " << m.triangleCount()
                      << " faces";
      } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find(cut + ": PLY file is truncated: the header declares 4 face"),
                  std::string::npos)
            << e.what();
      }
      std::filesystem::remove(cut);
    }
    std::filesystem::remove(path);
  }
}

TEST(Models, GltfIndicesPastTheVerticesAreRefused) {
  // Three vertices, a triangle (0, 1, N): N = 9999 and 0xFFFFFFF0 (embedded buffer, 32-bit indices).
  const std::string head =
      R"({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "scene": 0, "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
    "buffers": [{"byteLength": 48, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAEAAAA)";
  const std::string tail = R"("}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                  {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}]})";
  for (const char* last : {"PJwAA", "w////"}) {
    const std::string path = writeModel("mrgi_bad_index.gltf", head + last + tail);
    try {
      const Mesh m = loadMesh(path);
      ADD_FAILURE() << "accepted an index past the vertices (" << m.indices.size() << " indices)";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
    std::filesystem::remove(path);
  }
}

TEST(SceneFile, ParsesObjectsLightsAndKnobs) {
  const SceneDescription s = parseScene(R"({
    "objects": [{"model": "../models/cube.obj", "translate": [0, 0, 0.05], "rotate_deg": [0, 0, 90], "scale": 0.1,
                 "material": {"albedo": [0.9, 0.2, 0.1], "roughness": 0.5, "specular": 0.1}}],
    "lights": [{"type": "point", "position": [0, 0, 1], "intensity": [5, 5, 5]},
               {"type": "directional", "direction": [0, 0, -2], "irradiance": [1, 2, 3]},
               {"type": "point", "position": [0, 0, 2], "intensity": [5, 5, 5], "radius_m": 0.04},
               {"type": "directional", "direction": [0, 0, -1], "irradiance": [1, 1, 1], "angular_radius_deg": 10}],
    "ambient_radiance": [0.1, 0.1, 0.1],
    "technique": "lpv-diff",
    "lpv": {"resolution": 16, "steps": 8, "rsm_size": 128, "size_factor": 3, "damping": 0.25}
  })",
                                        kScenePath);
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_NEAR(s.objects[0].mesh.boundsMax[0], 0.05f, 1e-6f);  // scaled
  EXPECT_NEAR(s.objects[0].T_marker_object(2, 3), 0.05, 1e-12);
  EXPECT_NEAR(s.objects[0].T_marker_object(1, 0), 1.0, 1e-12);  // 90 deg about z: x -> y
  EXPECT_EQ(s.objects[0].material.albedo, cv::Vec3f(0.9f, 0.2f, 0.1f));
  EXPECT_FLOAT_EQ(s.objects[0].material.specular, 0.1f);
  EXPECT_FLOAT_EQ(s.objects[0].material.roughness, 0.5f);
  // A material reflecting more than it receives is refused, naming the key.
  try {
    parseScene(
        R"({"objects": [{"model": "../models/cube.obj", "material": {"albedo": [0.9, 0.2, 0.1], "specular": 0.2}}]})",
        kScenePath);
    ADD_FAILURE() << "accepted albedo + specular > 1";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("objects[0].material: albedo + specular exceeds 1"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(s.lightSource, LightSource::Scene);
  ASSERT_EQ(s.lights.size(), 4u);
  EXPECT_EQ(s.lights[1].type, LightType::Directional);
  EXPECT_NEAR(s.lights[1].direction[2], -1.0, 1e-12);  // normalised
  // Extents: none unless given; a sphere lamp's radius in metres, a disc of sky's half-angle in radians.
  EXPECT_EQ(s.lights[0].extent, 0.0);
  EXPECT_EQ(s.lights[2].extent, 0.04);
  EXPECT_NEAR(s.lights[2].sinAngularRadius(2.0), 0.02, 1e-12);
  EXPECT_NEAR(s.lights[3].extent, 10 * CV_PI / 180, 1e-12);
  EXPECT_NEAR(s.lights[3].sinAngularRadius(1.0), std::sin(10 * CV_PI / 180), 1e-12);
  // "lpv-diff" is DLPV in both roles with its naive_difference variant knob; frame knobs read inside "lpv"
  // (where older files have them) land in the frame group.
  EXPECT_EQ(s.technique.real, "dlpv");
  EXPECT_EQ(s.technique.virtualObject, "dlpv");
  EXPECT_EQ(s.technique.name, "lpv-diff");
  EXPECT_EQ(s.knobs.at("lpv").at("naive_difference"), 1.0);
  EXPECT_EQ(s.knobs.at("lpv").at("resolution"), 16);
  EXPECT_EQ(s.knobs.at("frame").at("rsm_size"), 128);
  EXPECT_DOUBLE_EQ(s.knobs.at("lpv").at("damping"), 0.25);
  EXPECT_FALSE(s.ambientFromManifest);
  const SceneDescription val = parseScene(R"({"technique": "dlpv+kinect-val",
    "val": {"sparse_points": 2048, "k_cache": 64, "occlusion": false, "stride": 2, "rsm_stride": 4,
            "fusion": true, "voxel": 0.03, "decay": 0.8, "brute_force": true}})",
                                          kScenePath);
  EXPECT_EQ(val.technique.real, "dlpv");
  EXPECT_EQ(val.technique.virtualObject, "kinect-val");
  const KnobValues& v = val.knobs.at("val");
  EXPECT_EQ(v.at("sparse_points"), 2048);
  EXPECT_EQ(v.at("k_cache"), 64);
  EXPECT_EQ(v.at("occlusion"), 0.0);
  EXPECT_EQ(v.at("stride"), 2);
  EXPECT_EQ(v.at("rsm_stride"), 4);
  EXPECT_EQ(v.at("fusion"), 1.0);
  EXPECT_DOUBLE_EQ(v.at("voxel"), 0.03);
  EXPECT_DOUBLE_EQ(v.at("decay"), 0.8);
  EXPECT_EQ(v.at("brute_force"), 1.0);
  // The bundled shorthands and their roles; roles as an object; defaults when nothing is given.
  const std::map<std::string, std::pair<std::string, std::string>> roles = {
      {"dlpv", {"dlpv", "dlpv"}},
      {"lpv-diff", {"dlpv", "dlpv"}},
      {"kinect-val", {"none", "kinect-val"}},
      {"dlpv+kinect-val", {"dlpv", "kinect-val"}}};
  for (const auto& [name, r] : roles) {
    const SceneDescription d = parseScene("{\"technique\": \"" + name + "\"}", kScenePath);
    EXPECT_EQ(d.technique.real, r.first) << name;
    EXPECT_EQ(d.technique.virtualObject, r.second) << name;
    EXPECT_EQ(d.technique.name, name);
  }
  const SceneDescription obj = parseScene(R"({"technique": {"real": "none", "virtual": "dlpv"}})", kScenePath);
  EXPECT_EQ(obj.technique.real, "none");
  EXPECT_EQ(obj.technique.virtualObject, "dlpv");
  EXPECT_EQ(obj.technique.name, "none+dlpv");
  const SceneDescription empty = parseScene("{}", kScenePath);
  EXPECT_TRUE(empty.objects.empty());
  EXPECT_EQ(empty.lightSource, LightSource::Manifest);
}

TEST(SceneFile, AWorldFoundedOnARecordingsFirstFrame) {
  EXPECT_FALSE(parseScene("{}", kScenePath).firstFrameT_world_camera);
  const SceneDescription s =
      parseScene(R"({"world": {"first_frame_T_world_camera": [0,-1,0,0.5, 1,0,0,0, 0,0,1,1.2, 0,0,0,1]}})", kScenePath);
  ASSERT_TRUE(s.firstFrameT_world_camera);
  EXPECT_EQ((*s.firstFrameT_world_camera)(0, 1), -1);
  EXPECT_EQ((*s.firstFrameT_world_camera)(2, 3), 1.2);
}

TEST(SceneFile, LightsFromTheRoomAndTheirKnobs) {
  const SceneDescription d = parseScene(R"({"lights": "room"})", kScenePath);
  EXPECT_EQ(d.lightSource, LightSource::Room);
  EXPECT_EQ(d.roomLightCount, 4);
  EXPECT_EQ(d.roomSaturatedGain, 0.0);  // estimated
  const SceneDescription s = parseScene(
      R"({"lights": "room", "room_light_count": 8, "room_saturated_gain": 30, "room_white_albedo": 0.7})", kScenePath);
  EXPECT_EQ(s.roomLightCount, 8);
  EXPECT_EQ(s.roomSaturatedGain, 30.0);
  EXPECT_EQ(s.roomWhiteAlbedo, 0.7);
}

TEST(SceneFile, ErrorsNameTheFileAndTheKey) {
  struct Case {
    const char* text;
    const char* expected;
  };
  const Case cases[] = {
      {"{", "not valid JSON"},
      {R"({"object": []})", "object: unknown key"},
      {R"({"world": {}})", "world.first_frame_T_world_camera: missing"},
      {R"({"world": {"first_frame_T_world_camera": [1, 0, 0]}})",
       "world.first_frame_T_world_camera: must be an array of 16"},
      {R"({"world": {"first_frame_T_world_camera": [2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}})",
       "is not a rigid transform"},
      {R"({"world": {"first_frame_T_world_camera": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1], "x": 1}})",
       "world.x: unknown key"},
      {R"({"objects": [{}]})", "objects[0].model: missing"},
      {R"({"objects": [{"model": "nope.obj"}]})", "objects[0].model:"},
      {R"({"objects": [{"model": "../models/cube.obj", "scale": -1}]})",
       "objects[0].scale: must be a finite number in [1e-06, 1e+06], not -1"},
      {R"({"objects": [{"model": "../models/cube.obj", "material": {"albedo": [1, 2]}}]})",
       "objects[0].material.albedo: must be an array of 3 numbers"},
      {R"({"objects": [{"model": "../models/cube.obj", "material": {"albedo": [1, 2, 0]}}]})",
       "objects[0].material.albedo[1]: must be a finite number in [0, 1], not 2"},
      {R"({"lights": [{"type": "area"}]})", "lights[0].type: unknown light type 'area'"},
      {R"({"lights": [{"type": "point", "position": [0, 0, 1]}]})", "lights[0].intensity: missing"},
      {R"({"lights": [{"type": "point", "position": [0, 0, 1], "intensity": [1, 1, 1], "radius_m": -1}]})",
       "lights[0].radius_m: must be a finite number in [0, 10], not -1"},
      {R"({"lights": [{"type": "point", "position": [0, 0, 1], "intensity": [1, 1, 1], "angular_radius_deg": 5}]})",
       "lights[0].angular_radius_deg: is for directional lights"},
      {R"({"lights": [{"type": "directional", "direction": [0, 0, -1], "irradiance": [1, 1, 1], "radius_m": 1}]})",
       "lights[0].radius_m: is for point and spot lights"},
      {R"({"lights": [{"type": "directional", "direction": [0, 0, -1], "irradiance": [1, 1, 1],
                       "angular_radius_deg": 90}]})",
       "lights[0].angular_radius_deg: must be a finite number in [0, 80], not 90"},
      {R"({"lights": [{"type": "directional", "direction": [0, 0, 0], "irradiance": [1, 1, 1]}]})",
       "lights[0].direction: must not be the zero vector"},
      {R"({"lights": "sun"})", "lights: must be \"auto\", \"manifest\""},
      {R"({"technique": "rtx"})", "technique: unknown technique 'rtx'"},
      {R"({"lpv": {"resolution": 1000}})", "lpv.resolution: must be an integer in [4, 128], not 1000"},
      {R"({"lpv": {"steps": 2.5}})", "lpv.steps: must be an integer"},
      {R"({"val": {"k_cache": 1024}})", "val.k_cache: must be an integer in [16, 512], not 1024"},
      {R"({"val": {"occlusion": 1}})", "val.occlusion: must be true or false"},
      {R"({"val": {"sparse": 100}})", "val.sparse: unknown key"},
      {R"({"technique": {"real": "kinect-val"}})", "technique: technique 'kinect-val' cannot serve real pixels"},
      {R"({"technique": {"real": "dlpv", "virtual": "rtx"}})", "technique: unknown technique 'rtx'"},
      {R"({"technique": {"reals": "dlpv"}})", "technique.reals: unknown key"},
      {R"({"technique": 3})", "technique: must be a technique name"},
      {R"({"frame": {"rsm_size": 8}})", "frame.rsm_size: must be an integer in [16, 4096], not 8"},
      {R"({"lpv": {"rsm_size": 8}})", "lpv.rsm_size: must be an integer in [16, 4096], not 8"},
      {R"({"room_light_count": 0})", "room_light_count: must be an integer in [1, 16], not 0"},
      {R"({"room_saturated_gain": -1})", "room_saturated_gain: must be a finite number in [0, 10000], not -1"},
      {R"({"room_white_albedo": 2})", "room_white_albedo: must be a finite number in [0.05, 1], not 2"},
  };
  for (const Case& c : cases) {
    const std::string e = errorOf(c.text);
    EXPECT_NE(e.find(kScenePath), std::string::npos) << c.text << " -> " << e;
    EXPECT_NE(e.find(c.expected), std::string::npos) << c.text << " -> " << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << "one line: " << e;
  }
}
