#pragma once
/// What the frame's passes draw with: the mesh vertex and a mesh on the GPU, the real scene's mesh from a depth
/// mesh, the camera and its matrices, and the small helpers every pass uses (uniforms of matrices and vectors,
/// timed stages, texture downloads).
#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/types.h"
#include "gl/objects.h"
#include "gl/profiler.h"
#include "gl/program.h"
#include "lighting/scene.h"
#include "reconstruction/depth_filter.h"

namespace mrgi::lighting {

/// Interleaved vertex of every mesh the pipeline draws.
struct MeshVertex {
  cv::Vec3f position;  ///< model frame, metres
  cv::Vec3f normal;    ///< unit
  cv::Vec3f albedo;    ///< linear RGB
};

/// A mesh on the GPU (immutable; rebuilt when its vertices change).
class GpuMesh {
 public:
  GpuMesh() = default;
  GpuMesh(const std::vector<MeshVertex>& vertices, const std::vector<uint32_t>& indices);
  void draw() const;
  bool empty() const { return count_ == 0; }

 private:
  gl::Buffer vertices_, indices_;
  gl::VertexArray vao_;
  GLsizei count_ = 0;
};

/// The real-scene mesh in the lighting world: DepthMesh vertices (camera frame) moved by T_world_camera,
/// each with the albedo estimated at its pixel (albedo CV_32FC3, linear; empty = 0.5 grey).
void buildRealVertices(const reconstruction::DepthMesh& mesh, const cv::Mat& albedo,
                       const capture::Pose& T_world_camera, std::vector<MeshVertex>& vertices,
                       std::vector<uint32_t>& indices);

/// Appends the parallelogram p0 + s e1 + t e2 (s, t in [0, 1]) as an n x n grid of triangle pairs facing
/// e1 x e2, of one albedo (test and benchmark scenes: a floor, a wall).
void appendGridQuad(std::vector<MeshVertex>& vertices, std::vector<uint32_t>& indices, const cv::Vec3f& p0,
                    const cv::Vec3f& e1, const cv::Vec3f& e2, const cv::Vec3f& albedo, int n = 8);

/// Camera matrices (OpenCV camera frame: x right, y down, z forward). Image row 0 maps to NDC y = -1, so
/// framebuffer rows come back in cv::Mat order.
cv::Matx44d projectionFromIntrinsics(const capture::Intrinsics& k, double nearPlane, double farPlane);
cv::Matx44d orthographicProjection(double halfExtent, double nearPlane, double farPlane);
std::array<float, 16> toGl(const cv::Matx44d& m);
/// Inverse transpose of T's rotation part (normals).
cv::Matx33f normalMatrix(const cv::Matx44d& T);
void setMat3(const gl::Program& p, const std::string& name, const cv::Matx33f& m);
void setVec3(const gl::Program& p, const std::string& name, const cv::Vec3d& v);
/// uLightType of the shaders: 0 point, 1 spot, 2 directional.
int shaderLightType(LightType t);
/// A timed stage when there is a profiler (GPU timer queries too when `gpu`).
std::optional<gl::Profiler::Scope> timed(gl::Profiler* profiler, const char* name, bool gpu = true);

struct CameraView {
  capture::Intrinsics intrinsics;
  capture::Pose T_world_camera;
  double nearPlane = 0.05, farPlane = 20.0;
};

/// CV_32FC4 download of an RGBA32F 2D texture.
cv::Mat download4(const gl::Texture& t);

}  // namespace mrgi::lighting
