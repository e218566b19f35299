#pragma once
/// The frame's render passes, each with its declared inputs and outputs (lighting/frame/frame.h composes them
/// into the resources the techniques read):
///   FrameGeometry  — what every pass draws: the real mesh (and the camera's view of the real surface, per
///                    pixel), the virtual objects with their placements.
///   GBufferPass    — in: geometry, camera, the real surfaces' per-pixel albedo; out: world position, normal
///                    (w = object index + 1), albedo (a = virtual), depth, at the output size, and the same at
///                    1/factor (the frame knob render_scale) for technique outputs (lighting/upsample.h).
///   LightPass      — in: geometry, one light, the region that matters; out: that light's view, its RSMs
///                    (rho: real + virtual, mu: real only), the objects' shadow map, and its layer of the three
///                    shadow arrays the shading pass reads.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "gl/objects.h"
#include "gl/program.h"
#include "lighting/frame/light_view.h"
#include "lighting/frame/mesh.h"
#include "lighting/object_shadow.h"
#include "lighting/scene.h"

namespace mrgi::lighting {

/// A virtual object as the frame holds it: its mesh in model space (also on the GPU), material, placement.
struct FrameObject {
  VirtualObject source;  ///< mesh (model space, scaled) and material (a copy)
  GpuMesh gpu;
  OccluderSphere sphere;  ///< the sphere it stands as for the shadow of the ambient, model space (object_shadow.h)
  cv::Matx44d T_world_object = cv::Matx44d::eye();
};

class FrameGeometry {
 public:
  explicit FrameGeometry(const std::vector<VirtualObject>& objects);
  /// The real mesh (lighting world), kept on the CPU too.
  void setRealMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices);
  /// The real surface as the camera sees it now, as a mesh (lighting world) for the CPU's questions about it
  /// (cameraVertices: the shading pass's footprint); the G-buffer draws setViewSurface's pixels.
  void setViewMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices);
  /// The real surface as the camera sees it now, per camera pixel: positions and normals in the camera frame
  /// (CV_32FC3, the frame's size; z <= 0 or not finite: no depth there; a zero normal: unknown), which the
  /// G-buffer draws as reconstruction::buildDepthMesh's mesh over every `stride`-th pixel would be rasterised,
  /// without the mesh (lighting/frame/gbuffer_surface.frag). Empty: none.
  void setViewSurface(const cv::Mat& positions, const cv::Mat& normals, int stride, float maxRelativeJump);
  /// Whether setViewSurface gave a surface, and its textures (RGB32F, camera frame, row 0 = the image's top).
  bool hasViewSurface() const { return viewPosition_.id() != 0; }
  const gl::Texture& viewPosition() const { return viewPosition_; }
  const gl::Texture& viewNormal() const { return viewNormal_; }
  int viewStride() const { return viewStride_; }
  /// The view surface's textures, bytes (0 without one).
  size_t viewSurfaceBytes() const { return viewPosition_.bytes() + viewNormal_.bytes(); }
  float viewMaxRelativeJump() const { return viewMaxJump_; }
  void setObjectTransform(size_t i, const cv::Matx44d& T_world_object) {
    objects_.at(i).T_world_object = T_world_object;
  }

  const std::vector<MeshVertex>& realVertices() const { return realVertices_; }
  const std::vector<uint32_t>& realIndices() const { return realIndices_; }
  /// The mesh the camera sees (the G-buffer's): the view mesh when there is one, else the real mesh.
  const std::vector<MeshVertex>& cameraVertices() const { return viewIndices_.empty() ? realVertices_ : viewVertices_; }
  const std::vector<uint32_t>& cameraIndices() const { return viewIndices_.empty() ? realIndices_ : viewIndices_; }
  const std::vector<FrameObject>& objects() const { return objects_; }
  /// World bounding box of the placed objects (nullopt without objects).
  std::optional<std::pair<cv::Vec3d, cv::Vec3d>> objectBounds() const;

  /// Draws the real mesh and the objects when `includeVirtual`, with `program` (uModel, uNormalModel, uViewProj
  /// set here, and uVirtual, uObject where it declares them).
  void drawScene(const gl::Program& program, bool includeVirtual, const cv::Matx44d& viewProj) const;
  /// Draws the objects alone (uModel, uNormalModel, and uVirtual = 1, uObject where declared; uViewProj by the
  /// caller).
  void drawObjects(const gl::Program& program) const;

 private:
  std::vector<FrameObject> objects_;
  GpuMesh realMesh_;
  gl::Texture viewPosition_, viewNormal_;
  int viewStride_ = 1;
  float viewMaxJump_ = reconstruction::kDepthMeshMaxRelativeJump;
  std::vector<MeshVertex> realVertices_;
  std::vector<uint32_t> realIndices_;
  std::vector<MeshVertex> viewVertices_;
  std::vector<uint32_t> viewIndices_;
};

/// A G-buffer's textures and size: the frame's own, or its reduced copy that per-pixel technique outputs are
/// rendered at (lighting/upsample.h).
struct GBufferView {
  int width = 0, height = 0;
  int factor = 1;                         ///< frame pixels per texel along each axis (1: the frame's own)
  const gl::Texture* position = nullptr;  ///< xyz world, w = 1 where a surface was seen
  const gl::Texture* normal = nullptr;    ///< xyz unit normal, w = object index + 1 (0 real)
  const gl::Texture* albedo = nullptr;    ///< rgb albedo, a = 1 on virtual surfaces
  const gl::Texture* depth = nullptr;
  /// Binds position, normal and albedo to texture units 0, 1 and 2, where every pass that reads a G-buffer
  /// (the techniques' read-outs, the shading pass) declares them.
  void bind() const {
    position->bind(0);
    normal->bind(1);
    albedo->bind(2);
  }
};

/// A G-buffer's render targets: position, normal, albedo (RGBA32F, nearest filtering) and depth, as one
/// framebuffer (colour attachments 0-2).
struct GBufferTargets {
  GBufferTargets() = default;
  GBufferTargets(int width, int height);
  /// The targets as a view, each texel standing for `factor` x `factor` frame pixels.
  GBufferView view(int factor) const {
    return {position.width(), position.height(), factor, &position, &normal, &albedo, &depth};
  }
  size_t bytes() const { return position.bytes() + normal.bytes() + albedo.bytes() + depth.bytes(); }

  gl::Texture position, normal, albedo, depth;
  gl::Framebuffer fb;
};

class GBufferPass {
 public:
  /// `factor` > 1: render() also reduces the G-buffer to 1/factor (each texel one pixel of its block), the
  /// techniques' view and the object terms'; `factor` 1 and `termsFactor` > 1: to 1/termsFactor for the object
  /// terms alone.
  GBufferPass(int width, int height, int factor = 1, int termsFactor = 1);
  /// The real surfaces' albedo per camera pixel (CV_32FC3 linear, the pass's size; negative: none at that pixel)
  /// instead of the vertices'; empty or another size: the vertices'. `clipped` (CV_8UC1, the same size; empty:
  /// none): each pixel's clipped camera channels (lighting::clippedChannels), which the G-buffer's albedo carries
  /// as its alpha on real pixels, -bits (lighting/clipped_real.glsl). Returns whether what the pass draws changed.
  bool setPixelAlbedo(const cv::Mat& albedo, const cv::Mat& clipped = cv::Mat());
  void render(const FrameGeometry& geometry, const CameraView& camera);

  const gl::Texture& position() const { return full_.position; }  ///< xyz world, w = 1 where a surface was seen
  const gl::Texture& normal() const { return full_.normal; }      ///< xyz unit normal, w = object index + 1 (0 real)
  const gl::Texture& albedo() const { return full_.albedo; }      ///< rgb albedo, a = 1 on virtual surfaces
  const gl::Texture& depth() const { return full_.depth; }
  /// The G-buffer at the frame's size.
  GBufferView view() const { return full_.view(1); }
  /// The G-buffer at 1/factor (the frame's own when the factor is 1).
  GBufferView reducedView() const { return factor_ > 1 ? reduced_.view(factor_) : view(); }
  /// The G-buffer the shading pass's object terms are computed at: reducedView() when the factor is over 1,
  /// else the copy at 1/termsFactor (the frame's own when that is 1).
  GBufferView termsView() const { return reducedFactor_ > 1 ? reduced_.view(reducedFactor_) : view(); }
  size_t gpuBytes() const { return full_.bytes() + reduced_.bytes() + pixelAlbedo_.bytes(); }

 private:
  int width_, height_, factor_, reducedFactor_;
  gl::Program program_, surfaceProgram_, reduceProgram_;
  GBufferTargets full_, reduced_;  ///< reduced_: at reducedFactor_, only when it is over 1
  gl::VertexArray emptyVao_;
  gl::Texture pixelAlbedo_;  ///< setPixelAlbedo's, RGBA16F
  bool hasPixelAlbedo_ = false;
};

class LightPass {
 public:
  LightPass(int rsmSize, int shadowSize);
  /// Forgets the last run's light views (the next render() is light 0).
  void clear() { views_.clear(); }
  /// Light i of `lightCount` (in order): its view fitted to the region (and to the objects for their own map),
  /// its RSMs and the objects' shadow map, copied into layer i of the shadow arrays.
  void render(size_t i, size_t lightCount, const SceneLight& light, const Region& region, const FrameGeometry& geometry,
              bool soft = false);

  const std::vector<LightView>& views() const { return views_; }
  const Rsm& rsmRho() const { return rsmRho_; }
  const Rsm& rsmMu() const { return rsmMu_; }
  RsmTexels downloadRsm(bool rho) const;
  const gl::Texture& shadowRho() const { return shadowRho_; }
  const gl::Texture& shadowMu() const { return shadowMu_; }
  const gl::Texture& shadowObjects() const { return shadowObjects_; }
  ShadowTexels downloadShadowTexels(size_t i) const;
  /// Binds the three shadow arrays where lighting/direct_light.glsl reads them (units 12, 13, 14).
  void bindShadowMaps() const;
  size_t gpuBytes() const;

 private:
  void renderRsm(Rsm& rsm, const SceneLight& light, const LightView& view, bool includeVirtual,
                 const FrameGeometry& geometry);

  int rsmSize_, shadowSize_;
  gl::Program rsmProgram_, shadowProgram_;
  gl::Texture objectPosition_, objectDepth_;
  gl::Framebuffer objectFb_;
  Rsm rsmRho_, rsmMu_;
  gl::Texture shadowRho_, shadowMu_, shadowObjects_;
  std::vector<LightView> views_;
};

}  // namespace mrgi::lighting
