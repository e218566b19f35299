#pragma once
// Shared GL test scenes of the lighting pipeline tests: a z-up lighting world with a grey floor z = 0,
// optionally a red wall at x = -0.5, and a white virtual cube; a camera above and the usual lights.
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "gl/context.h"
#include "lighting/pipeline.h"
#include "lighting/scene_file.h"
#include "lighting/techniques/registry.h"

namespace mrgi::test {

using lighting::CameraView;
using lighting::InputFrame;
using lighting::LightingPipeline;
using lighting::MeshVertex;
using lighting::PipelineConfig;
using lighting::SceneLight;
using lighting::VirtualObject;

inline std::unique_ptr<gl::Context> makeContext() {
  gl::ContextConfig cfg;
  cfg.width = 64;
  cfg.height = 64;
  return gl::createContext(cfg);
}

/// Quad p0, p0+e1, p0+e1+e2, p0+e2, normal e1 x e2, subdivided n x n (so the real mesh resembles a depth mesh).
inline void addQuad(std::vector<MeshVertex>& v, std::vector<uint32_t>& idx, cv::Vec3f p0, cv::Vec3f e1, cv::Vec3f e2,
                    cv::Vec3f albedo, int n = 8) {
  appendGridQuad(v, idx, p0, e1, e2, albedo, n);
}

const cv::Vec3f kFloorAlbedo(0.5f, 0.5f, 0.5f);
const cv::Vec3f kRed(0.8f, 0.1f, 0.1f);

struct TestScene {
  std::vector<MeshVertex> vertices;
  std::vector<uint32_t> indices;
  std::vector<VirtualObject> objects;
};

/// Floor 2 x 2 m around the origin, optionally the red wall, and a white cube of side `cube` centred at `at`.
inline TestScene makeScene(bool wall, double cube, cv::Vec3d at) {
  TestScene s;
  addQuad(s.vertices, s.indices, {-1, -1, 0}, {2, 0, 0}, {0, 2, 0}, kFloorAlbedo, 16);
  if (wall) addQuad(s.vertices, s.indices, {-0.5f, -1, 0}, {0, 2, 0}, {0, 0, 1.5f}, kRed, 16);
  if (cube > 0) {
    VirtualObject o;
    o.mesh = lighting::loadMesh(std::string(MRGI_SOURCE_DIR) + "/recordings/models/cube.obj");
    for (auto& p : o.mesh.positions) p *= static_cast<float>(cube);
    o.mesh.computeBounds();
    o.material.albedo = {0.9f, 0.9f, 0.9f};
    o.T_marker_object = capture::makePose(cv::Matx33d::eye(), at);
    s.objects.push_back(std::move(o));
  }
  return s;
}

/// G-buffer size, volume resolution (the "lpv" group's) and RSM size of a test, with `technique`; the other
/// knobs keep their defaults.
inline PipelineConfig testConfig(int width, int height, int resolution, int rsmSize,
                                 const std::string& technique = "dlpv") {
  PipelineConfig cfg;
  cfg.width = width;
  cfg.height = height;
  cfg.technique = lighting::parseTechniqueChoice(technique, &cfg.knobs);
  cfg.set("lpv", "resolution", resolution);
  cfg.set("frame", "rsm_size", rsmSize);
  return cfg;
}

/// Every technique spelling the registry knows: each name, each alias, each real + virtual pairing.
inline std::vector<std::string> allTechniqueSpellings() {
  std::vector<std::string> out = lighting::techniqueSpellings();
  for (const auto& r : lighting::techniques())
    for (const auto& v : lighting::techniques())
      if (&r != &v && r.real && v.virtualObject) out.push_back(r.name + "+" + v.name);
  return out;
}

/// A test-name-friendly spelling ("dlpv+kinect-val" -> "dlpv_kinect_val").
inline std::string testName(std::string n) {
  for (char& c : n)
    if (c == '-' || c == '+') c = '_';
  return n;
}

/// A pipeline over the scene's virtual objects with its real mesh set.
inline LightingPipeline makePipeline(const PipelineConfig& cfg, const TestScene& s) {
  LightingPipeline pipe(cfg, s.objects);
  pipe.setRealMesh(s.vertices, s.indices);
  return pipe;
}

inline CameraView topCamera(int w, int h) {
  CameraView c;
  c.intrinsics = {w, h, 0.9 * w, 0.9 * w, 0.5 * w - 0.5, 0.5 * h - 0.5};
  c.T_world_camera = capture::lookAtPose({0.0, -0.25, 1.6}, {0, 0, 0});
  return c;
}

/// 96 x 72, looking from the front right at a cube next to the red wall (makeScene(true, ..., {-0.36, 0, 0.06})).
inline CameraView wallCamera() {
  CameraView c;
  const int w = 96, h = 72;
  c.intrinsics = {w, h, 1.2 * w, 1.2 * w, 0.5 * w - 0.5, 0.5 * h - 0.5};
  c.T_world_camera = capture::lookAtPose({0.35, -0.6, 0.45}, {-0.25, 0.0, 0.05});
  return c;
}

/// A 2 W/sr lamp 0.9 m over the floor, in front of the wall.
inline std::vector<SceneLight> wallLamp() {
  SceneLight l;
  l.type = lighting::LightType::Point;
  l.position = {0.1, -0.2, 0.9};
  l.intensity = {2.0, 2.0, 2.0};
  return {l};
}

inline SceneLight sunDown(double e = 10.0) {
  SceneLight l;
  l.type = lighting::LightType::Directional;
  l.direction = {0, 0, -1};
  l.irradiance = {e, e, e};
  return l;
}

inline SceneLight pointAbove() {
  SceneLight l;
  l.type = lighting::LightType::Point;
  l.position = {0.3, 0.2, 1.2};
  l.intensity = {5, 5, 5};
  return l;
}

/// The sun from above, aslant (8 W/m^2).
inline SceneLight obliqueSun() {
  SceneLight l = sunDown(8.0);
  l.direction = cv::normalize(cv::Vec3d(0.5, 0.3, -0.8));
  return l;
}

/// pointAbove() moved to `position` as a sphere lamp of radius `extent` metres (soft shadows).
inline SceneLight sphereLamp(cv::Vec3d position = {-0.4, -0.3, 0.5}, double extent = 0.25) {
  SceneLight l = pointAbove();
  l.position = position;
  l.extent = extent;
  return l;
}

/// A wall of real surface seen head-on, as a technique's input builder takes a frame (technique_input.h): the
/// plane x = -0.5 facing +x over y in [-1, 1], z in [0, 1.5], of uniform exitance (W/m^2) in red and a tenth of
/// it in green and blue (radiance exitance / pi), from a 32 x 24 camera at x = 1.
inline InputFrame wallFrame(float exitance) {
  InputFrame f;
  const int w = 32, h = 24;
  const double d = 1.5, focal = 24.0;
  f.intrinsics = {w, h, focal, focal, (w - 1) / 2.0, (h - 1) / 2.0};
  f.positions.create(h, w, CV_32FC3);
  f.normals.create(h, w, CV_32FC3);
  const float L = exitance / static_cast<float>(CV_PI);
  f.radiance = cv::Mat(h, w, CV_32FC3, cv::Scalar(L, 0.1f * L, 0.1f * L));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      f.positions.at<cv::Vec3f>(y, x) =
          cv::Vec3f(static_cast<float>((x - f.intrinsics.cx) / focal * d),
                    static_cast<float>((y - f.intrinsics.cy) / focal * d), static_cast<float>(d));
      f.normals.at<cv::Vec3f>(y, x) = {0, 0, -1};
    }
  // Camera x = world y, camera y (down) = world -z, camera z (forward) = world -x.
  f.T_world_camera = capture::Pose(0, 0, -1, 1.0, 1, 0, 0, 0, 0, -1, 0, 0.75, 0, 0, 0, 1);
  return f;
}

/// Builds every technique's own input (if it has one) from `frame` and hands it to the pipeline; false when no
/// technique in use takes one.
inline bool setTechniqueInputs(LightingPipeline& pipe, const InputFrame& frame) {
  auto builders = pipe.inputBuilders();
  for (auto& [name, builder] : builders) pipe.setTechniqueInput(name, builder->fromFrame(frame));
  return !builders.empty();
}

inline float lum(const cv::Vec4f& v) { return 0.2126f * v[0] + 0.7152f * v[1] + 0.0722f * v[2]; }

/// Whether the ray from p towards the light (against `dir`) hits the axis-aligned box of half side h at c.
inline bool inShadow(const cv::Vec3d& p, const cv::Vec3d& dir, const cv::Vec3d& c, double h) {
  double t0 = 0, t1 = 1e9;
  for (int k = 0; k < 3; ++k) {
    const double d = -dir[k];
    if (std::abs(d) < 1e-12) {
      if (std::abs(p[k] - c[k]) > h) return false;
      continue;
    }
    double a = (c[k] - h - p[k]) / d, b = (c[k] + h - p[k]) / d;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t0 <= t1;
}

}  // namespace mrgi::test
