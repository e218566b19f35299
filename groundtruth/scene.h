#pragma once
/// Scene description shared by the reference renderer and the synthetic-session generator.
/// World space: metres, right-handed, y up. Colours and albedos are linear RGB.
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "groundtruth/environment.h"

namespace mrgi::groundtruth {

struct Material {
  std::string name;
  cv::Vec3f albedo{0.5f, 0.5f, 0.5f};  ///< diffuse reflectance in [0, 1] per channel
  int texture = -1;                    ///< index into Scene::textures (multiplies albedo), -1 = none
  /// Glossy reflectance of the normalised Phong lobe, as the real-time shading evaluates it:
  /// L = specular * (k + 1)/(2 pi) * cos^k(angle to the mirror direction) * L_in dw (no cos theta_i).
  cv::Vec3f specular{0, 0, 0};
  float exponent = 0;           ///< Phong exponent k
  cv::Vec3f emission{0, 0, 0};  ///< emitted radiance, W/(m^2 sr), from both faces
  bool isVirtual = false;       ///< part of an inserted virtual object (the compositor's mask)
};

enum class LightType { Point, Spot, Directional };

/// A delta light. Point and spot lights may be drawn as a small emissive sphere so cameras can see them.
struct Light {
  cv::Vec3f position;    ///< point/spot
  cv::Vec3f intensity;   ///< point/spot: radiant intensity, W/sr per channel
  float radius = 0.03f;  ///< radius of the visible sphere, metres (0 = invisible); its radiance is I / (pi r^2)
  LightType type = LightType::Point;
  cv::Vec3f direction{0, -1, 0};  ///< spot axis / directional travel direction, unit
  float spotCos = -1;             ///< spot: cosine of the cone's half angle (hard edge)
  cv::Vec3f irradiance{0, 0, 0};  ///< directional: irradiance at normal incidence, W/m^2
};

struct Scene {
  std::vector<cv::Vec3f> vertices;
  std::vector<cv::Vec2f> uvs;  ///< per vertex, texture coordinates (u right, v down)
  /// Per vertex shading normals (interpolated; a triangle whose vertices have zero normals uses its
  /// geometric normal) and albedo multipliers; both resized with the vertices.
  std::vector<cv::Vec3f> normals, vertexAlbedo;
  std::vector<cv::Vec3i> triangles;
  std::vector<int> triangleMaterial;
  std::vector<Material> materials;
  std::vector<cv::Mat> textures;  ///< CV_32FC3 linear RGB, row 0 = v 0
  std::vector<Light> lights;
  cv::Vec3f ambient{0, 0,
                    0};  ///< ray caster only: constant radiance added as albedo * ambient (a crude bounce stand-in)
  cv::Vec3f environment{0, 0, 0};  ///< path tracer: radiance of every ray that leaves the scene
  /// Path tracer: an HDR environment added to `environment` (importance-sampled, MIS with the BRDF).
  std::shared_ptr<const EnvironmentMap> environmentMap;

  int addMaterial(Material m);
  /// Appends a triangle mesh moved by T (4x4, metres) with smooth normals (rotated by T) and one material.
  void addMesh(const std::vector<cv::Vec3f>& positions, const std::vector<cv::Vec3f>& meshNormals,
               const std::vector<uint32_t>& indices, int material, const cv::Matx44d& T = cv::Matx44d::eye());
  /// Quad p0, p0+e1, p0+e1+e2, p0+e2 with uv (0,0) at p0, u along e1, v along e2; normal e1 x e2.
  void addQuad(cv::Vec3f p0, cv::Vec3f e1, cv::Vec3f e2, int material);
  /// Axis-aligned box [lo, hi], faces pointing outwards (or inwards when inward = true: a room).
  void addBox(cv::Vec3f lo, cv::Vec3f hi, int material, bool inward = false);
};

}  // namespace mrgi::groundtruth
