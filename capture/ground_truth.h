#pragma once
/// The typed ground truth a session may carry (manifest "ground_truth", recordings/FORMAT.md), read in one
/// place: where the marker sits in the world, the lights of every type, the ambient radiance, the environment
/// map's description and the true reference composites. Per-frame camera poses travel with the frames
/// (Frame::groundTruthT_world_camera). World frame = the generator's (metres, linear RGB).
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/types.h"

namespace mrgi::capture {

/// Where the session's true reference composites are (patterns relative to the session, NNNNNN = the frame
/// index) and the scene file (relative to the session) whose objects they show.
struct GroundTruthReference {
  std::string scene, composite, delta, mask;
  /// The file of `pattern` for frame `index`, under `sessionDir`.
  static std::string pathFor(const std::string& sessionDir, const std::string& pattern, int64_t index);
};

/// Parses a JSON array of lights (the manifest's "ground_truth.lights", a frame's "lights"); errors name
/// `file` and the key (`key` + "[i].type"). An unknown light type is an error, never dropped.
std::vector<GroundTruthLight> lightsFromJson(const nlohmann::json& array, const std::string& file,
                                             const std::string& key);
/// The same array as the parser reads it.
nlohmann::json lightsToJson(const std::vector<GroundTruthLight>& lights);

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
