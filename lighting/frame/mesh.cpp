#include "lighting/frame/mesh.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "gl/error.h"

namespace mrgi::lighting {

// ---------------------------------------------------------------------------------------------- meshes

GpuMesh::GpuMesh(const std::vector<MeshVertex>& vertices, const std::vector<uint32_t>& indices)
    : count_(static_cast<GLsizei>(indices.size())) {
  if (indices.empty()) return;
  static_assert(sizeof(MeshVertex) == 9 * sizeof(float));
  vertices_ = gl::Buffer(static_cast<GLsizeiptr>(vertices.size() * sizeof(MeshVertex)), vertices.data(), 0);
  indices_ = gl::Buffer(static_cast<GLsizeiptr>(indices.size() * sizeof(uint32_t)), indices.data(), 0);
  vao_.attribute(0, vertices_, 0, sizeof(MeshVertex), 3);
  vao_.attribute(1, vertices_, 3 * sizeof(float), sizeof(MeshVertex), 3);
  vao_.attribute(2, vertices_, 6 * sizeof(float), sizeof(MeshVertex), 3);
  vao_.elements(indices_);
}

void GpuMesh::draw() const {
  if (count_ == 0) return;
  vao_.bind();
  glDrawElements(GL_TRIANGLES, count_, GL_UNSIGNED_INT, nullptr);
}

void appendGridQuad(std::vector<MeshVertex>& vertices, std::vector<uint32_t>& indices, const cv::Vec3f& p0,
                    const cv::Vec3f& e1, const cv::Vec3f& e2, const cv::Vec3f& albedo, int n) {
  n = std::max(n, 1);
  const cv::Vec3f normal = cv::normalize(e1.cross(e2));
  const auto base = static_cast<uint32_t>(vertices.size());
  const auto un = static_cast<uint32_t>(n);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      vertices.push_back({p0 + e1 * (static_cast<float>(i) / n) + e2 * (static_cast<float>(j) / n), normal, albedo});
  for (uint32_t j = 0; j < un; ++j)
    for (uint32_t i = 0; i < un; ++i) {
      const uint32_t a = base + j * (un + 1) + i, b = a + 1, c = a + un + 2, d = a + un + 1;
      indices.insert(indices.end(), {a, b, c, a, c, d});
    }
}

void buildRealVertices(const reconstruction::DepthMesh& mesh, const cv::Mat& albedo,
                       const capture::Pose& T_world_camera, std::vector<MeshVertex>& vertices,
                       std::vector<uint32_t>& indices) {
  const cv::Matx33d R = capture::rotationOf(T_world_camera);
  // Vertices whose depth normal is unknown (isolated samples, edges) take the area-weighted normal of their
  // triangles, turned towards the camera; a zero normal would shade as NaN.
  std::vector<cv::Vec3f> normals = mesh.normals;
  std::vector<cv::Vec3f> faceSum(mesh.positions.size(), cv::Vec3f(0, 0, 0));
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
    const cv::Vec3f f = (mesh.positions[b] - mesh.positions[a]).cross(mesh.positions[c] - mesh.positions[a]);
    for (uint32_t i : {a, b, c}) faceSum[i] += f;
  }
  for (size_t i = 0; i < normals.size(); ++i) {
    if (normals[i] != cv::Vec3f(0, 0, 0)) continue;
    cv::Vec3f n = faceSum[i];
    const float len = static_cast<float>(cv::norm(n));
    if (!(len > 0)) n = -mesh.positions[i];  // no triangle: face the camera
    n = cv::normalize(n);
    if (n.dot(mesh.positions[i]) > 0) n = -n;
    normals[i] = n;
  }
  vertices.resize(mesh.positions.size());
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    MeshVertex& v = vertices[i];
    v.position = cv::Vec3f(capture::transformPoint(T_world_camera, cv::Vec3d(mesh.positions[i])));
    v.normal = cv::Vec3f(R * cv::Vec3d(normals[i]));
    v.albedo = {0.5f, 0.5f, 0.5f};
    if (!albedo.empty()) {
      const int x = std::clamp(static_cast<int>(std::lround(mesh.pixels[i][0])), 0, albedo.cols - 1);
      const int y = std::clamp(static_cast<int>(std::lround(mesh.pixels[i][1])), 0, albedo.rows - 1);
      v.albedo = albedo.at<cv::Vec3f>(y, x);
    }
  }
  indices = mesh.indices;
}

// ---------------------------------------------------------------------------------------------- cameras

cv::Matx44d projectionFromIntrinsics(const capture::Intrinsics& k, double n, double f) {
  const double W = k.width, H = k.height;
  return {2 * k.fx / W,
          0,
          2 * (k.cx + 0.5) / W - 1,
          0,  //
          0,
          2 * k.fy / H,
          2 * (k.cy + 0.5) / H - 1,
          0,  //
          0,
          0,
          (f + n) / (f - n),
          -2 * f * n / (f - n),  //
          0,
          0,
          1,
          0};
}

cv::Matx44d orthographicProjection(double h, double n, double f) {
  return {1 / h, 0,     0,           0,                   //
          0,     1 / h, 0,           0,                   //
          0,     0,     2 / (f - n), -(f + n) / (f - n),  //
          0,     0,     0,           1};
}

std::array<float, 16> toGl(const cv::Matx44d& m) {
  std::array<float, 16> out;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) out[c * 4 + r] = static_cast<float>(m(r, c));
  return out;
}

cv::Matx33f normalMatrix(const cv::Matx44d& T) {
  const cv::Matx33d R = capture::rotationOf(T);
  return cv::Matx33f(R.inv().t());
}

void setMat3(const gl::Program& p, const std::string& name, const cv::Matx33f& m) {
  float cm[9];
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) cm[c * 3 + r] = m(r, c);
  glProgramUniformMatrix3fv(p.id(), p.location(name), 1, GL_FALSE, cm);
}

void setVec3(const gl::Program& p, const std::string& name, const cv::Vec3d& v) {
  p.set(name, static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
}

int shaderLightType(LightType t) { return t == LightType::Point ? 0 : t == LightType::Spot ? 1 : 2; }

std::optional<gl::Profiler::Scope> timed(gl::Profiler* profiler, const char* name, bool gpu) {
  return profiler ? std::optional<gl::Profiler::Scope>(std::in_place, *profiler, name, gpu) : std::nullopt;
}

cv::Mat download4(const gl::Texture& t) {
  cv::Mat m(t.height(), t.width(), CV_32FC4);
  t.download(GL_RGBA, GL_FLOAT, m.ptr(), static_cast<GLsizei>(m.total() * m.elemSize()), 4);
  return m;
}

}  // namespace mrgi::lighting
