#pragma once
// The synthetic tabletop scene of `mrgi synth`: a room with differently coloured walls, a table with an
// AprilTag, a box and a point light (or outdoors under an HDR environment); camera path orbiting the tag; a
// fisheye camera on the table looking up.
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "capture/types.h"
#include "groundtruth/scene.h"

namespace mrgi::evaluation {

struct TabletopConfig {
  std::string tagFamily = "tag36h11";
  int tagId = 0;
  double tagSize = 0.16;  ///< black-square edge, metres
  uint64_t seed = 1;
  /// Outdoors: the table stands on open ground under this HDR environment (no room, no point light).
  std::shared_ptr<const groundtruth::EnvironmentMap> environment;
  nlohmann::json environmentInfo;  ///< what the manifest records about it (file, scale)
  cv::Vec3f boxOffset{0, 0, 0};    ///< the box's displacement on the table (world, metres)
  /// A window in the right wall (x = +2 m: z in [-0.5, 0.5] m, y in [1.0, 2.0] m) and the sun shining through it
  /// onto the table: a distant light the cameras never see, only the sunlit patches and shadows it casts.
  bool windowSun = false;
};

/// --window-sun: the sun's direction from the room towards it (world: y up) and its irradiance at normal incidence.
inline cv::Vec3f windowSunTowards() { return cv::normalize(cv::Vec3f(2.0f, 0.78f, 0.12f)); }
inline cv::Vec3f windowSunIrradiance() { return {14.0f, 12.6f, 10.8f}; }
/// --window-sun: the sky's radiance above the horizon, seen and shining through the window (world +y up).
inline cv::Vec3f windowSkyRadiance() { return {0.42f, 0.58f, 0.9f}; }

/// Where the box stands on the table, lower and upper corner (world: y up), before any offset.
inline std::pair<cv::Vec3f, cv::Vec3f> tabletopBox() { return {{0.22f, 0.75f, -0.26f}, {0.37f, 0.90f, -0.11f}}; }
/// Where `mrgi synth --move-box` moves it halfway through: to the front of the table (towards the
/// orbit's second half), clear of the tag.
inline cv::Vec3f movedBoxOffset() { return {0.0f, 0.0f, 0.36f}; }

struct Tabletop {
  groundtruth::Scene scene;
  capture::Pose T_world_marker;
  nlohmann::json groundTruth;  ///< lights, materials, marker pose, as stored in the manifest
};

Tabletop buildTabletop(const TabletopConfig& config);

/// Camera i of n on the orbit: OpenCV camera frame (x right, y down, z forward) in the world.
capture::Pose orbitCamera(int i, int n);

}  // namespace mrgi::evaluation
