#pragma once
// What lights a session's frames besides the frames themselves: the scene, the marker and the lights,
// resolved once against the source (its manifest's marker and ground truth, or its fisheye calibration).
#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame_source.h"
#include "capture/ground_truth.h"
#include "lighting/radiance_map.h"
#include "lighting/scene_file.h"
#include "runtime/pose_source.h"

namespace mrgi::runtime {

/// What the lighting path needs besides the frames: the scene, the marker and the lights.
struct LightingSetup {
  lighting::SceneDescription scene;
  std::string tagFamily = "tag36h11";
  double tagSize = 0.16;
  int tagId = -1;
  bool markerGiven =
      false;  ///< the source's manifest names its marker; without one a first frame without a tag founds the world
  std::vector<lighting::SceneLight> lights;  ///< marker frame
  cv::Vec3d ambient{0, 0, 0};
  /// The ambient's directional part: radiance as SH bands 1-2 (band 0 is `ambient`; lighting/sh.h
  /// convention, lighting world), from a fisheye's or the room's remainder after its lights; zero otherwise.
  std::array<cv::Vec3d, 9> ambientSh{};
  /// The same ambient over every direction as a lat-long map (the room's remainder after its lights, seen from the
  /// objects): what the objects hide of it is read across the caps they cover (lighting/object_shadow.h). Null:
  /// the SH alone.
  std::shared_ptr<const lighting::RadianceMap> ambientMap;
  std::optional<capture::Pose> T_world_marker;  ///< ground truth, for --pose ground-truth
  /// Takes a scene edited after the setup was resolved (objects placed, knobs moved) with its lights still coming
  /// from where the setup resolved them ("auto": the room, the fisheye, the manifest).
  void useEditedScene(lighting::SceneDescription edited) {
    edited.lightSource = scene.lightSource;
    edited.ambientFromManifest = scene.ambientFromManifest;
    if (scene.lightSource != lighting::LightSource::Scene) edited.lights = scene.lights;
    scene = std::move(edited);
  }
  /// The marker the setup's source carries (family, size, id).
  MarkerSpec marker() const { return {tagFamily, tagSize, tagId}; }
  std::optional<capture::FisheyeCalibration> fisheye;  ///< lights estimated per fisheye frame
  /// The scene leaves its lights to the source ("lights": "auto" or no "lights"), which lists none, has no
  /// fisheye and was given no room: the lights come from a room fused from the recording (as the frames come
  /// in replay and live; before the preview in insert). The caller fuses it.
  bool lightsFromFusedRoom = false;
};

/// The marker of a source (family, size, id from its manifest) and its ground-truth T_world_marker: what
/// the measuring half of a FramePipeline needs for camera poses, without a scene; prepareLighting starts
/// from it.
LightingSetup markerSetup(const capture::FrameSource& source);

/// A session's ground-truth lights (world frame, every type) in the marker frame, a lamp with its radius.
std::vector<lighting::SceneLight> lightsInMarkerFrame(const std::vector<capture::GroundTruthLight>& lights,
                                                      const capture::Pose& T_world_marker);

/// Resolves a loaded scene against a source (marker from the manifest, lights from the scene, the
/// manifest's ground truth or its fisheye calibration). `sceneFile` and `sourcePath` name the culprit in
/// errors; PoseMode::GroundTruth needs the manifest's T_world_marker.
/// `roomGiven`: a room model will light the frames; a scene that does not say where its lights come from
/// then takes them from the room when the source lists none and has no fisheye (without a room:
/// lightsFromFusedRoom, said once on stderr).
LightingSetup prepareLighting(lighting::SceneDescription scene, const std::string& sceneFile,
                              const capture::FrameSource& source, const std::string& sourcePath, PoseMode poseMode,
                              bool roomGiven = false);

}  // namespace mrgi::runtime
