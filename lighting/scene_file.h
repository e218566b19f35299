#pragma once
/// Scene files: which virtual objects go where (relative to the marker), their materials, the lights and
/// the lighting technique with its knobs. JSON; every error names the file and the offending key.
///
/// Frames: "marker" = the tag frame (origin at the tag centre, z out of the tag, x along its first edge,
/// metres). The lighting world of `mrgi replay` is the marker frame: the tag is fixed in the room, so the
/// volume stays axis-aligned in a frame that does not move with the camera.
#include <cmath>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "capture/error.h"
#include "lighting/knobs.h"

namespace mrgi::lighting {

/// The ranges of an object's placement, the same in a scene file and on insert's flags.
struct ValueRange {
  double lo, hi;
};
inline constexpr ValueRange kObjectScale{1e-6, 1e6};
inline constexpr ValueRange kObjectTranslateM{-1e3, 1e3};
inline constexpr ValueRange kObjectRotateDeg{-3600, 3600};
inline constexpr ValueRange kAlbedo{0, 1};

/// Bad scene file or model: "path: key: problem" (the one input-error class, capture/error.h).
using SceneError = capture::InputError;

/// A triangle mesh in its model frame (metres after the scene's scale).
struct Mesh {
  std::vector<cv::Vec3f> positions;
  std::vector<cv::Vec3f> normals;  ///< unit, per vertex
  std::vector<uint32_t> indices;   ///< triangles
  cv::Vec3f boundsMin{0, 0, 0}, boundsMax{0, 0, 0};
  size_t triangleCount() const { return indices.size() / 3; }
  void computeBounds();
};

/// Loads OBJ, PLY, glTF/GLB (anything assimp reads): all meshes of the file in their node transforms,
/// triangulated, smooth normals generated where missing. Throws SceneError naming the file when it cannot
/// be read or holds no triangles.
Mesh loadMesh(const std::string& path);

struct Material {
  cv::Vec3f albedo{0.8f, 0.8f, 0.8f};  ///< diffuse reflectance, linear RGB in [0, 1]
  float roughness = 1.0f;              ///< [0, 1]; Phong exponent k = 2/r² − 2 for the glossy lobe (Kinect-VAL)
  float specular = 0.0f;               ///< glossy reflectance in [0, 1], albedo + specular ≤ 1 per channel
};

struct VirtualObject {
  std::string model;  ///< resolved path
  Mesh mesh;          ///< already scaled
  cv::Matx44d T_marker_object = cv::Matx44d::eye();
  Material material;
};

enum class LightType { Point, Spot, Directional };

/// A light in the lighting world (marker frame).
struct SceneLight {
  LightType type = LightType::Point;
  cv::Vec3d position{0, 0, 0};    ///< point/spot, metres
  cv::Vec3d direction{0, 0, -1};  ///< spot axis / directional travel direction (from the light into the scene), unit
  cv::Vec3d intensity{0, 0, 0};   ///< point/spot: radiant intensity, W/sr per channel
  cv::Vec3d irradiance{0, 0, 0};  ///< directional: irradiance at normal incidence, W/m^2 per channel
  double spotHalfAngleDeg = 45;   ///< spot: cone half angle
  double spotCos() const { return std::cos(spotHalfAngleDeg * CV_PI / 180.0); }
  bool operator==(const SceneLight&) const = default;
};

/// Where lights come from: listed in the scene file, the ground truth stored in a session's manifest, or
/// estimated per fisheye frame of the session (solid-angle-weighted median cut -> directional lights).
/// or estimated from the room model (--room) as seen from the virtual objects (reconstruction/room_lights.h).
enum class LightSource { Scene, Manifest, Fisheye, Room };

/// The lighting techniques of a scene by role (lighting/techniques/registry.h parses and lists them):
/// "none" = no technique for that role (real pixels then get only the object's direct shadow, the object
/// only its direct light and ambient).
struct TechniqueChoice {
  std::string real = "none", virtualObject = "none";
  std::string name;  ///< how the scene spelled it ("dlpv+kinect-val"), or the canonical name of the roles
  bool operator==(const TechniqueChoice& o) const { return real == o.real && virtualObject == o.virtualObject; }
};

struct SceneDescription {
  std::string path;
  std::vector<VirtualObject> objects;
  LightSource lightSource = LightSource::Manifest;
  bool lightsGiven = false;        ///< the file says where lights come from ("lights"); else the source decides
  std::vector<SceneLight> lights;  ///< for LightSource::Scene
  int fisheyeLightCount = 16;      ///< for LightSource::Fisheye: median-cut lights (1..16)
  /// For LightSource::Room: lights from the split (1..16), the gain on saturated radiance (0 = estimated
  /// with the white-patch assumption) and that assumption's albedo.
  int roomLightCount = 4;
  double roomSaturatedGain = 0;
  double roomWhiteAlbedo = 0.8;
  cv::Vec3d ambientRadiance{0, 0, 0};  ///< uniform environment radiance lighting the virtual object (W/m^2/sr)
  bool ambientFromManifest = true;     ///< take ambient from the manifest when it has one
  /// The world the objects are placed in: the marker frame (none: the default), or, for a recording without
  /// a marker, the world its first frame founded ("world": {"first_frame_T_world_camera": [16 numbers]}:
  /// that frame's camera pose in it, row-major; mrgi insert writes it, replay places the first frame there).
  std::optional<cv::Matx44d> firstFrameT_world_camera;
  TechniqueChoice technique;  ///< default: the registry's first technique
  /// Knob values by group ("frame" and each technique's section), every declared knob present.
  KnobSet knobs;
};

/// Parses and validates a scene file; model paths are relative to the scene file. Throws SceneError.
SceneDescription loadScene(const std::string& path);
/// Same from a JSON text (path used in messages and to resolve models).
SceneDescription parseScene(const std::string& text, const std::string& path);

// Writing scene files (mrgi insert): the document is edited as JSON, checked by the parser, and written whole.

/// A scene file's document, checked by parseScene (errors name the key). Throws SceneError.
nlohmann::json readSceneDocument(const std::string& path);
/// Rewrites the document's relative model paths, relative to the scene file `from`, relative to `to`'s folder.
void rebaseModelPaths(nlohmann::json& doc, const std::string& from, const std::string& to);
/// Writes the document atomically (indented; the folder must exist).
void writeSceneDocument(const std::string& path, const nlohmann::json& doc);
/// Euler angles in degrees of R = Rz Ry Rx, the inverse of an object's "rotate_deg" (x, then y, then z about the
/// marker's axes); in gimbal lock (y = +-90 degrees) x is 0.
cv::Vec3d eulerDegrees(const cv::Matx33d& R);

}  // namespace mrgi::lighting
