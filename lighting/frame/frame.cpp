#include "lighting/frame/frame.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "capture/colour.h"
#include "gl/error.h"
#include "lighting/material.h"
#include "lighting/upsample.h"

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
      {{"soft_shadow_lights",
        KnobType::Int,
        0,
        16,
        0,
        "how many lights with extent (a fisheye's or a room's discs, listed lights with radius_m or "
        "angular_radius_deg), the brightest at the region, cast the objects' soft shadows (24 shadow-map "
        "taps per pixel each; the shading pass's soft variant costs llvmpipe 20 ms a frame at 320 x 240 from the "
        "first); the others the hard shadow of their centre",
        {0, 16},
        {},
        true},
       &FrameKnobs::softShadowLights},
      {{"render_scale",
        KnobType::Real,
        0.25,
        1.0,
        1.0,
        "resolution of the techniques' per-pixel outputs (real-pixel delta, the objects' indirect light), of the "
        "frame's: 1, 1/2, 1/3 or 1/4 (the nearest); the shading pass brings them to every pixel by joint bilateral "
        "upsampling with the G-buffer's depth, normals and objects. Kinect-VAL's object light is per vertex, at full "
        "resolution either way",
        {0.5, 0.25},
        {0.5},
        false},
       &FrameKnobs::renderScale},
      {{"object_terms_scale",
        KnobType::Real,
        0.25,
        1.0,
        0.5,
        "resolution, of the frame's, of the shading pass's object terms on real surfaces (what the objects hide of "
        "the ambient and the room's light, what they reflect onto them: smooth over a surface) while render_scale "
        "is 1, else render_scale's: 1, 1/2, 1/3 or 1/4 (the nearest), upsampled as the techniques' outputs are; "
        "the objects' direct shadow stays at the frame's resolution",
        {1.0},
        {},
        false},
       &FrameKnobs::objectTermsScale},
      {{"object_terms_history",
        KnobType::Real,
        0.0,
        0.95,
        0.0,
        "weight of the previous frame's object terms, reprojected through the camera's pose, where its surface is "
        "the texel's (a real point within 2 % of the distance, normals within 25 degrees): an exponential average "
        "over frames that takes the depth map's per-frame noise out of them; dropped whenever the objects, the "
        "lights or the ambient change (0: each frame's own)",
        {0.8},
        {},
        false},
       &FrameKnobs::objectTermsHistory},
  };
  return table;
}

int objectTermsFactor(const FrameKnobs& knobs) {
  const int factor = renderFactor(knobs.renderScale);
  return factor > 1 ? factor : renderFactor(knobs.objectTermsScale);
}

const KnobGroup& frameKnobGroup() {
  static const KnobGroup g = groupOf("frame", frameKnobTable());
  return g;
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
    p.set("uLightSoft" + k, i < views.size() && views[i].soft ? 1 : 0);
    p.set("uLightExtent" + k,
          static_cast<float>(l.type == LightType::Directional ? l.sinAngularRadius(1) : std::max(l.extent, 0.0)));
    if (i < views.size()) {
      const auto m = toGl(views[i].viewProj);
      p.setMat4("uLightViewProj" + k, m.data());
      p.set("uShadowBias" + k, static_cast<float>(views[i].shadowBias));
      const auto o = toGl(views[i].objectViewProj);
      p.setMat4("uObjectViewProj" + k, o.data());
      p.set("uObjectShadowBias" + k,
            views[i].objectShadowBias >= 0 ? static_cast<float>(views[i].objectShadowBias) : -1e30f);
      p.set("uObjectNear" + k, static_cast<float>(views[i].objectNear));
    } else {
      p.set("uShadowBias" + k, -1e30f);  // no map: nothing occludes
      p.set("uObjectShadowBias" + k, -1e30f);
    }
  }
}

// ---------------------------------------------------------------------------------------------- resources

FrameResources::FrameResources(const FrameConfig& config, const std::vector<VirtualObject>& objects)
    : config_(config),
      geometry_(objects),
      gbuffer_(config.width, config.height, renderFactor(config.knobs.renderScale), objectTermsFactor(config.knobs)),
      lightPass_(config.knobs.rsmSize, config.knobs.shadowSize) {}

void FrameResources::setRealMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices) {
  geometry_.setRealMesh(std::move(vertices), std::move(indices));
  geometryDirty_ = true;
}

void FrameResources::setViewMesh(std::vector<MeshVertex> vertices, std::vector<uint32_t> indices) {
  geometry_.setViewMesh(std::move(vertices), std::move(indices));
  viewDirty_ = true;
}

void FrameResources::setViewSurface(const cv::Mat& positions, const cv::Mat& normals, int stride,
                                    float maxRelativeJump) {
  geometry_.setViewSurface(positions, normals, stride, maxRelativeJump);
  viewDirty_ = true;
}

void FrameResources::setRealPixelAlbedo(const cv::Mat& albedo, const cv::Mat& clipped) {
  if (gbuffer_.setPixelAlbedo(albedo, clipped)) viewDirty_ = true;
}

void FrameResources::setObjectTransform(size_t i, const cv::Matx44d& T) { geometry_.setObjectTransform(i, T); }

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
  for (const FrameObject& o : geometry_.objects())
    in.objects.insert(in.objects.end(), o.T_world_object.val, o.T_world_object.val + 16);
  for (const SceneLight& l : lights) {
    in.lights.insert(in.lights.end(), {static_cast<double>(l.type), l.spotHalfAngleDeg});
    for (const cv::Vec3d* v : {&l.position, &l.direction, &l.intensity, &l.irradiance})
      in.lights.insert(in.lights.end(), v->val, v->val + 3);
    in.lights.push_back(l.extent);
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

void FrameResources::fitRegionToObjects() {
  region_ = config_.fixedRegion;
  if (region_) return;
  if (const auto b = objectBounds()) region_ = fitRegion(b->first, b->second, config_.knobs.sizeFactor);
}

void FrameResources::renderGBuffer() { gbuffer_.render(geometry_, camera_); }

void FrameResources::renderLight(size_t i) {
  if (!region_) throw std::logic_error("FrameResources::renderLight(): no region (no virtual object placed)");
  if (i == 0) {
    // The brightest lights with extent at the region cast soft shadows (frame knob soft_shadow_lights).
    std::vector<std::pair<double, size_t>> extended;
    for (size_t k = 0; k < lights_.size(); ++k)
      if (lights_[k].extent > 0) extended.push_back({-capture::luminance(irradianceBound(lights_[k], *region_)), k});
    std::sort(extended.begin(), extended.end());
    soft_.assign(lights_.size(), false);
    for (size_t k = 0; k < extended.size() && static_cast<int>(k) < config_.knobs.softShadowLights; ++k)
      soft_[extended[k].second] = true;
  }
  lightPass_.render(i, lights_.size(), lights_.at(i), *region_, geometry_, i < soft_.size() && soft_[i]);
}

const gl::Texture& FrameResources::zero() {
  if (!zero_.id()) {
    zero_ = gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, config_.width, config_.height);
    zero_.setFilter(GL_NEAREST, GL_NEAREST);
    zero_.clear();
  }
  return zero_;
}

cv::Mat FrameResources::downloadGBuffer(int channel, bool reduced) const {
  const GBufferView v = reduced ? gbuffer_.termsView() : gbuffer_.view();
  return download4(channel == 0 ? *v.position : channel == 1 ? *v.normal : *v.albedo);
}

size_t FrameResources::estimateBytes(const FrameConfig& c, size_t lights) {
  const size_t pixels = static_cast<size_t>(c.width) * static_cast<size_t>(c.height);
  const size_t texels = static_cast<size_t>(c.knobs.rsmSize) * static_cast<size_t>(c.knobs.rsmSize);
  const size_t rgba = 16, depth = 4;
  const size_t gbuffer = pixels * (3 * rgba + depth) + pixels * rgba;  // + the zero stand-in
  // The real surface per pixel (positions, normals: RGB32F) and its albedo (RGBA16F) a frame pipeline sets.
  const size_t surface = pixels * (2 * 12 + 8);
  const int factor = objectTermsFactor(c.knobs);  // the reduced copy serves the techniques and the object terms
  const size_t reduced = factor > 1 ? static_cast<size_t>(reducedSize(c.width, factor)) *
                                          static_cast<size_t>(reducedSize(c.height, factor)) * (3 * rgba + depth)
                                    : 0;
  const size_t rsms = 2 * texels * (4 * rgba + depth);
  const size_t objectTexels = static_cast<size_t>(c.knobs.shadowSize) * static_cast<size_t>(c.knobs.shadowSize);
  const size_t shadows = std::max<size_t>(lights, 1) * (2 * texels + objectTexels) * rgba;
  return gbuffer + surface + reduced + rsms + objectTexels * (rgba + depth) + shadows;
}

size_t FrameResources::gpuBytes() const {
  return gbuffer_.gpuBytes() + lightPass_.gpuBytes() + zero_.bytes() + geometry_.viewSurfaceBytes();
}

}  // namespace mrgi::lighting
