#include "lighting/techniques/dlpv/dlpv.h"

#include <algorithm>

#include "capture/colour.h"
#include "gl/error.h"
#include "lighting/debug_views.h"
#include "lighting/techniques/registry.h"

namespace mrgi::lighting {

const std::vector<KnobBinding<DlpvKnobs>>& dlpvKnobTable() {
  static const std::vector<KnobBinding<DlpvKnobs>> table = {
      {{"resolution", KnobType::Int, 4, 128, 32, "volume cells per axis", {8, 16, 48}, {8}, true},
       &DlpvKnobs::resolution},
      {{"steps", KnobType::Int, 0, 256, 16, "propagation steps", {4, 8, 32}, {4}, false}, &DlpvKnobs::steps},
      {{"damping",
        KnobType::Real,
        0.0,
        1.0,
        1.0,
        "directional damping of lateral and backward propagation (0 = off)",
        {0.0, 0.5},
        {},
        false},
       &DlpvKnobs::damping},
      {{"direct_steps",
        KnobType::Int,
        0,
        256,
        2,
        "propagation steps of the direct (shadow) delta, at most steps: more = softer shadows, darker centre",
        {},
        {},
        false},
       &DlpvKnobs::directSteps},
      {{"naive_difference",
        KnobType::Bool,
        0,
        1,
        0,
        "real pixels from two full volumes V^rho - V^mu instead of delta injection (the lpv-diff baseline)",
        {},
        {},
        false},
       &DlpvKnobs::naiveDifference},
  };
  return table;
}

TechniqueInfo dlpvTechniqueInfo() {
  TechniqueInfo t;
  t.name = "dlpv";
  t.description =
      "Delta Light Propagation Volumes: the object's shadow and bounce on real pixels, V^rho bounce on the object";
  t.real = true;
  t.virtualObject = true;
  t.stagePrefixes = {"lpv."};
  t.knobs = groupOf("lpv", dlpvKnobTable());
  t.aliases = {{"lpv-diff", {{"naive_difference", 1.0}}, "DLPV with the naive two-volume difference on real pixels"}};
  t.create = [](const TechniqueSetup& s) { return std::make_unique<DlpvTechnique>(s); };
  t.estimateBytes = [](const KnobValues& k, const KnobValues&, bool real, bool virtualObject, int w, int h, size_t) {
    const DlpvKnobs knobs = knobsFrom(dlpvKnobTable(), k);
    const size_t r = static_cast<size_t>(knobs.resolution);
    const size_t volumes = 2 + (virtualObject ? 1 : 0) + (real ? (knobs.naiveDifference ? 4 : 2) : 0);
    return volumes * 3 * r * r * r * 16 + 2 * 16 * static_cast<size_t>(w) * static_cast<size_t>(h);
  };
  return t;
}

DlpvTechnique::DlpvTechnique(const TechniqueSetup& setup)
    : knobs_(knobsFrom(dlpvKnobTable(), setup.knobs)),
      real_(setup.real),
      virtual_(setup.virtualObject),
      injectProgram_(gl::Program::graphics("lighting/techniques/dlpv/lpv_inject.vert",
                                           "lighting/techniques/dlpv/lpv_inject.geom",
                                           "lighting/techniques/dlpv/lpv_inject.frag")),
      propagateProgram_(gl::Program::compute("lighting/techniques/dlpv/lpv_propagate.comp")),
      addProgram_(gl::Program::compute("lighting/techniques/dlpv/lpv_add.comp")),
      readoutProgram_(
          gl::Program::graphics("lighting/gl/fullscreen.vert", "lighting/techniques/dlpv/dlpv_readout.frag")),
      out_(setup.frame->techniqueView().width, setup.frame->techniqueView().height) {}

DlpvTechnique::Volume DlpvTechnique::makeVolume(int res) const {
  Volume v{gl::Texture(GL_TEXTURE_3D, GL_RGBA32F, res, res, res), gl::Texture(GL_TEXTURE_3D, GL_RGBA32F, res, res, res),
           gl::Texture(GL_TEXTURE_3D, GL_RGBA32F, res, res, res), gl::Framebuffer()};
  v.fb.attachColour(0, v.r);
  v.fb.attachColour(1, v.g);
  v.fb.attachColour(2, v.b);
  v.fb.finalise(3);
  return v;
}

void DlpvTechnique::beginLights(const FrameResources& frame, gl::Profiler*) {
  grid_ = gridIn(*frame.region(), knobs_.resolution);
  if (grid_->resolution != volumeRes_) {
    volumeRes_ = grid_->resolution;
    scratchA_ = makeVolume(volumeRes_);
    scratchB_ = makeVolume(volumeRes_);
    if (virtual_) rho_ = makeVolume(volumeRes_);
    if (real_ && !knobs_.naiveDifference) {
      delta_ = makeVolume(volumeRes_);
      deltaDirect_ = makeVolume(volumeRes_);
    }
    if (real_ && knobs_.naiveDifference) {
      rhoFull_ = makeVolume(volumeRes_);
      muFull_ = makeVolume(volumeRes_);
      rhoDirect_ = makeVolume(volumeRes_);
      muDirect_ = makeVolume(volumeRes_);
    }
  }
  // Every run with new lights or geometry starts from cleared volumes.
  for (Volume* v : {&delta_, &rho_, &rhoFull_, &muFull_, &deltaDirect_, &rhoDirect_, &muDirect_})
    if (v->r.id()) {
      v->r.clear();
      v->g.clear();
      v->b.clear();
    }
}

void DlpvTechnique::inject(Volume& target, const Rsm& source, const Rsm* other, float sign, unsigned mode,
                           const SceneLight& light, int rsmSize) {
  const LpvGrid& g = *grid_;
  const gl::Program& p = injectProgram_;
  target.fb.bind();
  glViewport(0, 0, g.resolution, g.resolution);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE);
  glBlendEquation(GL_FUNC_ADD);
  p.use();
  p.set("uSize", rsmSize);
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
  glDrawArraysInstanced(GL_POINTS, 0, rsmSize * rsmSize, 2);
  glDisable(GL_BLEND);
}

void DlpvTechnique::light(const FrameResources& frame, size_t index, gl::Profiler* profiler) {
  auto s = timed(profiler, "lpv.inject");
  const SceneLight& light = frame.lights().at(index);
  const int n = frame.rsmSize();
  const Rsm& rho = frame.rsmRho();
  const Rsm& mu = frame.rsmMu();
  if (virtual_) inject(rho_, rho, nullptr, 1.0f, kInjectIndirect, light, n);
  if (!real_) return;
  // A sharp distant light's direct shadow is the shading pass's (accountsForDirectShadow): only its bounce here.
  const bool direct = accountsForDirectShadow(light);
  if (knobs_.naiveDifference) {
    inject(rhoFull_, rho, nullptr, 1.0f, kInjectIndirect, light, n);
    if (direct) inject(rhoDirect_, rho, nullptr, 1.0f, kInjectDirect, light, n);
    inject(muFull_, mu, nullptr, 1.0f, kInjectIndirect, light, n);
    if (direct) inject(muDirect_, mu, nullptr, 1.0f, kInjectDirect, light, n);
  } else {
    // Delta injection, only where RSM^rho and RSM^mu differ: +VPLs of RSM^rho, -VPLs of RSM^mu, and the
    // direct light RSM^mu received there, negative (the virtual object now intercepts it; its own direct
    // light is shaded by the shading pass and must not travel on through the object).
    inject(delta_, rho, &mu, 1.0f, kInjectIndirect, light, n);
    inject(delta_, mu, &rho, -1.0f, kInjectIndirect, light, n);
    if (direct) inject(deltaDirect_, mu, &rho, -1.0f, kInjectDirect, light, n);
  }
}

bool DlpvTechnique::sharpDistant(const SceneLight& light) {
  return light.type == LightType::Directional && light.extent <= kSharpAngularRadius;
}

void DlpvTechnique::add(const Volume& src, Volume& dst) {
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

void DlpvTechnique::propagate(Volume& v, bool clampNegative, const Volume* late) {
  const int res = grid_->resolution;
  const int steps = knobs_.steps;
  const int lateAt = std::max(0, steps - knobs_.directSteps);
  if (steps == 0) {
    if (late) add(*late, v);
    return;
  }
  for (auto [src, dst] : {std::pair{&v.r, &scratchA_.r}, {&v.g, &scratchA_.g}, {&v.b, &scratchA_.b}})
    glCopyImageSubData(src->id(), GL_TEXTURE_3D, 0, 0, 0, 0, dst->id(), GL_TEXTURE_3D, 0, 0, 0, 0, res, res, res);
  const gl::Program& p = propagateProgram_;
  p.use();
  p.set("uResolution", res);
  p.set("uDamping", static_cast<float>(knobs_.damping));
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

void DlpvTechnique::endLights(const FrameResources&, gl::Profiler* profiler) {
  auto s = timed(profiler, "lpv.propagate");
  if (virtual_) propagate(rho_, true, nullptr);
  if (!real_) return;
  if (knobs_.naiveDifference) {
    propagate(rhoFull_, true, &rhoDirect_);
    propagate(muFull_, true, &muDirect_);
  } else {
    propagate(delta_, false, &deltaDirect_);
  }
}

void DlpvTechnique::update(const FrameResources& frame, gl::Profiler* profiler) {
  if (!grid_) return;  // no light stage ran yet
  auto s = timed(profiler, "lpv.readout");
  out_.fb.bind();
  glViewport(0, 0, frame.techniqueView().width, frame.techniqueView().height);
  glDisable(GL_DEPTH_TEST);
  const gl::Program& p = readoutProgram_;
  p.use();
  setVec3(p, "uGridOrigin", grid_->origin);
  p.set("uCellSize", static_cast<float>(grid_->cellSize));
  p.set("uResolution", grid_->resolution);
  p.set("uReal", real_ ? 1 : 0);
  p.set("uVirtual", virtual_ ? 1 : 0);
  p.set("uDifference", knobs_.naiveDifference ? 1 : 0);
  frame.techniqueView().bind();
  const Volume& d = knobs_.naiveDifference ? rhoFull_ : delta_;
  const Volume& mu = knobs_.naiveDifference ? muFull_ : delta_;
  d.r.bind(3), d.g.bind(4), d.b.bind(5);
  mu.r.bind(6), mu.g.bind(7), mu.b.bind(8);
  rho_.r.bind(9), rho_.g.bind(10), rho_.b.bind(11);
  emptyVao_.bind();
  glDrawArrays(GL_TRIANGLES, 0, 3);
  gl::checkGlError("DlpvTechnique::update()");
}

TechniqueOutputs DlpvTechnique::outputs() const { return out_.outputs(real_, virtual_); }

const DlpvTechnique::Volume* DlpvTechnique::volume(const std::string& name) const {
  if (name == "delta") return &delta_;
  if (name == "rho") return &rho_;
  if (name == "rho_full") return &rhoFull_;
  if (name == "mu_full") return &muFull_;
  if (name == "delta_direct") return &deltaDirect_;
  if (name == "rho_direct") return &rhoDirect_;
  if (name == "mu_direct") return &muDirect_;
  throw std::invalid_argument("unknown volume '" + name + "'");
}

LpvVolumeCpu DlpvTechnique::downloadVolume(const std::string& name) const {
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

namespace {
/// The volume's band-0 luminance as a row of slices along z (every `every`-th slice), signed colours, each
/// cell `cellPixels` wide.
cv::Mat volumeSlices(const LpvVolumeCpu& volume, int every, int cellPixels, double& scale) {
  const int res = volume.resolution;
  const int slices = (res + every - 1) / every;
  std::vector<double> mags;
  for (const auto& c : volume.cells) {
    const double l = capture::luminance(cv::Vec3d(c[0][0], c[1][0], c[2][0]));
    if (l != 0) mags.push_back(std::abs(l));
  }
  if (scale <= 0) scale = percentile99(mags);
  const int gap = 2;
  cv::Mat out(res * cellPixels, slices * (res * cellPixels + gap), CV_8UC3, cv::Scalar(40, 40, 80));
  for (int s = 0; s < slices; ++s) {
    const int k = s * every;
    for (int j = 0; j < res; ++j)
      for (int i = 0; i < res; ++i) {
        const auto& c = volume.at(i, j, k);
        const double l = capture::luminance(cv::Vec3d(c[0][0], c[1][0], c[2][0]));
        const cv::Rect r(s * (res * cellPixels + gap) + i * cellPixels, (res - 1 - j) * cellPixels, cellPixels,
                         cellPixels);
        const cv::Vec3b colour = signedColour(l, scale);
        out(r).setTo(cv::Scalar(colour[0], colour[1], colour[2]));
      }
  }
  return out;
}
}  // namespace

cv::Mat DlpvTechnique::debugImage(const std::string& view, const DebugContext&, nlohmann::json& info) const {
  if (view != "dlpv_slices" || !grid_) return {};
  double scale = 0;
  const auto vol = downloadVolume(!real_ ? "rho" : knobs_.naiveDifference ? "rho_full" : "delta");
  if (vol.resolution == 0) return {};
  cv::Mat img = volumeSlices(vol, 4, 4, scale);
  info["debug_volume_scale"] = scale;
  return img;
}

size_t DlpvTechnique::gpuBytes() const {
  size_t sum = out_.bytes();
  for (const Volume* v :
       {&delta_, &rho_, &rhoFull_, &muFull_, &scratchA_, &scratchB_, &deltaDirect_, &rhoDirect_, &muDirect_})
    sum += v->r.bytes() + v->g.bytes() + v->b.bytes();
  return sum;
}

}  // namespace mrgi::lighting
