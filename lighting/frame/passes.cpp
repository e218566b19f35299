#include "lighting/frame/passes.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "gl/error.h"
#include "lighting/upsample.h"

namespace mrgi::lighting {

// ---------------------------------------------------------------------------------------------- geometry

FrameGeometry::FrameGeometry(const std::vector<VirtualObject>& objects) {
  objects_.reserve(objects.size());
  for (const VirtualObject& o : objects) {
    std::vector<MeshVertex> v(o.mesh.positions.size());
    for (size_t i = 0; i < v.size(); ++i) v[i] = {o.mesh.positions[i], o.mesh.normals[i], o.material.albedo};
    FrameObject fo;
    fo.source = o;
    fo.gpu = GpuMesh(v, o.mesh.indices);
    fo.sphere = occluderSphere(o.mesh);
    fo.sphere.albedo = o.material.albedo;
    fo.T_world_object = o.T_marker_object;
    objects_.push_back(std::move(fo));
  }
}

void FrameGeometry::setRealMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices) {
  realMesh_ = GpuMesh(vertices, indices);
  realVertices_ = std::move(vertices);
  realIndices_ = std::move(indices);
}

void FrameGeometry::setViewMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices) {
  viewVertices_ = std::move(vertices);  // for the shading pass's footprint (cameraVertices); never drawn
  viewIndices_ = std::move(indices);
}

void FrameGeometry::setViewSurface(const cv::Mat& positions, const cv::Mat& normals, int stride,
                                   float maxRelativeJump) {
  viewStride_ = std::max(1, stride);
  viewMaxJump_ = maxRelativeJump;
  if (positions.empty()) {
    viewPosition_ = gl::Texture();
    viewNormal_ = gl::Texture();
    return;
  }
  if (positions.type() != CV_32FC3 || normals.type() != CV_32FC3 || positions.size() != normals.size())
    throw std::invalid_argument("FrameGeometry::setViewSurface: positions and normals must be CV_32FC3 of one size");
  const auto upload = [&](gl::Texture& t, const cv::Mat& image) {
    if (t.id() == 0 || t.width() != image.cols || t.height() != image.rows) {
      t = gl::Texture(GL_TEXTURE_2D, GL_RGB32F, image.cols, image.rows);
      t.setFilter(GL_NEAREST, GL_NEAREST);
    }
    const cv::Mat packed = image.isContinuous() ? image : image.clone();
    t.upload(GL_RGB, GL_FLOAT, packed.data, 4);
  };
  upload(viewPosition_, positions);
  upload(viewNormal_, normals);
}

std::optional<std::pair<cv::Vec3d, cv::Vec3d>> FrameGeometry::objectBounds() const {
  if (objects_.empty()) return std::nullopt;
  cv::Vec3d lo = cv::Vec3d::all(1e30), hi = cv::Vec3d::all(-1e30);
  for (const FrameObject& o : objects_) {
    const cv::Vec3f& bmin = o.source.mesh.boundsMin;
    const cv::Vec3f& bmax = o.source.mesh.boundsMax;
    for (int c = 0; c < 8; ++c) {
      const cv::Vec3d corner((c & 1) ? bmax[0] : bmin[0], (c & 2) ? bmax[1] : bmin[1], (c & 4) ? bmax[2] : bmin[2]);
      const cv::Vec3d w = capture::transformPoint(o.T_world_object, corner);
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], w[k]);
        hi[k] = std::max(hi[k], w[k]);
      }
    }
  }
  return std::pair{lo, hi};
}

void FrameGeometry::drawScene(const gl::Program& program, bool includeVirtual, const cv::Matx44d& viewProj) const {
  program.use();
  const auto vp = toGl(viewProj);
  program.setMat4("uViewProj", vp.data());
  const auto id = toGl(cv::Matx44d::eye());
  program.setMat4("uModel", id.data());
  setMat3(program, "uNormalModel", cv::Matx33f::eye());
  // Which surface a texel shows: the G-buffer and the RSMs record it, the shadow maps need not.
  const bool tagged = program.declares("uObject"), virtualFlag = program.declares("uVirtual");
  if (virtualFlag) program.set("uVirtual", 0.0f);
  if (tagged) program.set("uObject", 0.0f);
  realMesh_.draw();
  if (includeVirtual) drawObjects(program);
}

void FrameGeometry::drawObjects(const gl::Program& program) const {
  program.use();
  const bool tagged = program.declares("uObject");
  if (program.declares("uVirtual")) program.set("uVirtual", 1.0f);
  for (size_t i = 0; i < objects_.size(); ++i) {
    if (tagged) program.set("uObject", static_cast<float>(i + 1));
    const auto m = toGl(objects_[i].T_world_object);
    program.setMat4("uModel", m.data());
    setMat3(program, "uNormalModel", normalMatrix(objects_[i].T_world_object));
    objects_[i].gpu.draw();
  }
}

// ---------------------------------------------------------------------------------------------- G-buffer

GBufferTargets::GBufferTargets(int width, int height)
    : position(GL_TEXTURE_2D, GL_RGBA32F, width, height),
      normal(GL_TEXTURE_2D, GL_RGBA32F, width, height),
      albedo(GL_TEXTURE_2D, GL_RGBA32F, width, height),
      depth(GL_TEXTURE_2D, GL_DEPTH_COMPONENT32F, width, height) {
  for (gl::Texture* t : {&position, &normal, &albedo}) t->setFilter(GL_NEAREST, GL_NEAREST);
  fb.attachColour(0, position);
  fb.attachColour(1, normal);
  fb.attachColour(2, albedo);
  fb.attachDepth(depth);
  fb.finalise(3);
}

GBufferPass::GBufferPass(int width, int height, int factor, int termsFactor)
    : width_(width),
      height_(height),
      factor_(std::max(factor, 1)),
      reducedFactor_(factor_ > 1 ? factor_ : std::max(termsFactor, 1)),
      program_(gl::Program::graphics("lighting/frame/mesh.vert", "lighting/frame/gbuffer.frag")),
      surfaceProgram_(gl::Program::graphics("lighting/gl/fullscreen.vert", "lighting/frame/gbuffer_surface.frag")),
      full_(width, height) {
  if (reducedFactor_ > 1) {
    reduceProgram_ = gl::Program::graphics("lighting/gl/fullscreen.vert", "lighting/frame/gbuffer_reduce.frag");
    reduced_ = GBufferTargets(reducedSize(width, reducedFactor_), reducedSize(height, reducedFactor_));
  }
}

bool GBufferPass::setPixelAlbedo(const cv::Mat& albedo, const cv::Mat& clipped) {
  const bool use = !albedo.empty() && albedo.type() == CV_32FC3 && albedo.cols == width_ && albedo.rows == height_;
  if (!use && !hasPixelAlbedo_) return false;
  hasPixelAlbedo_ = use;
  if (!use) return true;
  if (pixelAlbedo_.id() == 0) {
    pixelAlbedo_ = gl::Texture(GL_TEXTURE_2D, GL_RGBA16F, width_, height_);
    pixelAlbedo_.setFilter(GL_NEAREST, GL_NEAREST);
  }
  // Half floats, four channels: what the texture holds, so the driver converts nothing (an albedo needs no
  // more than half precision: 2^-11 relative).
  // Alpha: minus the pixel's clipped channels' bits (0 where none are, or none are given).
  cv::Mat alpha(albedo.size(), CV_32FC1, cv::Scalar(0));
  if (!clipped.empty()) {
    CV_Assert(clipped.type() == CV_8UC1 && clipped.size() == albedo.size());
    clipped.convertTo(alpha, CV_32F, -1.0);
  }
  std::vector<cv::Mat> channels;
  cv::split(albedo, channels);
  channels.push_back(alpha);
  cv::Mat rgba, half;
  cv::merge(channels, rgba);
  rgba.convertTo(half, CV_16F);
  pixelAlbedo_.upload(GL_RGBA, GL_HALF_FLOAT, half.data, 8);
  return true;
}

void GBufferPass::render(const FrameGeometry& geometry, const CameraView& camera) {
  full_.fb.bind();
  glViewport(0, 0, width_, height_);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  const float zero[4] = {0, 0, 0, 0};
  for (int i = 0; i < 3; ++i) glClearNamedFramebufferfv(full_.fb.id(), GL_COLOR, i, zero);
  const float one = 1.0f;
  glClearNamedFramebufferfv(full_.fb.id(), GL_DEPTH, 0, &one);
  const cv::Matx44d cameraFromWorld = capture::inversePose(camera.T_world_camera);
  const cv::Matx44d viewProj =
      projectionFromIntrinsics(camera.intrinsics, camera.nearPlane, camera.farPlane) * cameraFromWorld;
  setVec3(program_, "uEye", capture::translationOf(camera.T_world_camera));
  program_.set("uPixelAlbedo", hasPixelAlbedo_ ? 1 : 0);
  if (hasPixelAlbedo_) pixelAlbedo_.bind(0);
  if (geometry.hasViewSurface() && hasPixelAlbedo_ && geometry.viewPosition().width() == width_ &&
      geometry.viewPosition().height() == height_) {
    // The real surface the camera sees, one fragment per pixel from its own depth (no mesh to rasterise: a
    // mesh over every other depth pixel is hundreds of thousands of triangles a frame), then the objects
    // depth-tested against it.
    surfaceProgram_.use();
    const auto vp = toGl(viewProj);
    surfaceProgram_.setMat4("uViewProj", vp.data());
    const auto worldFromCamera = toGl(camera.T_world_camera);
    surfaceProgram_.setMat4("uWorldFromCamera", worldFromCamera.data());
    setVec3(surfaceProgram_, "uEye", capture::translationOf(camera.T_world_camera));
    surfaceProgram_.set("uStride", geometry.viewStride());
    surfaceProgram_.set("uMaxRelativeJump", geometry.viewMaxRelativeJump());
    geometry.viewPosition().bind(1);
    geometry.viewNormal().bind(2);
    emptyVao_.bind();
    glDrawArrays(GL_TRIANGLES, 0, 3);
    program_.use();
    program_.setMat4("uViewProj", vp.data());
    geometry.drawObjects(program_);
  } else {
    geometry.drawScene(program_, true, viewProj);
  }
  if (reducedFactor_ > 1) {
    // Every reduced texel is written (depth test always passes), depth included, for passes that test against it.
    reduced_.fb.bind();
    glViewport(0, 0, reduced_.position.width(), reduced_.position.height());
    glDepthFunc(GL_ALWAYS);
    reduceProgram_.use();
    reduceProgram_.set("uFactor", reducedFactor_);
    view().bind();
    full_.depth.bind(3);
    emptyVao_.bind();
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDepthFunc(GL_LESS);
  }
  glDisable(GL_DEPTH_TEST);
}

// ---------------------------------------------------------------------------------------------- lights

namespace {

Rsm makeRsm(int size) {
  Rsm r{gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, size, size),
        gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, size, size),
        gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, size, size),
        gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, size, size),
        gl::Texture(GL_TEXTURE_2D, GL_DEPTH_COMPONENT32F, size, size),
        gl::Framebuffer()};
  for (auto* t : {&r.position, &r.normal, &r.flux, &r.direct}) t->setFilter(GL_NEAREST, GL_NEAREST);
  r.fb.attachColour(0, r.position);
  r.fb.attachColour(1, r.normal);
  r.fb.attachColour(2, r.flux);
  r.fb.attachColour(3, r.direct);
  r.fb.attachDepth(r.depth);
  r.fb.finalise(4);
  return r;
}

}  // namespace

LightPass::LightPass(int rsmSize, int shadowSize)
    : rsmSize_(rsmSize),
      shadowSize_(shadowSize),
      rsmProgram_(gl::Program::graphics("lighting/frame/mesh.vert", "lighting/frame/rsm.frag")),
      shadowProgram_(gl::Program::graphics("lighting/frame/mesh.vert", "lighting/frame/shadow.frag")),
      objectPosition_(GL_TEXTURE_2D, GL_RGBA32F, shadowSize, shadowSize),
      objectDepth_(GL_TEXTURE_2D, GL_DEPTH_COMPONENT32F, shadowSize, shadowSize),
      rsmRho_(makeRsm(rsmSize)),
      rsmMu_(makeRsm(rsmSize)) {
  objectPosition_.setFilter(GL_NEAREST, GL_NEAREST);
  objectFb_.attachColour(0, objectPosition_);
  objectFb_.attachDepth(objectDepth_);
  objectFb_.finalise(1);
}

void LightPass::renderRsm(Rsm& rsm, const SceneLight& light, const LightView& view, bool includeVirtual,
                          const FrameGeometry& geometry) {
  const int size = rsmSize_;
  rsm.fb.bind();
  glViewport(0, 0, size, size);
  const float zero[4] = {0, 0, 0, 0};
  for (int i = 0; i < 4; ++i) glClearNamedFramebufferfv(rsm.fb.id(), GL_COLOR, i, zero);
  const float one = 1.0f;
  glClearNamedFramebufferfv(rsm.fb.id(), GL_DEPTH, 0, &one);
  const gl::Program& p = rsmProgram_;
  p.set("uLightType", shaderLightType(light.type));
  setVec3(p, "uLightPosition", light.position);
  setVec3(p, "uLightDirection", light.direction);
  setVec3(p, "uLightPower", light.type == LightType::Directional ? light.irradiance : light.intensity);
  p.set("uSpotCos", static_cast<float>(light.spotCos()));
  p.set("uFocal", static_cast<float>(view.focalPixels));
  p.set("uCentre", 0.5f * size);
  p.set("uTexelArea", static_cast<float>(view.texelArea));
  geometry.drawScene(p, includeVirtual, view.viewProj);
}

void LightPass::render(size_t i, size_t lightCount, const SceneLight& light, const Region& region,
                       const FrameGeometry& geometry, bool soft) {
  if (views_.size() != i) throw std::logic_error("LightPass::render(): lights must be rendered in order");
  LightView view = fitLightView(light, region, rsmSize_);
  view.soft = soft && light.extent > 0;
  const auto bounds = geometry.objectBounds();
  if (bounds)
    fitObjectView(view, light, 0.5 * (bounds->first + bounds->second), 0.5 * cv::norm(bounds->second - bounds->first),
                  shadowSize_);
  views_.push_back(view);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  renderRsm(rsmRho_, light, views_.back(), true, geometry);
  renderRsm(rsmMu_, light, views_.back(), false, geometry);
  const int m = shadowSize_;
  if (view.objectShadowBias >= 0) {
    objectFb_.bind();
    glViewport(0, 0, m, m);
    const float zero[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(objectFb_.id(), GL_COLOR, 0, zero);
    const float one = 1.0f;
    glClearNamedFramebufferfv(objectFb_.id(), GL_DEPTH, 0, &one);
    const auto vp = toGl(view.objectViewProj);
    shadowProgram_.use();
    shadowProgram_.setMat4("uViewProj", vp.data());
    geometry.drawObjects(shadowProgram_);
  }
  glDisable(GL_DEPTH_TEST);
  const int n = rsmSize_;
  // Shadow arrays: one layer per light of this run (allocated for the lights there are).
  const int layers = static_cast<int>(lightCount);
  auto ensureLayers = [&](gl::Texture& t, int size) {
    if (t.id() && t.depth() >= layers) return;
    t = gl::Texture(GL_TEXTURE_2D_ARRAY, GL_RGBA32F, size, size, layers);
    t.setFilter(GL_NEAREST, GL_NEAREST);
  };
  if (i == 0) {
    ensureLayers(shadowRho_, n);
    ensureLayers(shadowMu_, n);
    ensureLayers(shadowObjects_, m);
  }
  const auto layer = static_cast<GLint>(i);
  glCopyImageSubData(rsmRho_.position.id(), GL_TEXTURE_2D, 0, 0, 0, 0, shadowRho_.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0,
                     layer, n, n, 1);
  glCopyImageSubData(rsmMu_.position.id(), GL_TEXTURE_2D, 0, 0, 0, 0, shadowMu_.id(), GL_TEXTURE_2D_ARRAY, 0, 0, 0,
                     layer, n, n, 1);
  if (view.objectShadowBias >= 0)
    glCopyImageSubData(objectPosition_.id(), GL_TEXTURE_2D, 0, 0, 0, 0, shadowObjects_.id(), GL_TEXTURE_2D_ARRAY, 0, 0,
                       0, layer, m, m, 1);
}

ShadowTexels LightPass::downloadShadowTexels(size_t i) const {
  if (i >= views_.size()) throw std::out_of_range("LightPass::downloadShadowTexels(): no such light in the last run");
  auto layer = [&](const gl::Texture& t) {
    cv::Mat m(t.height(), t.width(), CV_32FC4);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    gl::countSynchronousReadback();
    glGetTextureSubImage(t.id(), 0, 0, 0, static_cast<GLint>(i), t.width(), t.height(), 1, GL_RGBA, GL_FLOAT,
                         static_cast<GLsizei>(m.total() * m.elemSize()), m.ptr());
    return m;
  };
  // RSM^rho is read only where the light has no objects' map (lightVisibility), so only then downloaded.
  ShadowTexels out{cv::Mat(), layer(shadowMu_), cv::Mat()};
  if (views_[i].objectShadowBias >= 0)
    out.objects = layer(shadowObjects_);
  else
    out.rho = layer(shadowRho_);
  return out;
}

void LightPass::bindShadowMaps() const {
  shadowRho_.bind(12);
  shadowMu_.bind(13);
  shadowObjects_.bind(14);
}

RsmTexels LightPass::downloadRsm(bool rho) const {
  const Rsm& r = rho ? rsmRho_ : rsmMu_;
  return {download4(r.position), download4(r.normal), download4(r.flux), download4(r.direct)};
}

size_t LightPass::gpuBytes() const {
  size_t sum = 0;
  for (const gl::Texture* t : {&shadowRho_, &shadowMu_, &shadowObjects_, &objectPosition_, &objectDepth_})
    sum += t->bytes();
  for (const Rsm* r : {&rsmRho_, &rsmMu_})
    for (const gl::Texture* t : {&r->position, &r->normal, &r->flux, &r->direct, &r->depth}) sum += t->bytes();
  return sum;
}

}  // namespace mrgi::lighting
