#pragma once
/// Scene description shared by the reference renderer and the synthetic-session generator.
/// World space: metres, right-handed, y up. Colours and albedos are linear RGB.
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace mrgi::lighting::reference {

struct Material {
  std::string name;
  cv::Vec3f albedo{0.5f, 0.5f, 0.5f};  ///< diffuse reflectance in [0, 1] per channel
  int texture = -1;                    ///< index into Scene::textures (multiplies albedo), -1 = none
};

/// An isotropic point light drawn as a small emissive sphere (so cameras can see it).
struct PointLight {
  cv::Vec3f position;
  cv::Vec3f intensity;   ///< radiant intensity, W/sr per channel
  float radius = 0.03f;  ///< radius of the visible sphere, metres; its radiance is I / (pi r^2)
};

struct Scene {
  std::vector<cv::Vec3f> vertices;
  std::vector<cv::Vec2f> uvs;  ///< per vertex, texture coordinates (u right, v down)
  std::vector<cv::Vec3i> triangles;
  std::vector<int> triangleMaterial;
  std::vector<Material> materials;
  std::vector<cv::Mat> textures;  ///< CV_32FC3 linear RGB, row 0 = v 0
  std::vector<PointLight> lights;
  cv::Vec3f ambient{0, 0, 0};  ///< constant radiance added as albedo * ambient (a crude bounce stand-in)

  int addMaterial(Material m);
  /// Quad p0, p0+e1, p0+e1+e2, p0+e2 with uv (0,0) at p0, u along e1, v along e2; normal e1 x e2.
  void addQuad(cv::Vec3f p0, cv::Vec3f e1, cv::Vec3f e2, int material);
  /// Axis-aligned box [lo, hi], faces pointing outwards (or inwards when inward = true: a room).
  void addBox(cv::Vec3f lo, cv::Vec3f hi, int material, bool inward = false);
};

}  // namespace mrgi::lighting::reference
