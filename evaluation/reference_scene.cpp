#include "evaluation/reference_scene.h"

#include <algorithm>
#include <memory>

#include "groundtruth/environment.h"
#include "lighting/material.h"
#include "lighting/sh.h"

namespace mrgi::evaluation {

namespace ref = groundtruth;

void addVirtualObjects(const std::vector<lighting::VirtualObject>& objects, const capture::Pose& T_world_marker,
                       ref::Scene& scene) {
  for (const auto& o : objects) {
    ref::Material m;
    m.name = o.model;
    m.albedo = o.material.albedo;
    m.specular = cv::Vec3f::all(o.material.specular);
    m.exponent = lighting::phongExponent(o.material.roughness);
    m.isVirtual = true;
    scene.addMesh(o.mesh.positions, o.mesh.normals, o.mesh.indices, scene.addMaterial(m),
                  T_world_marker * o.T_marker_object);
  }
}

std::vector<ref::Light> referenceLights(const std::vector<lighting::SceneLight>& lights) {
  std::vector<ref::Light> out;
  for (const auto& l : lights) {
    ref::Light r;
    r.radius = 0;
    r.position = cv::Vec3f(l.position);
    r.direction = cv::Vec3f(l.direction);
    r.intensity = cv::Vec3f(l.intensity);
    r.irradiance = cv::Vec3f(l.irradiance);
    r.spotCos = static_cast<float>(l.spotCos());
    r.type = l.type == lighting::LightType::Directional ? ref::LightType::Directional
             : l.type == lighting::LightType::Spot      ? ref::LightType::Spot
                                                        : ref::LightType::Point;
    out.push_back(r);
  }
  return out;
}

ReferenceScenes reconstructedScenes(const runtime::LightingSetup& setup, const runtime::RealSurface& real,
                                    const capture::Intrinsics& intrinsics, const capture::Pose& T_marker_camera) {
  ReferenceScenes out;
  ref::Scene& s = out.realOnly;
  const int realMaterial = s.addMaterial({"real", {1, 1, 1}});  // the albedo is per vertex
  std::vector<cv::Vec3f> positions, normals;
  for (const auto& v : real.vertices) positions.push_back(v.position), normals.push_back(v.normal);
  s.addMesh(positions, normals, real.indices, realMaterial);
  for (size_t i = 0; i < real.vertices.size(); ++i) s.vertexAlbedo[i] = real.vertices[i].albedo;
  s.lights = referenceLights(setup.lights);
  s.environment = cv::Vec3f(setup.ambient);
  if (std::any_of(setup.ambientSh.begin(), setup.ambientSh.end(),
                  [](const cv::Vec3d& c) { return c != cv::Vec3d(0, 0, 0); })) {
    // A directional ambient (a fisheye's or the room's remainder) as the shading pass adds it: the uniform
    // part and SH bands 1-2 as one environment map (clamped at 0: radiance is never negative).
    cv::Mat map(64, 128, CV_32FC3);
    for (int y = 0; y < map.rows; ++y)
      for (int x = 0; x < map.cols; ++x) {
        const cv::Vec3f d = ref::EnvironmentMap::directionOf((x + 0.5f) / map.cols, (y + 0.5f) / map.rows);
        double basis[9];
        lighting::sh::evaluate(cv::Vec3d(d), 3, basis);
        cv::Vec3d L = setup.ambient;
        for (int k = 1; k < 9; ++k) L += basis[k] * setup.ambientSh[static_cast<size_t>(k)];
        map.at<cv::Vec3f>(y, x) = cv::Vec3f(L);
      }
    s.environment = {0, 0, 0};
    s.environmentMap = std::make_shared<const ref::EnvironmentMap>(map);
  }

  out.withObjects = s;
  addVirtualObjects(setup.scene.objects, capture::identityPose(), out.withObjects);
  out.camera.intrinsics = intrinsics;
  out.camera.T_world_camera = T_marker_camera;
  return out;
}

}  // namespace mrgi::evaluation
