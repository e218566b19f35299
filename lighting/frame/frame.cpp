#include "lighting/frame/frame.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "gl/error.h"
#include "lighting/material.h"

namespace mrgi::lighting {

// ---------------------------------------------------------------------------------------------- knobs

const std::vector<KnobBinding<FrameKnobs>>& frameKnobTable() {
  static const std::vector<KnobBinding<FrameKnobs>> table = {
      {{"rsm_size",
        KnobType::Int,
        16,
        4096,
        256,
        "RSM and shadow-map texels per side, per light (RSM^rho and RSM^mu)",
        {64, 128, 512},
        {64},
        true},
       &FrameKnobs::rsmSize},
      {{"shadow_size",
        KnobType::Int,
        16,
        4096,
        512,
        "texels per side of the objects' shadow maps (the virtual objects alone, fitted to their bounding "
        "sphere, per light)",
        {128, 1024},
        {128},
        true},
       &FrameKnobs::shadowSize},
      {{"size_factor",
        KnobType::Real,
        1.0,
        64.0,
        4.0,
        "side of the region around the virtual objects that light views and volumes cover, in units of the "
        "objects' largest bounding-box edge",
        {2.0, 3.0, 6.0},
        {},
        false},
       &FrameKnobs::sizeFactor},
      {{"light_cutoff",
        KnobType::Real,
        0.0,
        0.5,
        0.01,
        "share of the most irradiance the lights and the ambient can give the region that the dimmest lights "
        "may carry and be skipped (no RSM, shadow map or technique work); 0: every light is rendered",
        {},
        {},
        false},  // not swept: the bundled sessions have no light to leave out (README, real time)
       &FrameKnobs::lightCutoff},
  };
  return table;
}

const KnobGroup& frameKnobGroup() {
  static const KnobGroup g = groupOf("frame", frameKnobTable());
  return g;
}

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

void setAmbientUniforms(const gl::Program& p, const FrameResources& frame) {
  setVec3(p, "uAmbient", frame.ambient());
  for (int k = 0; k < 9; ++k)
    setVec3(p, "uAmbientSh[" + std::to_string(k) + "]", frame.ambientSh()[static_cast<size_t>(k)]);
}

void setObjectLobes(const gl::Program& p, const FrameResources& frame) {
  const auto& objects = frame.objects();
  for (int k = 0; k < kShaderMaxObjects; ++k) {
    const std::string at = "[" + std::to_string(k) + "]";
    float spec = 0, exponent = 0;
    if (k < static_cast<int>(objects.size())) {
      spec = objects[static_cast<size_t>(k)].source.material.specular;
      exponent = phongExponent(objects[static_cast<size_t>(k)].source.material.roughness);
    }
    p.set("uSpecular" + at, spec);
    p.set("uExponent" + at, exponent);
  }
}

int shaderLightType(LightType t) { return t == LightType::Point ? 0 : t == LightType::Spot ? 1 : 2; }

std::optional<gl::Profiler::Scope> timed(gl::Profiler* profiler, const char* name, bool gpu) {
  return profiler ? std::optional<gl::Profiler::Scope>(std::in_place, *profiler, name, gpu) : std::nullopt;
}

Region fitRegion(const cv::Vec3d& lo, const cv::Vec3d& hi, double sizeFactor) {
  const cv::Vec3d extent = hi - lo;
  const double edge = std::max({extent[0], extent[1], extent[2], 1e-3});
  Region r;
  r.side = edge * sizeFactor;
  r.origin = 0.5 * (lo + hi) - cv::Vec3d::all(0.5 * r.side);
  return r;
}

cv::Vec3d irradianceBound(const SceneLight& light, const Region& region) {
  if (light.type == LightType::Directional) return light.irradiance;
  const cv::Vec3d toCentre = region.centre() - light.position;
  const double d = cv::norm(toCentre), r = region.radius();
  if (!(d > r)) return cv::Vec3d::all(std::numeric_limits<double>::infinity());
  if (light.type == LightType::Spot) {
    // The cone misses the sphere when the angle from its axis to the centre exceeds the half angle by more
    // than the sphere's angular radius.
    const double off = std::acos(std::clamp(toCentre.dot(light.direction) / d, -1.0, 1.0));
    if (off - std::asin(r / d) > light.spotHalfAngleDeg * CV_PI / 180.0) return {0, 0, 0};
  }
  return light.intensity / ((d - r) * (d - r));
}

std::vector<size_t> lightsThatMatter(const std::vector<SceneLight>& lights, const cv::Vec3d& ambientRadiance,
                                     const Region& region, double cutoff) {
  std::vector<size_t> kept(lights.size());
  std::iota(kept.begin(), kept.end(), size_t{0});
  if (!(cutoff > 0)) return kept;
  std::vector<cv::Vec3d> bound(lights.size());
  cv::Vec3d total = CV_PI * ambientRadiance;
  for (size_t i = 0; i < lights.size(); ++i) {
    bound[i] = irradianceBound(lights[i], region);
    if (std::isfinite(bound[i][0] + bound[i][1] + bound[i][2])) total += bound[i];
  }
  auto brightest = [](const cv::Vec3d& b) { return std::max({b[0], b[1], b[2]}); };
  std::vector<size_t> order = kept;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return brightest(bound[a]) < brightest(bound[b]); });
  std::vector<bool> skip(lights.size(), false);
  cv::Vec3d skipped{0, 0, 0};
  for (size_t i : order) {
    const cv::Vec3d next = skipped + bound[i];
    bool within = true;
    for (int c = 0; c < 3; ++c) within = within && next[c] <= cutoff * total[c];
    if (!within) break;
    skipped = next;
    skip[i] = true;
  }
  kept.clear();
  for (size_t i = 0; i < lights.size(); ++i)
    if (!skip[i]) kept.push_back(i);
  return kept;
}

LightView fitLightView(const SceneLight& light, const Region& region, int size) {
  LightView v;
  const cv::Vec3d centre = region.centre();
  const double radius = region.radius();
  if (light.type == LightType::Directional) {
    const double back = 4.0 * radius;  // room for occluders in front of the region
    const cv::Vec3d eye = centre - light.direction * back;
    v.viewProj =
        orthographicProjection(radius, 0.0, back + radius) * capture::inversePose(capture::lookAtPose(eye, centre));
    const double texel = 2.0 * radius / size;
    v.texelArea = texel * texel;
    v.shadowBias = 2.0 * texel;
  } else {
    const double dist = cv::norm(centre - light.position);
    if (dist < 1e-6) throw std::invalid_argument("a point light sits at the centre of the region around the objects");
    const double half = std::asin(std::min(radius / dist, std::sin(80.0 * CV_PI / 180.0)));
    v.focalPixels = 0.5 * size / std::tan(half);
    capture::Intrinsics k;
    k.width = k.height = size;
    k.fx = k.fy = v.focalPixels;
    k.cx = k.cy = 0.5 * size - 0.5;
    v.viewProj = projectionFromIntrinsics(k, std::max(1e-3, 0.01 * dist), dist + radius) *
                 capture::inversePose(capture::lookAtPose(light.position, centre));
    v.shadowBias = 2.0 * (dist + radius) / v.focalPixels;
  }
  return v;
}

void fitObjectView(LightView& v, const SceneLight& light, const cv::Vec3d& centre, double radius, int size) {
  radius = std::max(radius, 1e-4);
  v.objectShadowBias = -1;
  if (light.type == LightType::Directional) {
    const cv::Vec3d eye = centre - light.direction * (2.0 * radius);
    v.objectViewProj =
        orthographicProjection(radius, 0.0, 3.0 * radius) * capture::inversePose(capture::lookAtPose(eye, centre));
    v.objectShadowBias = 2.0 * (2.0 * radius / size);
    return;
  }
  const double dist = cv::norm(centre - light.position);
  if (!(dist > 1.05 * radius)) return;  // the light is (almost) among the objects: no single view holds them
  const double half = std::asin(radius / dist);
  const double focal = 0.5 * size / std::tan(half);
  capture::Intrinsics k;
  k.width = k.height = size;
  k.fx = k.fy = focal;
  k.cx = k.cy = 0.5 * size - 0.5;
  v.objectViewProj = projectionFromIntrinsics(k, std::max(1e-4, dist - radius), dist + radius) *
                     capture::inversePose(capture::lookAtPose(light.position, centre));
  v.objectShadowBias = 2.0 * (dist + radius) / focal;
}

cv::Mat download4(const gl::Texture& t) {
  cv::Mat m(t.height(), t.width(), CV_32FC4);
  t.download(GL_RGBA, GL_FLOAT, m.ptr(), static_cast<GLsizei>(m.total() * m.elemSize()), 4);
  return m;
}

// ---------------------------------------------------------------------------------------------- resources

FrameResources::FrameResources(const FrameConfig& config, const std::vector<VirtualObject>& objects)
    : config_(config),
      gbufferProgram_(gl::Program::graphics("lighting/frame/mesh.vert", "lighting/frame/gbuffer.frag")),
      rsmProgram_(gl::Program::graphics("lighting/frame/mesh.vert", "lighting/frame/rsm.frag")),
      shadowProgram_(gl::Program::graphics("lighting/frame/mesh.vert", "lighting/frame/shadow.frag")),
      objectPosition_(GL_TEXTURE_2D, GL_RGBA32F, config.knobs.shadowSize, config.knobs.shadowSize),
      objectDepth_(GL_TEXTURE_2D, GL_DEPTH_COMPONENT32F, config.knobs.shadowSize, config.knobs.shadowSize),
      gPosition_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      gNormal_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      gAlbedo_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      gDepth_(GL_TEXTURE_2D, GL_DEPTH_COMPONENT32F, config.width, config.height) {
  for (auto* t : {&gPosition_, &gNormal_, &gAlbedo_}) t->setFilter(GL_NEAREST, GL_NEAREST);
  gbufferFb_.attachColour(0, gPosition_);
  gbufferFb_.attachColour(1, gNormal_);
  gbufferFb_.attachColour(2, gAlbedo_);
  gbufferFb_.attachDepth(gDepth_);
  gbufferFb_.finalise(3);
  objectPosition_.setFilter(GL_NEAREST, GL_NEAREST);
  objectFb_.attachColour(0, objectPosition_);
  objectFb_.attachDepth(objectDepth_);
  objectFb_.finalise(1);
  rsmRho_ = makeRsm(config.knobs.rsmSize);
  rsmMu_ = makeRsm(config.knobs.rsmSize);
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

Rsm FrameResources::makeRsm(int size) const {
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

void FrameResources::setRealMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices) {
  realMesh_ = GpuMesh(vertices, indices);
  realVertices_ = std::move(vertices);
  realIndices_ = std::move(indices);
  geometryDirty_ = true;
}

void FrameResources::setViewMesh(const std::vector<MeshVertex>& vertices, const std::vector<uint32_t>& indices) {
  viewMesh_ = GpuMesh(vertices, indices);
  viewDirty_ = true;
}

void FrameResources::setRealPixelAlbedo(const cv::Mat& albedo) {
  const bool use =
      !albedo.empty() && albedo.type() == CV_32FC3 && albedo.cols == config_.width && albedo.rows == config_.height;
  if (!use && !hasPixelAlbedo_) return;
  hasPixelAlbedo_ = use;
  viewDirty_ = true;
  if (!use) return;
  if (pixelAlbedo_.id() == 0) {
    pixelAlbedo_ = gl::Texture(GL_TEXTURE_2D, GL_RGBA16F, config_.width, config_.height);
    pixelAlbedo_.setFilter(GL_NEAREST, GL_NEAREST);
  }
  // Half floats, four channels: what the texture holds, so the driver converts nothing (an albedo needs no
  // more than half precision: 2^-11 relative).
  cv::Mat rgba, half;
  cv::cvtColor(albedo, rgba, cv::COLOR_RGB2RGBA);
  rgba.convertTo(half, CV_16F);
  pixelAlbedo_.upload(GL_RGBA, GL_HALF_FLOAT, half.data, 8);
}

void FrameResources::setObjectTransform(size_t i, const cv::Matx44d& T) { objects_.at(i).T_world_object = T; }

void FrameResources::setTechniqueInput(const std::string& technique, std::shared_ptr<const TechniqueInput> input) {
  techniqueInputs_[technique] = std::move(input);
  ownDirty_ = true;
}

const TechniqueInput* FrameResources::techniqueInput(const std::string& technique) const {
  const auto it = techniqueInputs_.find(technique);
  return it == techniqueInputs_.end() ? nullptr : it->second.get();
}

void FrameResources::invalidate() {
  seen_.reset();
  geometryDirty_ = ownDirty_ = true;
}

void setLightUniforms(const gl::Program& p, const std::vector<SceneLight>& lights,
                      const std::vector<LightView>& views) {
  p.set("uLightCount", static_cast<int>(lights.size()));
  for (size_t i = 0; i < lights.size(); ++i) {
    std::string k(1, '[');  // "[i]", the uniform array index
    k += std::to_string(i);
    k += ']';
    const SceneLight& l = lights[i];
    p.set("uLightType" + k, shaderLightType(l.type));
    setVec3(p, "uLightPosition" + k, l.position);
    setVec3(p, "uLightDirection" + k, l.direction);
    setVec3(p, "uLightPower" + k, l.type == LightType::Directional ? l.irradiance : l.intensity);
    p.set("uSpotCos" + k, static_cast<float>(l.spotCos()));
    if (i < views.size()) {
      const auto m = toGl(views[i].viewProj);
      p.setMat4("uLightViewProj" + k, m.data());
      p.set("uShadowBias" + k, static_cast<float>(views[i].shadowBias));
      const auto o = toGl(views[i].objectViewProj);
      p.setMat4("uObjectViewProj" + k, o.data());
      p.set("uObjectShadowBias" + k,
            views[i].objectShadowBias >= 0 ? static_cast<float>(views[i].objectShadowBias) : -1e30f);
    } else {
      p.set("uShadowBias" + k, -1e30f);  // no map: nothing occludes
      p.set("uObjectShadowBias" + k, -1e30f);
    }
  }
}

const FrameVersions& FrameResources::update(const CameraView& camera, const std::vector<SceneLight>& lights,
                                            const cv::Vec3d& ambient) {
  if (static_cast<int>(lights.size()) > kMaxLights)
    throw std::invalid_argument("at most " + std::to_string(kMaxLights) + " lights are supported, got " +
                                std::to_string(lights.size()));
  // Exact comparison: any change counts.
  Seen in;
  in.camera = {camera.intrinsics.fx,
               camera.intrinsics.fy,
               camera.intrinsics.cx,
               camera.intrinsics.cy,
               static_cast<double>(camera.intrinsics.width),
               static_cast<double>(camera.intrinsics.height),
               camera.nearPlane,
               camera.farPlane};
  for (int i = 0; i < 16; ++i) in.camera.push_back(camera.T_world_camera.val[i]);
  for (const FrameObject& o : objects_)
    in.objects.insert(in.objects.end(), o.T_world_object.val, o.T_world_object.val + 16);
  for (const SceneLight& l : lights) {
    in.lights.insert(in.lights.end(), {static_cast<double>(l.type), l.spotHalfAngleDeg});
    for (const cv::Vec3d* v : {&l.position, &l.direction, &l.intensity, &l.irradiance})
      in.lights.insert(in.lights.end(), v->val, v->val + 3);
  }
  in.ambient = {ambient[0], ambient[1], ambient[2]};
  for (const cv::Vec3d& c : ambientSh_) in.ambient.insert(in.ambient.end(), c.val, c.val + 3);
  const bool fresh = !seen_;
  if (fresh || viewDirty_ || in.camera != seen_->camera) ++versions_.camera;
  viewDirty_ = false;
  if (fresh || geometryDirty_ || in.objects != seen_->objects) ++versions_.geometry;
  if (fresh || in.lights != seen_->lights) ++versions_.lights;
  if (fresh || in.ambient != seen_->ambient) ++versions_.ambient;
  if (fresh || ownDirty_) ++versions_.own;
  geometryDirty_ = ownDirty_ = false;
  seen_ = std::move(in);
  camera_ = camera;
  lights_ = lights;
  ambient_ = ambient;
  return versions_;
}

std::optional<std::pair<cv::Vec3d, cv::Vec3d>> FrameResources::objectBounds() const {
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

void FrameResources::fitRegionToObjects() {
  region_ = config_.fixedRegion;
  if (region_) return;
  if (const auto b = objectBounds()) region_ = fitRegion(b->first, b->second, config_.knobs.sizeFactor);
}

void FrameResources::drawScene(const gl::Program& program, bool includeVirtual, const cv::Matx44d& viewProj,
                               bool cameraView) const {
  program.use();
  const auto vp = toGl(viewProj);
  program.setMat4("uViewProj", vp.data());
  const auto id = toGl(cv::Matx44d::eye());
  program.setMat4("uModel", id.data());
  setMat3(program, "uNormalModel", cv::Matx33f::eye());
  program.set("uVirtual", 0.0f);
  program.set("uObject", 0.0f);
  if (cameraView && !viewMesh_.empty())
    viewMesh_.draw();
  else
    realMesh_.draw();
  if (includeVirtual) drawObjects(program);
}

void FrameResources::drawObjects(const gl::Program& program) const {
  program.use();
  program.set("uVirtual", 1.0f);
  for (size_t i = 0; i < objects_.size(); ++i) {
    program.set("uObject", static_cast<float>(i + 1));
    const auto m = toGl(objects_[i].T_world_object);
    program.setMat4("uModel", m.data());
    setMat3(program, "uNormalModel", normalMatrix(objects_[i].T_world_object));
    objects_[i].gpu.draw();
  }
}

void FrameResources::renderGBuffer() {
  gbufferFb_.bind();
  glViewport(0, 0, config_.width, config_.height);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  const float zero[4] = {0, 0, 0, 0};
  for (int i = 0; i < 3; ++i) glClearNamedFramebufferfv(gbufferFb_.id(), GL_COLOR, i, zero);
  const float one = 1.0f;
  glClearNamedFramebufferfv(gbufferFb_.id(), GL_DEPTH, 0, &one);
  const cv::Matx44d view = capture::inversePose(camera_.T_world_camera);
  setVec3(gbufferProgram_, "uEye", capture::translationOf(camera_.T_world_camera));
  gbufferProgram_.set("uPixelAlbedo", hasPixelAlbedo_ ? 1 : 0);
  if (hasPixelAlbedo_) pixelAlbedo_.bind(0);
  drawScene(gbufferProgram_, true,
            projectionFromIntrinsics(camera_.intrinsics, camera_.nearPlane, camera_.farPlane) * view, true);
  glDisable(GL_DEPTH_TEST);
}

void FrameResources::renderRsm(Rsm& rsm, const SceneLight& light, const LightView& view, bool includeVirtual) {
  const int size = rsmSize();
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
  drawScene(p, includeVirtual, view.viewProj);
}

void FrameResources::renderLight(size_t i) {
  if (!region_) throw std::logic_error("FrameResources::renderLight(): no region (no virtual object placed)");
  if (views_.size() != i) throw std::logic_error("FrameResources::renderLight(): lights must be rendered in order");
  const SceneLight& light = lights_.at(i);
  LightView view = fitLightView(light, *region_, rsmSize());
  const auto bounds = objectBounds();
  if (bounds)
    fitObjectView(view, light, 0.5 * (bounds->first + bounds->second), 0.5 * cv::norm(bounds->second - bounds->first),
                  config_.knobs.shadowSize);
  views_.push_back(view);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  renderRsm(rsmRho_, light, views_.back(), true);
  renderRsm(rsmMu_, light, views_.back(), false);
  const int m = config_.knobs.shadowSize;
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
    drawObjects(shadowProgram_);
  }
  glDisable(GL_DEPTH_TEST);
  const int n = rsmSize();
  // Shadow arrays: one layer per light of this run (allocated for the lights there are).
  const int layers = static_cast<int>(lights_.size());
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

ShadowTexels FrameResources::downloadShadowTexels(size_t i) const {
  if (i >= views_.size())
    throw std::out_of_range("FrameResources::downloadShadowTexels(): no such light in the last run");
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

float shadowTest(const cv::Mat& positions, const SceneLight& light, const cv::Matx44d& viewProj, double bias,
                 cv::Vec3d x, const cv::Vec3d& n) {
  if (bias < 0 || positions.empty()) return 1.f;
  x += n * bias;
  const cv::Vec4d c = viewProj * cv::Vec4d(x[0], x[1], x[2], 1.0);
  if (c[3] <= 0) return 1.f;
  const double u = c[0] / c[3], v = c[1] / c[3];
  if (std::abs(u) > 1 || std::abs(v) > 1) return 1.f;
  const int col = std::clamp(static_cast<int>(std::floor((u * 0.5 + 0.5) * positions.cols)), 0, positions.cols - 1);
  const int row = std::clamp(static_cast<int>(std::floor((v * 0.5 + 0.5) * positions.rows)), 0, positions.rows - 1);
  const cv::Vec4f s = positions.at<cv::Vec4f>(row, col);
  if (s[3] < 0.5f) return 1.f;
  const cv::Vec3d occ(s[0], s[1], s[2]);
  double self, other;
  if (light.type == LightType::Directional) {
    self = x.dot(light.direction);
    other = occ.dot(light.direction);
  } else {
    self = cv::norm(x - light.position);
    other = cv::norm(occ - light.position);
  }
  return other < self - bias ? 0.f : 1.f;
}

float lightVisibility(const ShadowTexels& maps, const SceneLight& light, const LightView& view, bool withObjects,
                      const cv::Vec3d& x, const cv::Vec3d& n) {
  if (!withObjects) return shadowTest(maps.mu, light, view.viewProj, view.shadowBias, x, n);
  if (view.objectShadowBias < 0) return shadowTest(maps.rho, light, view.viewProj, view.shadowBias, x, n);
  return shadowTest(maps.mu, light, view.viewProj, view.shadowBias, x, n) *
         shadowTest(maps.objects, light, view.objectViewProj, view.objectShadowBias, x, n);
}

cv::Vec3d unshadowedIrradiance(const SceneLight& light, const cv::Vec3d& x, const cv::Vec3d& n) {
  if (light.type == LightType::Directional) return light.irradiance * std::max(-n.dot(light.direction), 0.0);
  const cv::Vec3d l = light.position - x;
  const double d2 = std::max(l.dot(l), 1e-8);
  const cv::Vec3d ln = l / std::sqrt(d2);
  if (light.type == LightType::Spot && (-ln).dot(light.direction) < light.spotCos()) return {0, 0, 0};
  return light.intensity * (std::max(n.dot(ln), 0.0) / d2);
}

void FrameResources::bindShadowMaps() const {
  shadowRho_.bind(12);
  shadowMu_.bind(13);
  shadowObjects_.bind(14);
}

RsmTexels FrameResources::downloadRsm(bool rho) const {
  const Rsm& r = rho ? rsmRho_ : rsmMu_;
  return {download4(r.position), download4(r.normal), download4(r.flux), download4(r.direct)};
}

const gl::Texture& FrameResources::zero() {
  if (!zero_.id()) {
    zero_ = gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, config_.width, config_.height);
    zero_.setFilter(GL_NEAREST, GL_NEAREST);
    zero_.clear();
  }
  return zero_;
}

cv::Mat FrameResources::downloadGBuffer(int channel) const {
  return download4(channel == 0 ? gPosition_ : channel == 1 ? gNormal_ : gAlbedo_);
}

size_t FrameResources::estimateBytes(const FrameConfig& c, size_t lights) {
  const size_t pixels = static_cast<size_t>(c.width) * static_cast<size_t>(c.height);
  const size_t texels = static_cast<size_t>(c.knobs.rsmSize) * static_cast<size_t>(c.knobs.rsmSize);
  const size_t rgba = 16, depth = 4;
  const size_t gbuffer = pixels * (3 * rgba + depth) + pixels * rgba;  // + the zero stand-in
  const size_t rsms = 2 * texels * (4 * rgba + depth);
  const size_t objectTexels = static_cast<size_t>(c.knobs.shadowSize) * static_cast<size_t>(c.knobs.shadowSize);
  const size_t shadows = std::max<size_t>(lights, 1) * (2 * texels + objectTexels) * rgba;
  return gbuffer + rsms + objectTexels * (rgba + depth) + shadows;
}

size_t FrameResources::gpuBytes() const {
  size_t sum = 0;
  for (const gl::Texture* t : {&gPosition_, &gNormal_, &gAlbedo_, &gDepth_, &shadowRho_, &shadowMu_, &shadowObjects_,
                               &objectPosition_, &objectDepth_, &zero_})
    sum += t->bytes();
  for (const Rsm* r : {&rsmRho_, &rsmMu_})
    for (const gl::Texture* t : {&r->position, &r->normal, &r->flux, &r->direct, &r->depth}) sum += t->bytes();
  return sum;
}

}  // namespace mrgi::lighting
