#include "lighting/pipeline.h"

#include <algorithm>
#include <stdexcept>

#include "gl/error.h"
#include "lighting/object_shadow.h"
#include "lighting/shadow_footprint.h"
#include "lighting/upsample.h"

namespace mrgi::lighting {

PipelineConfig::PipelineConfig() {
  completeKnobs(knobs);
  technique = parseTechniqueChoice(defaultTechniqueName(), &knobs);
}

PipelineConfig& PipelineConfig::set(const std::string& group, const std::string& knob, double value) {
  const KnobGroup* g = findKnobGroup(group);
  const KnobInfo* k = g ? g->find(knob) : nullptr;
  if (!k) throw std::invalid_argument("unknown knob '" + group + "." + knob + "'");
  g->check(*k, value, group + "." + knob, [](const std::string& key, const std::string& problem) {
    throw std::invalid_argument(key + ": " + problem);
  });
  knobs[group][knob] = value;
  return *this;
}

static FrameConfig frameConfigOf(const PipelineConfig& config) {
  FrameConfig fc;
  fc.width = config.width;
  fc.height = config.height;
  fc.knobs = knobsFrom(frameKnobTable(), config.knobs.at(frameKnobGroup().key));
  fc.fixedRegion = config.fixedRegion;
  return fc;
}

PipelineConfig pipelineConfig(const SceneDescription& scene, int width, int height) {
  PipelineConfig pc;
  pc.width = width;
  pc.height = height;
  pc.technique = scene.technique;
  pc.knobs = scene.knobs;
  completeKnobs(pc.knobs);
  return pc;
}

size_t estimateGpuBytes(const PipelineConfig& config, size_t lights) {
  PipelineConfig c = config;
  completeKnobs(c.knobs);
  const FrameConfig fc = frameConfigOf(c);
  // The shade and irradiance targets, and the object terms' at their reduced resolution.
  size_t sum = FrameResources::estimateBytes(fc, lights) + 2 * 16 * static_cast<size_t>(c.width) * c.height;
  const int termsFactor = objectTermsFactor(fc.knobs);
  const bool history = fc.knobs.objectTermsHistory > 0;  // two sets of terms, points and normals
  if (termsFactor > 1 || history)
    sum += (history ? 6 : 1) * 16 * static_cast<size_t>(reducedSize(c.width, termsFactor)) *
           reducedSize(c.height, termsFactor);
  for (const RoleAssignment& a : assignRoles(c.technique))
    if (a.info->estimateBytes)
      sum += a.info->estimateBytes(c.knobs.at(a.info->knobs.key), c.knobs.at("frame"), a.real, a.virtualObject, c.width,
                                   c.height, lights);
  return sum;
}

namespace {

/// The objects as spheres for the shading pass's shadow of the ambient (lighting/object_shadow.glsl).
void setOccluderUniforms(const gl::Program& p, const FrameResources& frame) {
  constexpr size_t kMaxOccluders = 16;  // MAX_OCCLUDERS
  size_t n = 0;
  for (const auto& o : frame.objects()) {
    if (n == kMaxOccluders) break;
    const OccluderSphere s = placeSphere(o.sphere, o.T_world_object);
    p.set("uOccluderAlbedo[" + std::to_string(n) + "]", s.albedo[0], s.albedo[1], s.albedo[2]);
    p.set("uOccluders[" + std::to_string(n++) + "]", s.centre[0], s.centre[1], s.centre[2], s.radius);
  }
  p.set("uOccluderCount", static_cast<int>(n));
}
/// What the object terms depend on besides the camera (the objects' spheres, the lights kept, the ambients, the
/// soft-shadow variant), value by value: their history carries over only while this stays the same.
std::vector<double> objectTermsInputs(const FrameResources& frame, const std::vector<SceneLight>& kept,
                                      const std::optional<Ambient>& hiddenAmbient, unsigned hiddenSerial, bool soft) {
  std::vector<double> inputs;
  for (const auto& o : frame.objects()) {
    const OccluderSphere s = placeSphere(o.sphere, o.T_world_object);
    inputs.insert(inputs.end(),
                  {s.centre[0], s.centre[1], s.centre[2], s.radius, s.albedo[0], s.albedo[1], s.albedo[2]});
  }
  for (const SceneLight& l : kept) {
    inputs.insert(inputs.end(), {static_cast<double>(l.type), l.extent, l.spotHalfAngleDeg});
    for (const cv::Vec3d& v : {l.position, l.direction, l.intensity, l.irradiance})
      inputs.insert(inputs.end(), {v[0], v[1], v[2]});
  }
  const Ambient hidden = hiddenAmbient.value_or(Ambient{});
  for (const cv::Vec3f& v : hidden.sh) inputs.insert(inputs.end(), {v[0], v[1], v[2]});
  for (const cv::Vec3d& v : frame.ambientSh()) inputs.insert(inputs.end(), {v[0], v[1], v[2]});
  const cv::Vec3d a = frame.ambient();
  inputs.insert(inputs.end(), {a[0], a[1], a[2], hidden.uniform[0], hidden.uniform[1], hidden.uniform[2],
                               hiddenAmbient ? 1.0 : 0.0, static_cast<double>(hiddenSerial), soft ? 1.0 : 0.0});
  return inputs;
}

/// The inputs a consumer depends on changed between two version snapshots.
bool changed(const std::optional<FrameVersions>& at, const FrameVersions& now, unsigned inputs) {
  if (!at) return true;
  return ((inputs & kInputCamera) && at->camera != now.camera) ||
         ((inputs & kInputGeometry) && at->geometry != now.geometry) ||
         ((inputs & kInputLights) && at->lights != now.lights) ||
         ((inputs & kInputAmbient) && at->ambient != now.ambient) || ((inputs & kInputOwn) && at->own != now.own);
}
constexpr unsigned kAllInputs = kInputCamera | kInputGeometry | kInputLights | kInputAmbient | kInputOwn;
}  // namespace

LightingPipeline::LightingPipeline(const PipelineConfig& config, const std::vector<VirtualObject>& objects)
    : config_(config),
      shade_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height),
      irradiance_(GL_TEXTURE_2D, GL_RGBA32F, config.width, config.height) {
  completeKnobs(config_.knobs);
  frame_ = std::make_unique<FrameResources>(frameConfigOf(config_), objects);
  for (auto* t : {&shade_, &irradiance_}) t->setFilter(GL_NEAREST, GL_NEAREST);
  shadeFb_.attachColour(0, shade_);
  shadeFb_.attachColour(1, irradiance_);
  shadeFb_.finalise(2);
  for (const RoleAssignment& a : assignRoles(config_.technique)) {
    TechniqueSetup s;
    s.knobs = config_.knobs.at(a.info->knobs.key);
    s.real = a.real;
    s.virtualObject = a.virtualObject;
    s.frame = frame_.get();
    s.progress = config_.progress;
    s.cacheDir = config_.cacheDir;
    techniques_.push_back(a.info->create(s));
    if (a.real) real_ = techniques_.back().get();
    if (a.virtualObject) virtual_ = techniques_.back().get();
  }
  techniqueAt_.resize(techniques_.size());
}

bool LightingPipeline::idle(const Technique& t) const { return environment_ && &t == virtual_ && &t != real_; }

std::vector<std::pair<std::string, std::unique_ptr<TechniqueInputBuilder>>> LightingPipeline::inputBuilders() const {
  std::vector<std::pair<std::string, std::unique_ptr<TechniqueInputBuilder>>> out;
  for (const auto& t : techniques_)
    if (!idle(*t))
      if (auto b = t->inputBuilder()) out.emplace_back(t->name(), std::move(b));
  return out;
}

void LightingPipeline::invalidate() {
  frame_->invalidate();
  termsCamera_.reset();
  gbufferAt_.reset();
  lightsAt_.reset();
  shadeAt_.reset();
  for (auto& at : techniqueAt_) at.reset();
}

Technique* LightingPipeline::techniqueFor(Role role) const { return role == Role::Real ? real_ : virtual_; }

Technique* LightingPipeline::technique(const std::string& name) const {
  for (const auto& t : techniques_)
    if (t->name() == name) return t.get();
  return nullptr;
}

nlohmann::json LightingPipeline::stats() const {
  nlohmann::json out = nlohmann::json::object();
  for (const auto& t : techniques_) {
    if (std::find(skipped_.begin(), skipped_.end(), t->name()) != skipped_.end()) continue;  // did not run
    nlohmann::json s = t->stats();
    if (!s.empty()) out[t->name()] = std::move(s);
  }
  return out;
}

void LightingPipeline::run(const CameraView& camera, const std::vector<SceneLight>& lights,
                           const cv::Vec3d& ambientRadiance, gl::Profiler* profiler) {
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  // Only the lights that matter at the objects' region are rendered (frame knob light_cutoff); the others
  // change the objects' effect on the scene by at most that share, and light real pixels equally with and
  // without the objects.
  frame_->fitRegionToObjects();
  const std::optional<Region>& region = frame_->region();
  lightsKept_ = lightsThatMatter(lights, ambientRadiance, region.value_or(Region{}),
                                 region ? frame_->config().knobs.lightCutoff : 0.0);
  std::vector<SceneLight> kept;
  for (size_t i : lightsKept_) kept.push_back(lights[i]);
  const FrameVersions now = frame_->update(camera, kept, ambientRadiance);
  const bool needGbuffer = changed(gbufferAt_, now, kInputCamera | kInputGeometry);
  unsigned lightInputs = kInputGeometry | kInputLights;
  for (const auto& t : techniques_) lightInputs |= t->lightInputs();
  const bool needLights = changed(lightsAt_, now, lightInputs);
  skipped_.clear();
  if (!needGbuffer) skipped_.push_back("gbuffer");
  if (!needLights) skipped_.push_back("rsm");
  std::vector<bool> needTechnique(techniques_.size());
  for (size_t i = 0; i < techniques_.size(); ++i) {
    needTechnique[i] =
        (needLights || changed(techniqueAt_[i], now, techniques_[i]->inputs())) && !idle(*techniques_[i]);
    if (!needTechnique[i]) skipped_.push_back(techniques_[i]->name());
  }
  if (!changed(shadeAt_, now, kAllInputs)) {
    skipped_.push_back("shade");
    return;
  }

  const bool lit = frame_->region().has_value();
  if (needGbuffer) {
    auto s = timed(profiler, "gbuffer");
    frame_->renderGBuffer();
    gbufferAt_ = now;
  }
  // The lights whose objects' shadow this pass draws (bit i: kept[i]): those the real-role technique leaves to it.
  int passShadows = 0;
  std::vector<SceneLight> passShadowLights;
  for (size_t li = 0; li < kept.size(); ++li)
    if (!(real_ && real_->accountsForDirectShadow(kept[li]))) {
      passShadows |= 1 << li;
      passShadowLights.push_back(kept[li]);
    }
  if (needLights) {
    frame_->clearLightViews();
    if (lit) {
      for (auto& t : techniques_) t->beginLights(*frame_, profiler);
      for (size_t li = 0; li < kept.size(); ++li) {
        {
          auto s = timed(profiler, "rsm");
          frame_->renderLight(li);
        }
        for (auto& t : techniques_) t->light(*frame_, li, profiler);
      }
      glMemoryBarrier(GL_ALL_BARRIER_BITS);
      for (auto& t : techniques_) t->endLights(*frame_, profiler);
    }
    lightsAt_ = now;
  }
  for (size_t i = 0; i < techniques_.size(); ++i) {
    if (!needTechnique[i]) continue;
    if (lit) techniques_[i]->update(*frame_, profiler);
    techniqueAt_[i] = now;
  }

  auto s = timed(profiler, "shade");
  glDisable(GL_DEPTH_TEST);
  // The soft-shadow variant only when a light casts one, the upsampling one only when a technique's output is
  // reduced (render_scale): their code costs llvmpipe even where no pixel takes it.
  bool soft = false;
  for (const LightView& v : frame_->lightViews()) soft = soft || v.soft;
  const TechniqueOutputs realOut = real_ ? real_->outputs() : TechniqueOutputs{};
  const TechniqueOutputs virtualOut = virtual_ ? virtual_->outputs() : TechniqueOutputs{};
  const GBufferView reduced = frame_->techniqueView();
  const GBufferView termsView = frame_->objectTermsView();
  const auto factorOf = [&](const gl::Texture* t) {
    if (!t || t->width() == config_.width) return 1;
    if (t->width() != reduced.width || t->height() != reduced.height)
      throw std::logic_error(
          "LightingPipeline::run(): a technique output is neither the frame's size nor its reduced view's");
    return reduced.factor;
  };
  const std::array<int, 3> factors{factorOf(realOut.realDelta), factorOf(virtualOut.virtualIrradiance),
                                   factorOf(virtualOut.virtualRadiance)};
  // The objects' terms beyond their direct shadow (lighting/object_terms.glsl) at the reduced view's resolution
  // when the frame knob render_scale reduces it, else at object_terms_scale: smooth over a surface, upsampled by
  // the pass.
  const double historyWeight = frame_->config().knobs.objectTermsHistory;
  const bool history = lit && historyWeight > 0;
  const bool reducedTerms = lit && (termsView.factor > 1 || history);
  const bool upsample = reducedTerms || *std::max_element(factors.begin(), factors.end()) > 1;
  const auto setObjectTermUniforms = [&](const gl::Program& q) {
    q.set("uAddReflectedLight", real_ && real_->accountsForReflectedLight() ? 0 : 1);
    setOccluderUniforms(q, *frame_);
    Ambient hidden;
    if (hiddenAmbient_) {
      hidden = *hiddenAmbient_;
    } else {
      hidden.uniform = cv::Vec3f(frame_->ambient());
      for (size_t k = 0; k < 9; ++k) hidden.sh[k] = cv::Vec3f(frame_->ambientSh()[k]);
      hidden.map = ambientMap_;
    }
    // The map on the GPU as the C++ twin reads it: its own levels, linear within and between them, the azimuth
    // repeating (lighting/radiance_map.h).
    if (hidden.map && hidden.map != hiddenMapSource_) {
      const auto& levels = hidden.map->levels();
      hiddenMap_ = gl::Texture(GL_TEXTURE_2D, GL_RGB32F, hidden.map->width(), hidden.map->height(), 1,
                               static_cast<int>(levels.size()));
      for (size_t l = 0; l < levels.size(); ++l) {
        const cv::Mat level = levels[l].isContinuous() ? levels[l] : levels[l].clone();
        hiddenMap_.uploadLevel(static_cast<int>(l), GL_RGB, GL_FLOAT, level.ptr<float>());
      }
      hiddenMap_.setFilter(GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR);
      hiddenMap_.setWrap(GL_REPEAT, GL_CLAMP_TO_EDGE);
      hiddenMapSource_ = hidden.map;
    }
    q.set("uHiddenMapOn", hidden.map ? 1 : 0);
    if (hidden.map) hiddenMap_.bind(11);
    q.set("uHiddenUniform", hidden.uniform[0], hidden.uniform[1], hidden.uniform[2]);
    for (size_t k = 0; k < 9; ++k)
      q.set("uHiddenSh[" + std::to_string(k) + "]", hidden.sh[k][0], hidden.sh[k][1], hidden.sh[k][2]);
    setLightUniforms(q, kept, frame_->lightViews());
  };
  if (reducedTerms) {
    // With the history the two sets of targets alternate: this run writes the one the last run did not.
    const int current = history ? 1 - termsCurrent_ : 0;
    const auto allocate = [&](int i) {
      const auto make = [&](gl::Texture& t) {
        t = gl::Texture(GL_TEXTURE_2D, GL_RGBA32F, termsView.width, termsView.height);
        t.setFilter(GL_NEAREST, GL_NEAREST);
      };
      const bool targets = history ? termsNormal_[i].id() != 0 : termsNormal_[i].id() == 0;
      if (objectTerms_[i].width() == termsView.width && objectTerms_[i].height() == termsView.height && targets)
        return false;
      objectTermsFb_[i] = gl::Framebuffer();
      make(objectTerms_[i]);
      objectTermsFb_[i].attachColour(0, objectTerms_[i]);
      termsPosition_[i] = gl::Texture();
      termsNormal_[i] = gl::Texture();
      if (history) {
        make(termsPosition_[i]);
        make(termsNormal_[i]);
        objectTermsFb_[i].attachColour(1, termsPosition_[i]);
        objectTermsFb_[i].attachColour(2, termsNormal_[i]);
      }
      objectTermsFb_[i].finalise(history ? 3 : 1);
      return true;
    };
    bool fresh = allocate(current);
    std::vector<double> inputs;
    if (history) {
      inputs = objectTermsInputs(*frame_, kept, hiddenAmbient_, hiddenSerial_, soft);
      fresh = allocate(1 - current) || fresh;
    }
    const bool carry =
        history && !fresh && termsCamera_ && termsCamera_->factor == termsView.factor && inputs == termsInputs_;
    gl::Program& t = objectTermsPrograms_[(soft ? 1 : 0) | (history ? 2 : 0)];
    if (!t.id()) {
      std::vector<std::pair<std::string, std::string>> defines;
      if (soft) defines.push_back({"SOFT_OBJECT_SHADOWS", "1"});
      if (history) defines.push_back({"TERMS_HISTORY", "1"});
      t = gl::Program::graphics("lighting/gl/fullscreen.vert", "lighting/object_terms.frag", defines);
    }
    objectTermsFb_[current].bind();
    glViewport(0, 0, termsView.width, termsView.height);
    t.use();
    setObjectTermUniforms(t);
    termsView.bind();
    frame_->bindShadowMaps();
    if (history) {
      t.set("uHistory", carry ? 1 : 0);
      t.set("uHistoryWeight", static_cast<float>(historyWeight));
      if (carry) {
        const HistoryCamera& before = *termsCamera_;
        const cv::Matx44f columns = before.cameraFromWorld.t();  // column-major
        t.setMat4("uPreviousCameraFromWorld", columns.val);
        t.set("uPreviousIntrinsics", before.fx, before.fy, before.cx, before.cy);
        t.set("uPreviousFactor", before.factor);
        setVec3(t, "uEye", capture::translationOf(camera.T_world_camera));
        objectTerms_[1 - current].bind(3);
        termsPosition_[1 - current].bind(4);
        termsNormal_[1 - current].bind(5);
      }
    }
    emptyVao_.bind();
    glDrawArrays(GL_TRIANGLES, 0, 3);
    termsCurrent_ = current;
    if (history) {
      termsCamera_ = historyCamera(camera, termsView.factor);
      termsInputs_ = std::move(inputs);
    } else {
      termsCamera_.reset();
    }
  } else {
    termsCamera_.reset();
  }
  shadeFb_.bind();
  glViewport(0, 0, config_.width, config_.height);
  // The whole program only where the objects lie or their direct shadow may fall (objectsFootprint); the rest
  // of the image takes the variant without them, which gives the same values there for less of llvmpipe's time.
  const cv::Rect image(0, 0, config_.width, config_.height);
  footprint_ = image;
  const auto bounds = frame_->objectBounds();
  if (lit && boundedShading_ && bounds) {
    const cv::Vec3d centre = 0.5 * (bounds->first + bounds->second);
    const double radius = 0.5 * cv::norm(bounds->second - bounds->first);
    // The shadow maps' texels blur the shadow's edge: two of the region's map, and the tests' offsets.
    double bias = 0;
    for (const LightView& v : frame_->lightViews()) bias = std::max({bias, v.shadowBias, v.objectShadowBias});
    const double margin = 4.0 * frame_->region()->radius() / std::max(1, frame_->rsmSize()) + 2.0 * bias;
    footprint_ = objectsFootprint(frame_->camera(), centre, radius, passShadowLights, margin, frame_->cameraVertices(),
                                  frame_->cameraIndices());
  }
  // The real-role delta at the object terms' own reduced view: one set of upsampling weights for both.
  const bool sharedUpsample = reducedTerms && realOut.realDelta && factors[0] > 1 && factors[0] == termsView.factor &&
                              realOut.realDelta->width() == termsView.width &&
                              realOut.realDelta->height() == termsView.height;
  const auto shadeWith = [&](bool realOnly) {
    gl::Program& p = shadePrograms_[(soft ? 1 : 0) | (upsample ? 2 : 0) | (reducedTerms ? 4 : 0) | (realOnly ? 8 : 0) |
                                    (sharedUpsample ? 16 : 0)];
    if (!p.id()) {
      std::vector<std::pair<std::string, std::string>> defines;
      if (soft) defines.push_back({"SOFT_OBJECT_SHADOWS", "1"});
      if (upsample) defines.push_back({"UPSAMPLE_OUTPUTS", "1"});
      if (reducedTerms) defines.push_back({"REDUCED_OBJECT_TERMS", "1"});
      if (realOnly) defines.push_back({"SHADE_REAL_ONLY", "1"});
      if (sharedUpsample) defines.push_back({"SHARED_UPSAMPLE", "1"});
      p = gl::Program::graphics("lighting/gl/fullscreen.vert", "lighting/shade.frag", defines);
    }
    p.use();
    p.set("uRealDeltaOn", realOut.realDelta ? 1 : 0);
    p.set("uPassShadows", passShadows);
    p.set("uAllLights", static_cast<int>((1u << kept.size()) - 1u));
    setObjectTermUniforms(p);
    setAmbientUniforms(p, *frame_);  // this run's ambient (frame_->update) and the SH part (setAmbientSh)
    p.set("uEnvironmentHoldsBounce", environment_ ? 1 : 0);
    p.set("uCameraWhite", static_cast<float>(cameraWhite_));
    frame_->gbufferView().bind();
    auto orZero = [&](const gl::Texture* t) -> const gl::Texture& { return t ? *t : frame_->zero(); };
    orZero(realOut.realDelta).bind(3);
    orZero(virtualOut.virtualIrradiance).bind(4);
    orZero(virtualOut.virtualRadiance).bind(5);
    if (upsample) {  // outputs at the reduced view's size are upsampled by the pass
      p.set("uRealDeltaFactor", factors[0]);
      p.set("uVirtualIrradianceFactor", factors[1]);
      p.set("uVirtualRadianceFactor", factors[2]);
      termsView.position->bind(6);  // the techniques' reduced view when render_scale reduces it
      termsView.normal->bind(7);
    }
    if (reducedTerms) {
      p.set("uObjectTermsFactor", termsView.factor);
      objectTerms_[termsCurrent_].bind(8);
    }
    frame_->bindShadowMaps();
    emptyVao_.bind();
    glDrawArrays(GL_TRIANGLES, 0, 3);
  };
  if (!lit) {
    // No virtual object: nothing to shade, only which pixels saw a surface (SHADE_UNLIT).
    if (!unlitProgram_.id())
      unlitProgram_ =
          gl::Program::graphics("lighting/gl/fullscreen.vert", "lighting/shade.frag", {{"SHADE_UNLIT", "1"}});
    unlitProgram_.use();
    frame_->gbufferView().bind();
    emptyVao_.bind();
    glDrawArrays(GL_TRIANGLES, 0, 3);
  } else if (footprint_ == image) {
    shadeWith(false);
  } else {
    // Each pixel drawn once: the variant over the bands around the footprint, the whole program over it.
    glEnable(GL_SCISSOR_TEST);
    for (const cv::Rect& band : bandsAround(image, footprint_)) {
      glScissor(band.x, band.y, band.width, band.height);  // framebuffer rows = image rows
      shadeWith(true);
    }
    if (!footprint_.empty()) {
      glScissor(footprint_.x, footprint_.y, footprint_.width, footprint_.height);
      shadeWith(false);
    }
    glDisable(GL_SCISSOR_TEST);
  }
  shadeAt_ = now;
  gl::checkGlError("LightingPipeline::run()");
}

cv::Mat LightingPipeline::downloadShade() const { return download4(shade_); }
cv::Mat LightingPipeline::downloadIrradiance() const { return download4(irradiance_); }

cv::Mat LightingPipeline::downloadObjectTerms(int channel) const {
  const size_t i = static_cast<size_t>(termsCurrent_);
  const gl::Texture& t = channel == 0 ? objectTerms_[i] : channel == 1 ? termsPosition_[i] : termsNormal_[i];
  return t.id() ? download4(t) : cv::Mat();
}

size_t LightingPipeline::gpuBytes() const {
  size_t sum = frame_->gpuBytes() + shade_.bytes() + irradiance_.bytes();
  for (size_t i = 0; i < 2; ++i) sum += objectTerms_[i].bytes() + termsPosition_[i].bytes() + termsNormal_[i].bytes();
  for (const auto& t : techniques_) sum += t->gpuBytes();
  return sum;
}

}  // namespace mrgi::lighting
