#include "runtime/lighting_setup.h"

#include <cstdio>
#include <string>
#include <utility>

#include "capture/error.h"
#include "capture/session.h"
#include "lighting/pipeline.h"
#include "runtime/source.h"

namespace mrgi::runtime {

std::vector<lighting::SceneLight> lightsInMarkerFrame(const std::vector<capture::GroundTruthLight>& lights,
                                                      const capture::Pose& T_world_marker) {
  const capture::Pose T_marker_world = capture::inversePose(T_world_marker);
  const cv::Matx33d R = capture::rotationOf(T_marker_world);
  std::vector<lighting::SceneLight> out;
  for (const capture::GroundTruthLight& l : lights) {
    lighting::SceneLight s;
    s.type = l.type == capture::GroundTruthLight::Type::Point  ? lighting::LightType::Point
             : l.type == capture::GroundTruthLight::Type::Spot ? lighting::LightType::Spot
                                                               : lighting::LightType::Directional;
    s.position = capture::transformPoint(T_marker_world, l.position);
    s.direction = R * l.direction;
    s.intensity = l.intensity;
    s.irradiance = l.irradiance;
    s.spotHalfAngleDeg = l.spotHalfAngleDeg;
    if (s.type != lighting::LightType::Directional) s.extent = l.radius;  // the emitter's sphere
    out.push_back(s);
  }
  return out;
}

LightingSetup markerSetup(const capture::FrameSource& source) {
  LightingSetup setup;
  const capture::SessionManifest* manifest = source.sessionManifest();
  if (manifest && manifest->marker) {
    setup.tagFamily = manifest->marker->family;
    setup.tagSize = manifest->marker->sizeMetres;
    setup.tagId = manifest->marker->id;
    setup.markerGiven = true;
  }
  setup.T_world_marker = groundTruthT_world_marker(source);
  return setup;
}

LightingSetup prepareLighting(lighting::SceneDescription scene, const std::string& sceneFile,
                              const capture::FrameSource& source, const std::string& sourcePath, PoseMode poseMode,
                              bool roomGiven) {
  LightingSetup setup = markerSetup(source);
  setup.scene = std::move(scene);
  const capture::SessionManifest* manifest = source.sessionManifest();
  const capture::GroundTruth* truth = manifest ? &manifest->truth : nullptr;
  // A scene that leaves its lights to the source, which lists none and has no fisheye: the lights come from
  // the room (a saved one, else the one fused from the frames).
  if (!setup.scene.lightsGiven && !(truth && truth->listsLights) && !(manifest && manifest->fisheye)) {
    setup.scene.lightSource = lighting::LightSource::Room;
    setup.lightsFromFusedRoom = !roomGiven;
    std::fprintf(stderr,
                 "note: %s lists no lights and has no fisheye camera: the scene is lit from the room (\"lights\": "
                 "\"auto\"; list lights in the scene file to choose)\n",
                 sourcePath.c_str());
  }
  if (setup.scene.lightSource == lighting::LightSource::Scene) {
    setup.lights = setup.scene.lights;
  } else if (setup.scene.lightSource == lighting::LightSource::Fisheye) {
    if (!manifest || !manifest->fisheye)
      throw capture::CaptureError(sceneFile, "lights: \"fisheye\" but " + sourcePath + " has no fisheye calibration");
    setup.fisheye = manifest->fisheye;
    // Lights come from the environment image, which already holds all the room's light: no extra ambient.
    setup.scene.ambientFromManifest = false;
  } else if (setup.scene.lightSource == lighting::LightSource::Room) {
    // Estimated by the frame pipeline from its room model; the room's radiance holds all the light.
    setup.scene.ambientFromManifest = false;
  } else {
    if (!truth || !truth->listsLights || !setup.T_world_marker)
      throw capture::CaptureError(sceneFile, "lights: \"manifest\" but " + sourcePath +
                                                 " has no ground-truth lights; list the lights in the scene file");
    setup.lights = lightsInMarkerFrame(truth->lights, *setup.T_world_marker);
  }
  setup.ambient = setup.scene.ambientRadiance;
  if (setup.scene.ambientFromManifest && truth && truth->ambientRadiance) setup.ambient = *truth->ambientRadiance;
  if (setup.lights.size() > static_cast<size_t>(lighting::kMaxLights))
    throw capture::CaptureError(setup.scene.lightSource == lighting::LightSource::Scene ? sceneFile : sourcePath,
                                "lights: " + std::to_string(setup.lights.size()) + " lights, at most " +
                                    std::to_string(lighting::kMaxLights) + " are supported");
  if (poseMode == PoseMode::GroundTruth && !setup.T_world_marker)
    throw capture::CaptureError(sourcePath, "--pose ground-truth needs ground_truth.T_world_marker in the manifest");
  return setup;
}

}  // namespace mrgi::runtime
