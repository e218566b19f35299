#pragma once
/// The scene's data model: virtual objects (mesh, material, placement relative to the marker), lights, where
/// lights come from, the technique chosen per role and every knob. Scene files (lighting/scene_file.h) parse
/// into it; the frame, the techniques and the registry read it. It sits below them all and holds no GL.
///
/// Frames: "marker" = the tag frame (origin at the tag centre, z out of the tag, x along its first edge,
/// metres). The lighting world of `mrgi replay` is the marker frame.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

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

/// A triangle mesh in its model frame (metres after the scene's scale).
struct Mesh {
  std::vector<cv::Vec3f> positions;
  std::vector<cv::Vec3f> normals;  ///< unit, per vertex
  std::vector<uint32_t> indices;   ///< triangles
  cv::Vec3f boundsMin{0, 0, 0}, boundsMax{0, 0, 0};
  size_t triangleCount() const { return indices.size() / 3; }
  void computeBounds();
};

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
  /// Extent, for the irradiance near and below a surface's horizon (lighting/direct_light.glsl): directional,
  /// the half-angle of the disc of sky it stands for (radians); point/spot, the radius of the sphere it stands
  /// for (metres). 0: a point (direction). `irradiance`/`intensity` keep their meaning (normal incidence).
  double extent = 0;
  /// sin of the half-angle the light is seen under from distance `d` (directional: any d).
  double sinAngularRadius(double d) const {
    if (!(extent > 0)) return 0;
    if (type == LightType::Directional) return std::sin(std::min(extent, 1.5));
    return d > extent ? extent / d : 1.0;
  }
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

}  // namespace mrgi::lighting
