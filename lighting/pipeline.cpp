#include "lighting/pipeline.h"

#include <algorithm>
#include <cmath>
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

void buildRealVertices(const reconstruction::DepthMesh& mesh, const cv::Mat& albedo, const capture::Pose& T_world_camera,
                       std::vector<MeshVertex>& vertices, std::vector<uint32_t>& indices) {
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
  return {2 * k.fx / W, 0, 2 * (k.cx + 0.5) / W - 1, 0,  //
          0, 2 * k.fy / H, 2 * (k.cy + 0.5) / H - 1, 0,  //
          0, 0, (f + n) / (f - n), -2 * f * n / (f - n),  //
          0, 0, 1, 0};
}

cv::Matx44d orthographicProjection(double h, double n, double f) {
  return {1 / h, 0, 0, 0,  //
          0, 1 / h, 0, 0,  //
          0, 0, 2 / (f - n), -(f + n) / (f - n),  //
          0, 0, 0, 1};
}

std::array<float, 16> toGl(const cv::Matx44d& m) {
  std::array<float, 16> out;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) out[c * 4 + r] = static_cast<float>(m(r, c));
  return out;
}

LightView fitLightView(const SceneLight& light, const LpvGrid& grid, int size) {
  LightView v;
  const cv::Vec3d centre = grid.centre();
  const double radius = 0.5 * std::sqrt(3.0) * grid.side();
  if (light.type == LightType::Directional) {
    const double back = 4.0 * radius;  // room for occluders in front of the volume
    const cv::Vec3d eye = centre - light.direction * back;
    v.viewProj = orthographicProjection(radius, 0.0, back + radius) *
                 capture::inversePose(capture::lookAtPose(eye, centre));
    const double texel = 2.0 * radius / size;
    v.texelArea = texel * texel;
    v.shadowBias = 2.0 * texel;
  } else {
    const double dist = cv::norm(centre - light.position);
    if (dist < 1e-6) throw std::invalid_argument("a point light sits at the centre of the volume");
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

// ---------------------------------------------------------------------------------------------- pipeline

namespace {
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

/// A timed stage when there is a profiler (GPU timer queries too when `gpu`).
std::optional<gl::Profiler::Scope> timed(gl::Profiler* profiler, const char* name, bool gpu = true) {
  return profiler ? std::optional<gl::Profiler::Scope>(std::in_place, *profiler, name, gpu) : std::nullopt;
}

/// A receiver at (p, n) seen from `eye`.
Receiver seenFrom(const cv::Vec3f& p, const cv::Vec3f& n, const cv::Vec3f& eye, float exponent) {
  const cv::Vec3f toEye = eye - p;
  return {p, n, cv::norm(toEye) > 0 ? cv::normalize(toEye) : n, exponent};
}

/// uLightType of the shaders: 0 point, 1 spot, 2 directional.
int shaderLightType(LightType t) { return t == LightType::Point ? 0 : t == LightType::Spot ? 1 : 2; }

void setVec3(const gl::Program& p, const std::string& name, const cv::Vec3d& v) {
  p.set(name, static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
}
}  // namespace

LightingPipeline::LightingPipeline(const PipelineConfig& config, const std::vector<VirtualObject>& objects)
    : config_(config),
      gbufferProgram_(gl::Program::graphics("lighting/mesh.vert", "lighting/gbuffer.frag")),
      rsmProgram_(gl::Program::graphics("lighting/mesh.vert", "lighting/rsm.frag")),
      injectProgram_(gl::Program::graphics("lighting/lpv_inject.vert", "lighting/lpv_inject.geom", "lighting/lpv_inject.frag")),
      propagateProgram_(gl::Program::compute("lighting/lpv_propagate.comp")),
      addProgram_(gl::Program::compute("lighting/lpv_add.comp")),
      shadeProgram_(gl::Program::graphics("compositor/fullscreen.vert", "lighting/shade.frag")),
      gPosition_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      gNormal_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      gAlbedo_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      gDepth_(GL_TEXTURE_2D, GL_DEPTH_COMPONENT32F, config.width, config.height),
      shade_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      irradiance_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      shadowArray_(GL_TEXTURE_2D_ARRAY, GL_RGBA32F, config.lpv.rsmSize, config.lpv.rsmSize, kMaxLights) {
  for (auto* t : {&gPosition_, &gNormal_, &gAlbedo_, &shade_, &irradiance_}) t->setFilter(GL_NEAREST, GL_NEAREST);
  shadowArray_.setFilter(GL_NEAREST, GL_NEAREST);
  gbufferFb_.attachColour(0, gPosition_);
  gbufferFb_.attachColour(1, gNormal_);
  gbufferFb_.attachColour(2, gAlbedo_);
  gbufferFb_.attachDepth(gDepth_);
  gbufferFb_.finalise(3);
  shadeFb_.attachColour(0, shade_);
  shadeFb_.attachColour(1, irradiance_);
  shadeFb_.finalise(2);
  rsmRho_ = makeRsm(config.lpv.rsmSize);
  rsmMu_ = makeRsm(config.lpv.rsmSize);

  for (const VirtualObject& o : objects) {
    std::vector<MeshVertex> v(o.mesh.positions.size());
    for (size_t i = 0; i < v.size(); ++i) v[i] = {o.mesh.positions[i], o.mesh.normals[i], o.material.albedo};
    objectMeshes_.emplace_back(v, o.mesh.indices);
    objectTransforms_.push_back(o.T_marker_object);
    objectBoundsMin_.push_back(o.mesh.boundsMin);
    objectBoundsMax_.push_back(o.mesh.boundsMax);
  }

  if (usesVal(config.technique)) {
    // Sparse points and per-vertex weights depend on the mesh only (model space): computed once.
    for (const VirtualObject& o : objects) {
      ValObject vo;
      vo.material = o.material;
      vo.points = sampleSparsePoints(o.mesh, config.val.sparsePoints);
      const VertexWeights w = vertexWeights(o.mesh, vo.points);
      constexpr int K = VertexWeights::kNeighbours;
      static_assert(K == 8);
      struct Packed {
        int32_t index[8];
        float weight[8];
      };
      std::vector<Packed> packed(o.mesh.positions.size());
      for (size_t v = 0; v < packed.size(); ++v)
        for (int k = 0; k < K; ++k) {
          packed[v].index[k] = w.index[v * K + k];
          packed[v].weight[k] = w.weight[v * K + k];
        }
      vo.weights = gl::Buffer(static_cast<GLsizeiptr>(std::max<size_t>(packed.size(), 1) * sizeof(Packed)),
                              packed.empty() ? nullptr : packed.data());
      valObjects_.push_back(std::move(vo));
    }
    valGpu_.emplace(config.val.kCache);
    valMeshProgram_ = gl::Program::graphics("lighting/val_mesh.vert", "lighting/val_mesh.frag");
    valRadiance_ = gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height);
    valIrradiance_ = gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height);
    valRadiance_.setFilter(GL_NEAREST, GL_NEAREST);
    valIrradiance_.setFilter(GL_NEAREST, GL_NEAREST);
    valFb_.attachColour(0, valRadiance_);
    valFb_.attachColour(1, valIrradiance_);
    valFb_.attachDepth(gDepth_);
    valFb_.finalise(2);
  }
  if (config.technique == Technique::KinectVal) {
    shadowMuArray_ = gl::Texture(GL_TEXTURE_2D_ARRAY, GL_RGBA32F, config.lpv.rsmSize, config.lpv.rsmSize, kMaxLights);
    shadowMuArray_.setFilter(GL_NEAREST, GL_NEAREST);
  }
}

LightingPipeline::Volume LightingPipeline::makeVolume(int res) const {
  Volume v{gl::Texture(GL_TEXTURE_3D, GL_RGBA32F, res, res, res), gl::Texture(GL_TEXTURE_3D, GL_RGBA32F, res, res, res),
           gl::Texture(GL_TEXTURE_3D, GL_RGBA32F, res, res, res), gl::Framebuffer()};
  v.fb.attachColour(0, v.r);
  v.fb.attachColour(1, v.g);
  v.fb.attachColour(2, v.b);
  v.fb.finalise(3);
  return v;
}

LightingPipeline::Rsm LightingPipeline::makeRsm(int size) const {
  Rsm r{gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, size, size), gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, size, size),
        gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, size, size), gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, size, size),
        gl::Texture(GL_TEXTURE_2D, GL_DEPTH_COMPONENT32F, size, size), gl::Framebuffer()};
  for (auto* t : {&r.position, &r.normal, &r.flux, &r.direct}) t->setFilter(GL_NEAREST, GL_NEAREST);
  r.fb.attachColour(0, r.position);
  r.fb.attachColour(1, r.normal);
  r.fb.attachColour(2, r.flux);
  r.fb.attachColour(3, r.direct);
  r.fb.attachDepth(r.depth);
  r.fb.finalise(4);
  return r;
}

void LightingPipeline::setRealMesh(const std::vector<MeshVertex>& vertices, const std::vector<uint32_t>& indices) {
  realMesh_ = GpuMesh(vertices, indices);
  ++realMeshVersion_;
}

void LightingPipeline::setObjectTransform(size_t i, const cv::Matx44d& T) { objectTransforms_.at(i) = T; }

void LightingPipeline::drawScene(const gl::Program& program, bool includeVirtual, const cv::Matx44d& viewProj) const {
  program.use();
  const auto vp = toGl(viewProj);
  program.setMat4("uViewProj", vp.data());
  const auto id = toGl(cv::Matx44d::eye());
  program.setMat4("uModel", id.data());
  setMat3(program, "uNormalModel", cv::Matx33f::eye());
  program.set("uVirtual", 0.0f);
  program.set("uObject", 0.0f);
  realMesh_.draw();
  if (!includeVirtual) return;
  program.set("uVirtual", 1.0f);
  for (size_t i = 0; i < objectMeshes_.size(); ++i) {
    program.set("uObject", static_cast<float>(i + 1));
    const auto m = toGl(objectTransforms_[i]);
    program.setMat4("uModel", m.data());
    setMat3(program, "uNormalModel", normalMatrix(objectTransforms_[i]));
    objectMeshes_[i].draw();
  }
}

void LightingPipeline::renderRsm(Rsm& rsm, const SceneLight& light, const LightView& view, bool includeVirtual) {
  const int size = config_.lpv.rsmSize;
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

void LightingPipeline::inject(Volume& target, const Rsm& source, const Rsm* other, float sign, unsigned mode,
                              const SceneLight& light) {
  const LpvGrid& g = *grid_;
  const gl::Program& p = injectProgram_;
  target.fb.bind();
  glViewport(0, 0, g.resolution, g.resolution);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE);
  glBlendEquation(GL_FUNC_ADD);
  p.use();
  p.set("uSize", config_.lpv.rsmSize);
  p.set("uSign", sign);
  p.set("uMode", static_cast<int>(mode));
  p.set("uSkipIdentical", other ? 1 : 0);
  p.set("uLightType", shaderLightType(light.type));
  setVec3(p, "uLightPosition", light.position);
  setVec3(p, "uLightDirection", light.direction);
  setVec3(p, "uGridOrigin", g.origin);
  p.set("uCellSize", static_cast<float>(g.cellSize));
  p.set("uResolution", g.resolution);
  source.position.bind(0);
  source.normal.bind(1);
  source.flux.bind(2);
  source.direct.bind(3);
  const Rsm& o = other ? *other : source;
  o.position.bind(4);
  o.normal.bind(5);
  o.flux.bind(6);
  o.direct.bind(7);
  emptyVao_.bind();
  glDrawArraysInstanced(GL_POINTS, 0, config_.lpv.rsmSize * config_.lpv.rsmSize, 2);
  glDisable(GL_BLEND);
}

void LightingPipeline::add(const Volume& src, Volume& dst) {
  const int res = grid_->resolution;
  const gl::Program& p = addProgram_;
  p.use();
  p.set("uResolution", res);
  src.r.bind(0);
  src.g.bind(1);
  src.b.bind(2);
  glBindImageTexture(0, dst.r.id(), 0, GL_TRUE, 0, GL_READ_WRITE, GL_RGBA32F);
  glBindImageTexture(1, dst.g.id(), 0, GL_TRUE, 0, GL_READ_WRITE, GL_RGBA32F);
  glBindImageTexture(2, dst.b.id(), 0, GL_TRUE, 0, GL_READ_WRITE, GL_RGBA32F);
  const GLuint groups = static_cast<GLuint>((res + 3) / 4);
  glDispatchCompute(groups, groups, groups);
  glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
}

void LightingPipeline::propagate(Volume& v, bool clampNegative, const Volume* late) {
  const int res = grid_->resolution;
  const int steps = config_.lpv.steps;
  const int lateAt = std::max(0, steps - config_.lpv.directSteps);
  if (steps == 0) {
    if (late) add(*late, v);
    return;
  }
  for (auto [src, dst] : {std::pair{&v.r, &scratchA_.r}, {&v.g, &scratchA_.g}, {&v.b, &scratchA_.b}})
    glCopyImageSubData(src->id(), GL_TEXTURE_3D, 0, 0, 0, 0, dst->id(), GL_TEXTURE_3D, 0, 0, 0, 0, res, res, res);
  const gl::Program& p = propagateProgram_;
  p.use();
  p.set("uResolution", res);
  p.set("uDamping", static_cast<float>(config_.lpv.damping));
  p.set("uClampNegative", clampNegative ? 1 : 0);
  Volume* cur = &scratchA_;
  Volume* nxt = &scratchB_;
  const GLuint groups = static_cast<GLuint>((res + 3) / 4);
  for (int s = 0; s < steps; ++s) {
    if (late && s == lateAt) {
      add(*late, v);
      add(*late, *cur);
      p.use();
    }
    cur->r.bind(0);
    cur->g.bind(1);
    cur->b.bind(2);
    glBindImageTexture(0, nxt->r.id(), 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glBindImageTexture(1, nxt->g.id(), 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glBindImageTexture(2, nxt->b.id(), 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glBindImageTexture(3, v.r.id(), 0, GL_TRUE, 0, GL_READ_WRITE, GL_RGBA32F);
    glBindImageTexture(4, v.g.id(), 0, GL_TRUE, 0, GL_READ_WRITE, GL_RGBA32F);
    glBindImageTexture(5, v.b.id(), 0, GL_TRUE, 0, GL_READ_WRITE, GL_RGBA32F);
    glDispatchCompute(groups, groups, groups);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
    std::swap(cur, nxt);
  }
  if (late && lateAt >= steps) add(*late, v);
}

void LightingPipeline::run(const CameraView& camera, const std::vector<SceneLight>& lights,
                           const cv::Vec3d& ambientRadiance, gl::Profiler* profiler) {
  if (static_cast<int>(lights.size()) > kMaxLights)
    throw std::invalid_argument("at most " + std::to_string(kMaxLights) + " lights are supported, got " +
                                std::to_string(lights.size()));
  auto scope = [&](const char* name) { return timed(profiler, name); };
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);

  // Which stages the inputs require (exact comparison: any change recomputes).
  RunInputs in;
  in.camera = {camera.intrinsics.fx, camera.intrinsics.fy, camera.intrinsics.cx, camera.intrinsics.cy,
               static_cast<double>(camera.intrinsics.width), static_cast<double>(camera.intrinsics.height),
               camera.nearPlane, camera.farPlane};
  for (int i = 0; i < 16; ++i) in.camera.push_back(camera.T_world_camera.val[i]);
  for (const auto& T : objectTransforms_) in.objects.insert(in.objects.end(), T.val, T.val + 16);
  for (const SceneLight& l : lights) {
    in.lights.insert(in.lights.end(), {static_cast<double>(l.type), l.spotHalfAngleDeg});
    for (const cv::Vec3d* v : {&l.position, &l.direction, &l.intensity, &l.irradiance}) in.lights.insert(in.lights.end(), v->val, v->val + 3);
  }
  in.ambient = {ambientRadiance[0], ambientRadiance[1], ambientRadiance[2]};
  in.realMesh = realMeshVersion_;
  in.realVals = realValsVersion_;
  const bool fresh = !cache_;
  const bool geometryChanged = fresh || in.realMesh != cache_->realMesh || in.objects != cache_->objects;
  const bool cameraChanged = fresh || in.camera != cache_->camera;
  const bool needGbuffer = geometryChanged || cameraChanged;
  const bool needLights = geometryChanged || in.lights != cache_->lights;
  const bool needVal = needLights || cameraChanged || in.realVals != cache_->realVals || in.ambient != cache_->ambient;
  const bool needShade = needGbuffer || needVal;  // needVal already covers lights, real VALs and ambient
  cache_ = std::move(in);
  skipped_.clear();
  if (!needGbuffer) skipped_.push_back("gbuffer");
  if (!needLights) skipped_.insert(skipped_.end(), {"rsm", "lpv"});
  if (usesVal(config_.technique) && !needVal) skipped_.push_back("val");
  if (!needShade) {
    skipped_.push_back("shade");
    return;
  }

  // The volume: axis-aligned in the world, centred on and sized to the virtual objects.
  grid_ = config_.fixedGrid;
  if (!grid_ && !objectMeshes_.empty()) {
    cv::Vec3d lo = cv::Vec3d::all(1e30), hi = cv::Vec3d::all(-1e30);
    for (size_t i = 0; i < objectMeshes_.size(); ++i)
      for (int c = 0; c < 8; ++c) {
        const cv::Vec3d corner((c & 1) ? objectBoundsMax_[i][0] : objectBoundsMin_[i][0],
                               (c & 2) ? objectBoundsMax_[i][1] : objectBoundsMin_[i][1],
                               (c & 4) ? objectBoundsMax_[i][2] : objectBoundsMin_[i][2]);
        const cv::Vec3d w = capture::transformPoint(objectTransforms_[i], corner);
        for (int k = 0; k < 3; ++k) {
          lo[k] = std::min(lo[k], w[k]);
          hi[k] = std::max(hi[k], w[k]);
        }
      }
    grid_ = fitGrid(lo, hi, config_.lpv.sizeFactor, config_.lpv.resolution);
  }
  const bool diff = config_.technique == Technique::LpvDiff;
  const bool lpv = usesLpv(config_.technique), val = usesVal(config_.technique);
  if (lpv && grid_ && grid_->resolution != volumeRes_) {
    volumeRes_ = grid_->resolution;
    delta_ = makeVolume(volumeRes_);
    deltaDirect_ = makeVolume(volumeRes_);
    if (!val) rho_ = makeVolume(volumeRes_);
    scratchA_ = makeVolume(volumeRes_);
    scratchB_ = makeVolume(volumeRes_);
    if (diff) {
      rhoFull_ = makeVolume(volumeRes_);
      muFull_ = makeVolume(volumeRes_);
      rhoDirect_ = makeVolume(volumeRes_);
      muDirect_ = makeVolume(volumeRes_);
    }
  }

  if (needGbuffer) {
    auto s = scope("gbuffer");
    gbufferFb_.bind();
    glViewport(0, 0, config_.width, config_.height);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    const float zero[4] = {0, 0, 0, 0};
    for (int i = 0; i < 3; ++i) glClearNamedFramebufferfv(gbufferFb_.id(), GL_COLOR, i, zero);
    const float one = 1.0f;
    glClearNamedFramebufferfv(gbufferFb_.id(), GL_DEPTH, 0, &one);
    const cv::Matx44d view = capture::inversePose(camera.T_world_camera);
    setVec3(gbufferProgram_, "uEye", capture::translationOf(camera.T_world_camera));
    drawScene(gbufferProgram_, true,
              projectionFromIntrinsics(camera.intrinsics, camera.nearPlane, camera.farPlane) * view);
  }

  // Every frame with new lights or geometry starts from cleared volumes.
  std::vector<LightView>& views = views_;
  if (needLights) {
    views.clear();
    rsmVals_.clear();
    shadowMaps_.clear();
  }
  if (grid_ && needLights) {
    for (Volume* v : {&delta_, &rho_, &rhoFull_, &muFull_, &deltaDirect_, &rhoDirect_, &muDirect_})
      if (v->r.id()) {
        v->r.clear();
        v->g.clear();
        v->b.clear();
      }
    for (size_t li = 0; li < lights.size(); ++li) {
      const SceneLight& light = lights[li];
      views.push_back(fitLightView(light, *grid_, config_.lpv.rsmSize));
      {
        auto s = scope("rsm");
        glEnable(GL_DEPTH_TEST);
        renderRsm(rsmRho_, light, views.back(), true);
        renderRsm(rsmMu_, light, views.back(), false);
        glDisable(GL_DEPTH_TEST);
        const int n = config_.lpv.rsmSize;
        glCopyImageSubData(rsmRho_.position.id(), GL_TEXTURE_2D, 0, 0, 0, 0, shadowArray_.id(), GL_TEXTURE_2D_ARRAY, 0,
                           0, 0, static_cast<GLint>(li), n, n, 1);
        if (shadowMuArray_.id())
          glCopyImageSubData(rsmMu_.position.id(), GL_TEXTURE_2D, 0, 0, 0, 0, shadowMuArray_.id(), GL_TEXTURE_2D_ARRAY,
                             0, 0, 0, static_cast<GLint>(li), n, n, 1);
      }
      if (val) {
        // The virtual object's lit texels become VALs (virtual -> virtual bounce).
        auto s = scope("val.rsm_vals");
        const RsmTexels rho = downloadRsm(true);
        const auto v = valsFromRsm(rho, light, config_.val.rsmStride);
        rsmVals_.insert(rsmVals_.end(), v.begin(), v.end());
        cv::Mat mu(rho.position.size(), CV_32FC4);
        rsmMu_.position.download(GL_RGBA, GL_FLOAT, mu.ptr(), static_cast<GLsizei>(mu.total() * mu.elemSize()), 4);
        shadowMaps_.push_back({light, views.back(), rho.position, mu});
      }
      if (!lpv) continue;
      auto s = scope("lpv.inject");
      if (!val) inject(rho_, rsmRho_, nullptr, 1.0f, kInjectIndirect, light);
      if (diff) {
        inject(rhoFull_, rsmRho_, nullptr, 1.0f, kInjectIndirect, light);
        inject(rhoDirect_, rsmRho_, nullptr, 1.0f, kInjectDirect, light);
        inject(muFull_, rsmMu_, nullptr, 1.0f, kInjectIndirect, light);
        inject(muDirect_, rsmMu_, nullptr, 1.0f, kInjectDirect, light);
      } else {
        // Delta injection, only where RSM^rho and RSM^mu differ: +VPLs of RSM^rho, -VPLs of RSM^mu, and the
        // direct light RSM^mu received there, negative (the virtual object now intercepts it; its own direct
        // light is shaded by the compositor and must not travel on through the object).
        inject(delta_, rsmRho_, &rsmMu_, 1.0f, kInjectIndirect, light);
        inject(delta_, rsmMu_, &rsmRho_, -1.0f, kInjectIndirect, light);
        inject(deltaDirect_, rsmMu_, &rsmRho_, -1.0f, kInjectDirect, light);
      }
    }
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    if (lpv) {
      auto s = scope("lpv.propagate");
      if (!val) propagate(rho_, true, nullptr);
      if (diff) {
        propagate(rhoFull_, true, &rhoDirect_);
        propagate(muFull_, true, &muDirect_);
      } else {
        propagate(delta_, false, &deltaDirect_);
      }
    }
  }
  if (grid_ && val && needVal) runVal(camera, ambientRadiance, profiler);

  auto s = scope("shade");
  shadeFb_.bind();
  glViewport(0, 0, config_.width, config_.height);
  glDisable(GL_DEPTH_TEST);
  const gl::Program& p = shadeProgram_;
  p.use();
  p.set("uLighting", grid_ ? 1 : 0);
  p.set("uRealMode", diff ? 1 : lpv ? 0 : 2);
  p.set("uVirtualMode", val ? 1 : 0);
  if (grid_) {
    setVec3(p, "uGridOrigin", grid_->origin);
    p.set("uCellSize", static_cast<float>(grid_->cellSize));
    p.set("uResolution", grid_->resolution);
  }
  setVec3(p, "uAmbient", ambientRadiance);
  p.set("uLightCount", static_cast<int>(lights.size()));
  for (size_t i = 0; i < lights.size(); ++i) {
    const std::string k = "[" + std::to_string(i) + "]";
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
    } else {
      p.set("uShadowBias" + k, -1e30f);  // no map: nothing occludes
    }
  }
  gPosition_.bind(0);
  gNormal_.bind(1);
  gAlbedo_.bind(2);
  const Volume& d = diff ? rhoFull_ : delta_;
  const Volume& mu = diff ? muFull_ : delta_;
  if (d.r.id()) {
    d.r.bind(3), d.g.bind(4), d.b.bind(5);
    mu.r.bind(6), mu.g.bind(7), mu.b.bind(8);
    rho_.r.bind(9), rho_.g.bind(10), rho_.b.bind(11);
  }  // without a volume uLighting = 0 and the shader samples none of them
  shadowArray_.bind(12);
  if (shadowMuArray_.id()) shadowMuArray_.bind(13);
  if (val) {
    valRadiance_.bind(14);
    valIrradiance_.bind(15);
  }
  emptyVao_.bind();
  glDrawArrays(GL_TRIANGLES, 0, 3);
  gl::checkGlError("LightingPipeline::run()");
}

namespace {
/// The shade pass's shadow-map test (shade.frag visibility()) on the CPU: 1 lit, 0 occluded.
float mapVisibility(const cv::Mat& positions, const SceneLight& light, const LightView& view, const cv::Vec3f& p,
                    const cv::Vec3f& n) {
  const cv::Vec3d x = cv::Vec3d(p) + cv::Vec3d(n) * std::max(view.shadowBias, 0.0);
  const cv::Vec4d c = view.viewProj * cv::Vec4d(x[0], x[1], x[2], 1.0);
  if (c[3] <= 0) return 1.f;
  const double u = c[0] / c[3], v = c[1] / c[3];
  if (std::abs(u) > 1 || std::abs(v) > 1) return 1.f;
  const int col = std::clamp(static_cast<int>((u * 0.5 + 0.5) * positions.cols), 0, positions.cols - 1);
  const int row = std::clamp(static_cast<int>((v * 0.5 + 0.5) * positions.rows), 0, positions.rows - 1);
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
  return other < self - view.shadowBias ? 0.f : 1.f;
}

/// Direct irradiance a light sends to (p, n) without shadowing.
cv::Vec3d lightIrradiance(const SceneLight& light, const cv::Vec3f& p, const cv::Vec3f& n) {
  if (light.type == LightType::Directional) return light.irradiance * std::max(-cv::Vec3d(n).dot(light.direction), 0.0);
  const cv::Vec3d l = light.position - cv::Vec3d(p);
  const double d2 = std::max(l.dot(l), 1e-8);
  const cv::Vec3d ln = l / std::sqrt(d2);
  if (light.type == LightType::Spot && (-ln).dot(light.direction) < light.spotCos())
    return {0, 0, 0};
  return light.intensity * (std::max(cv::Vec3d(n).dot(ln), 0.0) / d2);
}
}  // namespace

size_t LightingPipeline::shadowRealVals(std::vector<Val>& vals, const cv::Vec3d& ambientRadiance) const {
  // The camera saw the real surfaces without the virtual object; where the object now shadows them they
  // reflect less: exitance x E_with / E_without (direct light through RSM^rho vs RSM^mu, plus the ambient),
  // so the object's underside does not receive bounce from the table it shadows.
  size_t dimmed = 0;
  for (Val& v : vals) {
    cv::Vec3d with = CV_PI * ambientRadiance, without = with;
    for (const ShadowMaps& m : shadowMaps_) {
      const cv::Vec3d e = lightIrradiance(m.light, v.position, v.normal);
      if (e == cv::Vec3d(0, 0, 0)) continue;
      without += e * mapVisibility(m.mu, m.light, m.view, v.position, v.normal);
      with += e * mapVisibility(m.rho, m.light, m.view, v.position, v.normal);
    }
    if (with == without) continue;
    for (int c = 0; c < 3; ++c)
      if (without[c] > 0) v.flux[c] *= static_cast<float>(std::clamp(with[c] / without[c], 0.0, 1.0));
    ++dimmed;
  }
  return dimmed;
}

void LightingPipeline::runVal(const CameraView& camera, const cv::Vec3d& ambientRadiance, gl::Profiler* profiler) {
  auto scope = [&](const char* name) { return timed(profiler, name); };
  const cv::Vec3f eye(capture::translationOf(camera.T_world_camera));
  valStats_ = {realVals_.size(), rsmVals_.size(), 0, 0, config_.val.bruteForce};
  {
    auto s = scope("val.upload");
    vals_.clear();
    vals_.reserve(realVals_.size() + rsmVals_.size());
    vals_.insert(vals_.end(), realVals_.begin(), realVals_.end());
    valStats_.shadowedVals = shadowRealVals(vals_, ambientRadiance);
    vals_.insert(vals_.end(), rsmVals_.begin(), rsmVals_.end());
    setValWeights(vals_);
    valGpu_->setVals(vals_);
  }
  const float zero[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(valFb_.id(), GL_COLOR, 0, zero);
  glClearNamedFramebufferfv(valFb_.id(), GL_COLOR, 1, zero);
  if (config_.val.bruteForce) {
    valBruteForce(camera, profiler);
    return;
  }

  // Receivers: every object's sparse points in the lighting world, seen from the camera.
  std::vector<Receiver> receivers;
  std::vector<cv::Vec3f> positions, normals;
  std::vector<float> radii;
  std::vector<int> base;
  for (size_t o = 0; o < valObjects_.size(); ++o) {
    const ValObject& vo = valObjects_[o];
    base.push_back(static_cast<int>(receivers.size()));
    const cv::Matx44d& T = objectTransforms_[o];
    const cv::Matx33f N = normalMatrix(T);
    const float k = phongExponent(vo.material.roughness);
    for (size_t i = 0; i < vo.points.positions.size(); ++i) {
      const Receiver r = seenFrom(cv::Vec3f(capture::transformPoint(T, cv::Vec3d(vo.points.positions[i]))),
                                  cv::normalize(N * vo.points.normals[i]), eye, k);
      receivers.push_back(r);
      positions.push_back(r.position);
      normals.push_back(r.normal);
      radii.push_back(vo.points.discRadius[i]);
    }
  }
  valStats_.receivers = receivers.size();
  {
    auto s = scope("val.gather");
    valGpu_->gather(receivers);
  }
  if (config_.val.occlusion) {
    auto s = scope("val.occlude");
    valGpu_->occlude(positions, normals, radii);
  }

  // Per-vertex interpolation and per-pixel evaluation on the visible virtual surfaces.
  auto s = scope("val.shade");
  valFb_.bind();
  glViewport(0, 0, config_.width, config_.height);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glDepthMask(GL_FALSE);
  const gl::Program& p = valMeshProgram_;
  p.use();
  const auto vp = toGl(projectionFromIntrinsics(camera.intrinsics, camera.nearPlane, camera.farPlane) *
                       capture::inversePose(camera.T_world_camera));
  p.setMat4("uViewProj", vp.data());
  setVec3(p, "uEye", cv::Vec3d(eye));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, valGpu_->vplBuffer().id());
  for (size_t o = 0; o < valObjects_.size(); ++o) {
    const ValObject& vo = valObjects_[o];
    const auto m = toGl(objectTransforms_[o]);
    p.setMat4("uModel", m.data());
    setMat3(p, "uNormalModel", normalMatrix(objectTransforms_[o]));
    p.set("uBase", base[o]);
    setVec3(p, "uSpecular", cv::Vec3d(vo.material.specular, vo.material.specular, vo.material.specular));
    p.set("uExponent", phongExponent(vo.material.roughness));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, vo.weights.id());
    objectMeshes_[o].draw();
  }
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);
  glDisable(GL_DEPTH_TEST);
}

namespace {
cv::Mat download4(const gl::Texture& t) {
  cv::Mat m(t.height(), t.width(), CV_32FC4);
  t.download(GL_RGBA, GL_FLOAT, m.ptr(), static_cast<GLsizei>(m.total() * m.elemSize()), 4);
  return m;
}
}  // namespace

void LightingPipeline::valBruteForce(const CameraView& camera, gl::Profiler* profiler) {
  auto staging = timed(profiler, "val.bruteforce_staging", false);  // G-buffer read-back, radiance upload (CPU)
  // Every visible virtual pixel is a receiver of every VAL (no interpolation, no occlusion): the reference
  // the sparse method is measured against. The gather runs on the GPU; the per-pixel material comes from
  // the G-buffer (albedo) and the object index in the normal's w.
  const cv::Vec3f eye(capture::translationOf(camera.T_world_camera));
  const cv::Mat pos = download4(gPosition_), nrm = download4(gNormal_), alb = download4(gAlbedo_);
  std::vector<Receiver> receivers;
  std::vector<int> pixels, objects;
  for (int y = 0; y < pos.rows; ++y)
    for (int x = 0; x < pos.cols; ++x) {
      const cv::Vec4f p = pos.at<cv::Vec4f>(y, x), n = nrm.at<cv::Vec4f>(y, x), a = alb.at<cv::Vec4f>(y, x);
      if (p[3] < 0.5f || a[3] < 0.5f) continue;
      const int o = static_cast<int>(std::lround(n[3])) - 1;
      if (o < 0 || o >= static_cast<int>(valObjects_.size())) continue;
      receivers.push_back(
          seenFrom({p[0], p[1], p[2]}, {n[0], n[1], n[2]}, eye, phongExponent(valObjects_[o].material.roughness)));
      pixels.push_back(y * pos.cols + x);
      objects.push_back(o);
    }
  valStats_.receivers = receivers.size();
  {
    auto s = timed(profiler, "val.gather");
    valGpu_->gather(receivers);
  }
  std::vector<cv::Vec3f> E, S;
  valGpu_->downloadSums(E, S);
  cv::Mat radiance(pos.size(), CV_32FC4, cv::Scalar::all(0)), irradiance(pos.size(), CV_32FC4, cv::Scalar::all(0));
  for (size_t i = 0; i < receivers.size(); ++i) {
    const Material& m = valObjects_[static_cast<size_t>(objects[i])].material;
    const cv::Vec4f a = alb.at<cv::Vec4f>(pixels[i]);
    const cv::Vec3f L = valRadiance(E[i], S[i], {a[0], a[1], a[2]}, cv::Vec3f::all(m.specular), receivers[i].exponent);
    radiance.at<cv::Vec4f>(pixels[i]) = {L[0], L[1], L[2], 1.f};
    irradiance.at<cv::Vec4f>(pixels[i]) = {E[i][0], E[i][1], E[i][2], 1.f};
  }
  valRadiance_.upload(GL_RGBA, GL_FLOAT, radiance.ptr(), 4);
  valIrradiance_.upload(GL_RGBA, GL_FLOAT, irradiance.ptr(), 4);
}

void LightingPipeline::downloadValSums(std::vector<cv::Vec3f>& E, std::vector<cv::Vec3f>& S) const {
  E.clear();
  S.clear();
  if (valGpu_) valGpu_->downloadSums(E, S);
}

cv::Mat LightingPipeline::downloadShade() const { return download4(shade_); }
cv::Mat LightingPipeline::downloadIrradiance() const { return download4(irradiance_); }
cv::Mat LightingPipeline::downloadGBuffer(int channel) const {
  return download4(channel == 0 ? gPosition_ : channel == 1 ? gNormal_ : gAlbedo_);
}

const LightingPipeline::Volume* LightingPipeline::volume(const std::string& name) const {
  if (name == "delta") return &delta_;
  if (name == "rho") return &rho_;
  if (name == "rho_full") return &rhoFull_;
  if (name == "mu_full") return &muFull_;
  if (name == "delta_direct") return &deltaDirect_;
  if (name == "rho_direct") return &rhoDirect_;
  if (name == "mu_direct") return &muDirect_;
  throw std::invalid_argument("unknown volume '" + name + "'");
}

LpvVolumeCpu LightingPipeline::downloadVolume(const std::string& name) const {
  const Volume* v = volume(name);
  if (!grid_ || !v->r.id()) return LpvVolumeCpu(0);
  const int res = grid_->resolution;
  LpvVolumeCpu out(res);
  std::vector<float> buf(size_t(res) * res * res * 4);
  const gl::Texture* ch[3] = {&v->r, &v->g, &v->b};
  for (int c = 0; c < 3; ++c) {
    ch[c]->download(GL_RGBA, GL_FLOAT, buf.data(), static_cast<GLsizei>(buf.size() * sizeof(float)), 4);
    for (size_t n = 0; n < out.cells.size(); ++n)
      for (int i = 0; i < 4; ++i) out.cells[n][c][i] = buf[n * 4 + i];
  }
  return out;
}

RsmTexels LightingPipeline::downloadRsm(bool rho) const {
  const Rsm& r = rho ? rsmRho_ : rsmMu_;
  return {download4(r.position), download4(r.normal), download4(r.flux), download4(r.direct)};
}

size_t LightingPipeline::gpuBytes() const {
  size_t sum = 0;
  for (const gl::Texture* t : {&gPosition_, &gNormal_, &gAlbedo_, &gDepth_, &shade_, &irradiance_, &shadowArray_,
                               &valRadiance_, &valIrradiance_, &shadowMuArray_})
    sum += t->bytes();
  for (const Rsm* r : {&rsmRho_, &rsmMu_})
    for (const gl::Texture* t : {&r->position, &r->normal, &r->flux, &r->direct, &r->depth}) sum += t->bytes();
  for (const Volume* v : {&delta_, &rho_, &rhoFull_, &muFull_, &scratchA_, &scratchB_, &deltaDirect_, &rhoDirect_, &muDirect_})
    sum += v->r.bytes() + v->g.bytes() + v->b.bytes();
  return sum;
}

}  // namespace mrgi::lighting
