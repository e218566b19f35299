// A scene's lights resolved against a source: the session's ground-truth lights of every type come into the
// marker frame (none dropped), with the ambient and the marker; sources without a manifest say what is missing.
#include <gtest/gtest.h>

#include "capture/error.h"
#include "capture/session.h"
#include "gl/context.h"
#include "runtime/frame_pipeline.h"

namespace mrgi::runtime {
namespace {

/// A source with a manifest and no frames.
class ManifestOnly final : public capture::FrameSource {
 public:
  explicit ManifestOnly(capture::SessionManifest m) : m_(std::move(m)) {}
  const capture::SourceInfo& info() const override { return info_; }
  std::optional<capture::Frame> next() override { return std::nullopt; }
  const capture::SessionManifest* sessionManifest() const override { return &m_; }

 private:
  capture::SessionManifest m_;
  capture::SourceInfo info_;
};

TEST(PrepareLighting, GroundTruthLightsOfEveryTypeComeIntoTheMarkerFrame) {
  capture::SessionManifest m;
  // The marker 0.5 m up the world's y axis, its z axis along the world's y (up).
  m.groundTruth = nlohmann::json::parse(R"({
    "T_world_marker": [1,0,0,0, 0,0,1,0.5, 0,-1,0,0, 0,0,0,1],
    "lights": [{"type": "point", "position": [0, 1.5, 0], "intensity_w_sr": [9, 9, 9], "radius_m": 0.04},
               {"type": "spot", "position": [0, 0.5, 1], "direction": [0, 0, -1], "intensity_w_sr": [1, 1, 1]},
               {"type": "directional", "direction": [0, -1, 0], "irradiance_w_m2": [5, 5, 5]}],
    "scene": {"ambient_radiance": [0.07, 0.07, 0.07]}})");
  m.truth = capture::GroundTruth::fromJson(m.groundTruth, "manifest.json");
  const ManifestOnly source(m);
  lighting::SceneDescription scene;
  scene.lightSource = lighting::LightSource::Manifest;
  const LightingSetup s = prepareLighting(scene, "scene.json", source, "session", PoseMode::Marker);
  ASSERT_EQ(s.lights.size(), 3u);
  // World = (x_m, z_m + 0.5, -y_m), so marker = (x_w, -z_w, y_w - 0.5).
  EXPECT_EQ(s.lights[0].type, lighting::LightType::Point);
  EXPECT_NEAR(cv::norm(s.lights[0].position - cv::Vec3d(0, 0, 1.0)), 0.0, 1e-12);
  EXPECT_EQ(s.lights[0].extent, 0.04) << "the lamp's radius: its soft shadow, its light near a horizon";
  EXPECT_EQ(s.lights[1].extent, 0.0);
  EXPECT_EQ(s.lights[1].type, lighting::LightType::Spot);
  EXPECT_NEAR(cv::norm(s.lights[1].position - cv::Vec3d(0, -1, 0)), 0.0, 1e-12);
  EXPECT_NEAR(cv::norm(s.lights[1].direction - cv::Vec3d(0, 1, 0)), 0.0, 1e-12);
  EXPECT_EQ(s.lights[2].type, lighting::LightType::Directional);
  EXPECT_NEAR(cv::norm(s.lights[2].direction - cv::Vec3d(0, 0, -1)), 0.0, 1e-12);  // straight down onto the marker
  EXPECT_EQ(s.lights[2].irradiance, cv::Vec3d(5, 5, 5));
  EXPECT_EQ(s.ambient, cv::Vec3d(0.07, 0.07, 0.07));
}

TEST(PrepareLighting, AnEnvironmentLitSessionHasNoDeltaLightsAndThatIsNoError) {
  capture::SessionManifest m;
  m.groundTruth = nlohmann::json::parse(R"({"T_world_marker": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1], "lights": []})");
  m.truth = capture::GroundTruth::fromJson(m.groundTruth, "manifest.json");
  const ManifestOnly source(m);
  lighting::SceneDescription scene;
  scene.lightSource = lighting::LightSource::Manifest;
  EXPECT_TRUE(prepareLighting(scene, "scene.json", source, "session", PoseMode::Marker).lights.empty());
}

TEST(PrepareLighting, ManifestLightsWithoutGroundTruthNameTheSceneAndTheSource) {
  const ManifestOnly source{capture::SessionManifest{}};
  lighting::SceneDescription scene;
  scene.lightSource = lighting::LightSource::Manifest;
  scene.lightsGiven = true;  // "lights": "manifest" (without the key the room fused from the frames lights it)
  try {
    prepareLighting(scene, "scene.json", source, "session-dir", PoseMode::Marker);
    ADD_FAILURE() << "accepted";
  } catch (const capture::CaptureError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("scene.json"), std::string::npos) << what;
    EXPECT_NE(what.find("session-dir has no ground-truth lights"), std::string::npos) << what;
  }
}

TEST(FramePipelineSetup, ADirectionalAmbientTheSetupCarriesShadesFromTheFirstFrame) {
  // A live window rebuilds its pipeline when a knob changes, from a setup whose lights and ambient were
  // estimated before (a fisheye frame may be many frames away): the SH part comes along, as the uniform part.
  gl::ContextConfig cfg;
  cfg.width = 64;
  cfg.height = 48;
  auto context = gl::createContext(cfg);
  LightingSetup setup;
  setup.ambient = {0.1, 0.1, 0.1};
  setup.ambientSh[2] = {0.3, 0.2, 0.1};
  FramePipeline fp(setup, 64, 48, FrameOptions{});
  ASSERT_NE(fp.lighting(), nullptr);
  EXPECT_EQ(fp.lighting()->frame().ambientSh()[2], cv::Vec3d(0.3, 0.2, 0.1));
}

}  // namespace
}  // namespace mrgi::runtime
