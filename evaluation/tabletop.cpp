#include "evaluation/tabletop.h"

#include <cmath>

#include "capture/session.h"
#include "reconstruction/marker_image.h"

namespace mrgi::evaluation {

namespace {
constexpr float kTableTop = 0.75f;
}

Tabletop buildTabletop(const TabletopConfig& c) {
  Tabletop t;
  auto& s = t.scene;
  const float W = 2.0f, H = 2.6f;  // room half-width, height
  const int floorM = s.addMaterial({"floor", {0.35f, 0.33f, 0.30f}});
  const int ceilM = s.addMaterial({"ceiling", {0.80f, 0.80f, 0.80f}});
  const int backM = s.addMaterial({"wall_back_red", {0.70f, 0.18f, 0.12f}});
  const int leftM = s.addMaterial({"wall_left_green", {0.18f, 0.55f, 0.22f}});
  const int rightM = s.addMaterial({"wall_right_white", {0.72f, 0.72f, 0.68f}});
  const int frontM = s.addMaterial({"wall_front_blue", {0.20f, 0.28f, 0.62f}});
  const int tableM = s.addMaterial({"table", {0.48f, 0.34f, 0.22f}});
  const int boxM = s.addMaterial({"box_yellow", {0.78f, 0.66f, 0.16f}});
  if (c.environment) {
    // Outdoors: open ground (grey stone) to the horizon's foot, lit by the environment alone.
    const float G = 30.f;
    s.addQuad({-G, 0, -G}, {0, 0, 2 * G}, {2 * G, 0, 0}, floorM);
    s.environmentMap = c.environment;
  } else {
    // Room faces point inwards.
    s.addQuad({-W, 0, -W}, {0, 0, 2 * W}, {2 * W, 0, 0}, floorM);
    s.addQuad({-W, H, -W}, {2 * W, 0, 0}, {0, 0, 2 * W}, ceilM);
    s.addQuad({-W, 0, -W}, {2 * W, 0, 0}, {0, H, 0}, backM);
    s.addQuad({-W, 0, -W}, {0, H, 0}, {0, 0, 2 * W}, leftM);
    if (c.windowSun) {
      // The right wall around its window: below, above, and either side of it.
      const float y0 = 1.0f, y1 = 2.0f, z0 = -0.5f, z1 = 0.5f;
      s.addQuad({W, 0, -W}, {0, 0, 2 * W}, {0, y0, 0}, rightM);
      s.addQuad({W, y1, -W}, {0, 0, 2 * W}, {0, H - y1, 0}, rightM);
      s.addQuad({W, y0, -W}, {0, 0, z0 + W}, {0, y1 - y0, 0}, rightM);
      s.addQuad({W, y0, z1}, {0, 0, W - z1}, {0, y1 - y0, 0}, rightM);
    } else {
      s.addQuad({W, 0, -W}, {0, 0, 2 * W}, {0, H, 0}, rightM);
    }
    s.addQuad({-W, 0, W}, {0, H, 0}, {2 * W, 0, 0}, frontM);
  }
  // Table: top slab and four legs.
  s.addBox({-0.6f, kTableTop - 0.03f, -0.4f}, {0.6f, kTableTop, 0.4f}, tableM);
  for (float x : {-0.55f, 0.52f})
    for (float z : {-0.35f, 0.32f}) s.addBox({x, 0, z}, {x + 0.03f, kTableTop - 0.03f, z + 0.03f}, tableM);
  // A box on the table.
  const auto [boxLo, boxHi] = tabletopBox();
  s.addBox(boxLo + c.boxOffset, boxHi + c.boxOffset, boxM);

  // The AprilTag lies flat at the table centre, slightly above the top to avoid z-fighting.
  reconstruction::TagLayout layout{};
  const cv::Mat tag = reconstruction::renderTag(c.tagFamily, c.tagId, &layout);
  cv::Mat tex(tag.size(), CV_32FC3);
  for (int y = 0; y < tag.rows; ++y)
    for (int x = 0; x < tag.cols; ++x) {
      const float a = tag.at<uchar>(y, x) > 127 ? 0.85f : 0.03f;  // printed paper / toner albedo
      tex.at<cv::Vec3f>(y, x) = {a, a, a};
    }
  s.textures.push_back(tex);
  const int tagM = s.addMaterial({"apriltag", {1, 1, 1}, 0});
  const float full = static_cast<float>(c.tagSize * layout.totalCells / layout.borderCells);
  const float tagY = kTableTop + 0.0005f;
  // Image rows run along world +z (marker -y), columns along world +x (marker x).
  s.addQuad({-full / 2, tagY, -full / 2}, {full, 0, 0}, {0, 0, full}, tagM);

  if (!c.environment) {
    s.lights.push_back({{0.45f, 1.95f, 0.55f}, {9.0f, 8.4f, 7.6f}, 0.04f});
    s.ambient = {0.05f, 0.05f, 0.05f};
  }
  if (c.windowSun) {
    // The sky seen through the window (and lighting the room through it): a clear sky above the horizon, the
    // ground below it; only the window lets it in.
    cv::Mat sky(32, 64, CV_32FC3);
    for (int v = 0; v < sky.rows; ++v)
      for (int u = 0; u < sky.cols; ++u) {
        const cv::Vec3f d = groundtruth::EnvironmentMap::directionOf((u + 0.5f) / sky.cols, (v + 0.5f) / sky.rows);
        sky.at<cv::Vec3f>(v, u) = d[1] > 0 ? windowSkyRadiance() : cv::Vec3f(0.16f, 0.14f, 0.11f);
      }
    s.environmentMap = std::make_shared<groundtruth::EnvironmentMap>(sky);
    groundtruth::Light sun;
    sun.type = groundtruth::LightType::Directional;
    sun.direction = -windowSunTowards();  // the way its light travels
    sun.irradiance = windowSunIrradiance();
    sun.radius = 0;
    s.lights.push_back(sun);
  }

  // Marker frame: x = world x, z = world y (out of the table), y = z x x = world -z.
  t.T_world_marker = capture::Pose(1, 0, 0, 0,     //
                                   0, 0, 1, tagY,  //
                                   0, -1, 0, 0,    //
                                   0, 0, 0, 1);
  nlohmann::json gt;
  gt["T_world_marker"] = capture::poseToJson(t.T_world_marker);
  gt["lights"] = nlohmann::json::array();
  for (const auto& l : s.lights)
    if (l.type == groundtruth::LightType::Directional)
      gt["lights"].push_back({{"type", "directional"},
                              {"direction", {l.direction[0], l.direction[1], l.direction[2]}},
                              {"irradiance_w_m2", {l.irradiance[0], l.irradiance[1], l.irradiance[2]}}});
    else
      gt["lights"].push_back({{"type", "point"},
                              {"position", {l.position[0], l.position[1], l.position[2]}},
                              {"intensity_w_sr", {l.intensity[0], l.intensity[1], l.intensity[2]}},
                              {"radius_m", l.radius}});
  gt["scene"]["generator"] = "mrgi synth (direct light + constant ambient, ray cast)";
  gt["scene"]["seed"] = c.seed;
  gt["scene"]["ambient_radiance"] = {s.ambient[0], s.ambient[1], s.ambient[2]};
  if (c.environment) gt["environment"] = c.environmentInfo;
  if (c.windowSun) {
    const cv::Vec3f sky = windowSkyRadiance();
    gt["scene"]["window_sky_radiance"] = {sky[0], sky[1], sky[2]};
  }
  gt["scene"]["box"] = {{"min", {boxLo[0] + c.boxOffset[0], boxLo[1] + c.boxOffset[1], boxLo[2] + c.boxOffset[2]}},
                        {"max", {boxHi[0] + c.boxOffset[0], boxHi[1] + c.boxOffset[1], boxHi[2] + c.boxOffset[2]}}};
  gt["scene"]["materials"] = nlohmann::json::array();
  for (const auto& m : s.materials)
    gt["scene"]["materials"].push_back({{"name", m.name}, {"albedo", {m.albedo[0], m.albedo[1], m.albedo[2]}}});
  t.groundTruth = gt;
  return t;
}

capture::Pose orbitCamera(int i, int n) {
  const double a = (n > 1 ? -0.45 + 0.9 * i / (n - 1) : 0.0);  // radians around the tag
  const cv::Vec3d target(0, kTableTop, 0);
  const cv::Vec3d pos(0.85 * std::sin(a), kTableTop + 0.55 + 0.05 * std::sin(3 * a), 0.85 * std::cos(a));
  return capture::lookAtPose(pos, target);
}

}  // namespace mrgi::evaluation
