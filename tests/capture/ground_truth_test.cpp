// The typed ground truth of a session manifest: every light type read (none silently dropped), the marker
// pose, ambient and reference composites, and one-line errors naming the manifest and the key.
#include "capture/ground_truth.h"

#include <gtest/gtest.h>

#include "capture/error.h"
#include "capture/json_io.h"
#include "capture/session.h"

namespace mrgi::capture {
namespace {

const char* kFile = "/tmp/s/manifest.json";

TEST(GroundTruth, ReadsEveryLightTypeTheMarkerAmbientAndReferences) {
  const auto j = nlohmann::json::parse(R"({
    "T_world_marker": [1,0,0,0, 0,1,0,0.5, 0,0,1,0, 0,0,0,1],
    "lights": [{"type": "point", "position": [1, 2, 3], "intensity_w_sr": [9, 8, 7], "radius_m": 0.04},
               {"type": "spot", "position": [0, 1, 0], "direction": [0, -2, 0], "intensity_w_sr": [1, 1, 1],
                "spot_half_angle_deg": 30},
               {"type": "directional", "direction": [0, 0, -3], "irradiance_w_m2": [5, 5, 4]}],
    "scene": {"ambient_radiance": [0.05, 0.05, 0.05]},
    "reference": {"scene": "../scenes/s.json", "composite": "reference/NNNNNN.png",
                  "delta": "reference/delta_NNNNNN.exr", "mask": "reference/mask_NNNNNN.png"},
    "environment": {"file": "sky.exr", "scale": 0.5}})");
  const GroundTruth g = GroundTruth::fromJson(j, kFile);
  ASSERT_TRUE(g.T_world_marker);
  EXPECT_DOUBLE_EQ((*g.T_world_marker)(1, 3), 0.5);
  ASSERT_EQ(g.lights.size(), 3u);
  EXPECT_EQ(g.lights[0].type, GroundTruthLight::Type::Point);
  EXPECT_EQ(g.lights[0].intensity, cv::Vec3d(9, 8, 7));
  EXPECT_DOUBLE_EQ(g.lights[0].radius, 0.04);
  EXPECT_EQ(g.lights[1].type, GroundTruthLight::Type::Spot);
  EXPECT_EQ(g.lights[1].direction, cv::Vec3d(0, -1, 0));  // normalised
  EXPECT_DOUBLE_EQ(g.lights[1].spotHalfAngleDeg, 30);
  EXPECT_EQ(g.lights[2].type, GroundTruthLight::Type::Directional);
  EXPECT_EQ(g.lights[2].direction, cv::Vec3d(0, 0, -1));
  EXPECT_EQ(g.lights[2].irradiance, cv::Vec3d(5, 5, 4));
  ASSERT_TRUE(g.ambientRadiance);
  EXPECT_DOUBLE_EQ((*g.ambientRadiance)[1], 0.05);
  ASSERT_TRUE(g.reference);
  EXPECT_EQ(GroundTruthReference::pathFor("/s", g.reference->delta, 12), "/s/reference/delta_000012.exr");
  EXPECT_EQ(g.environment["file"], "sky.exr");
  EXPECT_TRUE(g.listsLights);
  EXPECT_TRUE(GroundTruth::fromJson(nullptr, kFile).lights.empty());
  // Lit by an environment alone: the lights are listed, and there are none.
  const GroundTruth outdoors = GroundTruth::fromJson(nlohmann::json::parse(R"({"lights": []})"), kFile);
  EXPECT_TRUE(outdoors.listsLights);
  EXPECT_TRUE(outdoors.lights.empty());
  EXPECT_FALSE(GroundTruth::fromJson(nlohmann::json::parse(R"({"scene": {}})"), kFile).listsLights);
}

TEST(GroundTruth, BadEntriesAreOneLineErrorsNamingTheKey) {
  const std::pair<const char*, const char*> cases[] = {
      {R"({"lights": [{"type": "area", "position": [0, 0, 0]}]})", "ground_truth.lights[0].type 'area'"},
      {R"({"lights": [{"type": "point", "position": [0, 0]}]})",
       "ground_truth.lights[0].position must be an array of 3"},
      {R"({"lights": [{"type": "directional", "direction": [0, 0, -1]}]})",
       "ground_truth.lights[0].irradiance_w_m2 is missing"},
      {R"({"lights": {}})", "ground_truth.lights must be an array"},
      {R"({"reference": {"scene": "s.json", "composite": "c.png", "delta": "d_NNNNNN.exr", "mask": "m_NNNNNN.png"}})",
       "has no NNNNNN"},
      {R"({"T_world_marker": [1, 2]})", "ground_truth.T_world_marker"},
      {R"({"scene": {"ambient_radiance": []}})", "ground_truth.scene.ambient_radiance must be an array of 3"},
      {R"({"lights": [{"type": "point", "position": [], "intensity_w_sr": [1, 1, 1]}]})",
       "ground_truth.lights[0].position"},
      {R"({"lights": [{"type": "point", "position": [0, 0, 1], "intensity_w_sr": [1]}]})",
       "ground_truth.lights[0].intensity_w_sr"},
      {R"({"lights": [{"type": "point", "position": [0, 0, "x"], "intensity_w_sr": [1, 1, 1]}]})",
       "must hold finite numbers"},
  };
  for (const auto& [text, expected] : cases) {
    try {
      GroundTruth::fromJson(nlohmann::json::parse(text), kFile);
      ADD_FAILURE() << "accepted " << text;
    } catch (const CaptureError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(kFile), std::string::npos) << what;
      EXPECT_NE(what.find(expected), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
}

TEST(Json, DeepNestingIsRefusedInOneLineNotByTheStack) {
  // 10^5 nested objects, 10^6 nested arrays: the recursion of parsing or copying them ran out of stack.
  std::string objects, arrays(1000000, '[');
  for (int i = 0; i < 100000; ++i) objects += "{\"a\":";
  for (const std::string& text : {objects, arrays, std::string("{\"ground_truth\": ") + arrays}) {
    try {
      parseJson(text, kFile);
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()), std::string(kFile) + ": not valid JSON: nested deeper than 64 levels");
    }
  }
  EXPECT_EQ(parseJson(R"({"a": [[1, 2], {"b": null}]})", kFile)["a"][0][1], 2);
  try {
    parseJson("{\"x\": 1e400}", kFile);
    ADD_FAILURE() << "accepted 1e400";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(std::string(kFile) + ": not valid JSON: ", 0), 0u) << e.what();
  }
}

TEST(Json, AConstAccessToAMissingKeyThrowsInEveryBuild) {
  // nlohmann-json's own check is an assert(), gone in release builds: the access read past the map and
  // crashed only with some heap layouts (a CLI test, once in CI). capture/json_checks.h makes it throw.
  const nlohmann::json j = nlohmann::json::parse(R"({"frame": {"rsm_size": 128}})");
  EXPECT_EQ(j["frame"]["rsm_size"], 128);
  EXPECT_THROW(static_cast<void>(j["lpv"]), std::logic_error);
  EXPECT_THROW(static_cast<void>(j["frame"]["resolution"]), std::logic_error);
}

TEST(GroundTruth, SessionsExposeItWithoutKnowingTheSourceType) {
  const std::unique_ptr<FrameSource> s = open(std::string(MRGI_SOURCE_DIR) + "/recordings/tabletop-hdr");
  const SessionManifest* m = s->sessionManifest();
  ASSERT_NE(m, nullptr);
  EXPECT_TRUE(m->truth.T_world_marker);
  ASSERT_TRUE(m->truth.reference);
  EXPECT_FALSE(m->truth.environment.is_null());
}

}  // namespace
}  // namespace mrgi::capture
