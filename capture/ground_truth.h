#pragma once
/// The typed ground truth a session may carry (manifest "ground_truth", recordings/FORMAT.md), read in one
/// place: where the marker sits in the world, the lights of every type, the ambient radiance, the environment
/// map's description and the true reference composites. Per-frame camera poses travel with the frames
/// (Frame::groundTruthT_world_camera). World frame = the generator's (metres, linear RGB).
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "capture/types.h"

namespace mrgi::capture {

struct GroundTruthLight {
  enum class Type { Point, Spot, Directional };
  Type type = Type::Point;
  cv::Vec3d position{0, 0, 0};    ///< point/spot, world, metres
  cv::Vec3d direction{0, 0, -1};  ///< spot axis / directional travel direction (into the scene), unit
  cv::Vec3d intensity{0, 0, 0};   ///< point/spot: W/sr per channel
  cv::Vec3d irradiance{0, 0, 0};  ///< directional: W/m^2 at normal incidence
  double spotHalfAngleDeg = 45;
  double radius = 0;              ///< emitter radius (metres) the generator rendered, 0 = a delta light
};

/// Where the session's true reference composites are (patterns relative to the session, NNNNNN = the frame
/// index) and the scene file (relative to the session) whose objects they show.
struct GroundTruthReference {
  std::string scene, composite, delta, mask;
  /// The file of `pattern` for frame `index`, under `sessionDir`.
  static std::string pathFor(const std::string& sessionDir, const std::string& pattern, int64_t index);
};

struct GroundTruth {
  std::optional<Pose> T_world_marker;
  std::vector<GroundTruthLight> lights;
  bool listsLights = false;  ///< the manifest lists its lights (possibly none: lit by an environment alone)
  std::optional<cv::Vec3d> ambientRadiance;  ///< W/m^2/sr
  std::optional<GroundTruthReference> reference;
  nlohmann::json environment;  ///< the environment map's description ({"file", "mapping", "scale"}), null if none

  /// Parses and checks a manifest's "ground_truth" object; errors name the file and the key
  /// ("ground_truth.lights[0].type"). An unknown light type is an error, never dropped.
  static GroundTruth fromJson(const nlohmann::json& j, const std::string& fileForErrors);
};

}  // namespace mrgi::capture
