#include "lighting/techniques/splatting/splatting.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "capture/colour.h"
#include "gl/error.h"
#include "lighting/techniques/registry.h"

namespace mrgi::lighting {

const std::vector<KnobBinding<SplattingKnobs>>& splattingKnobTable() {
  static const std::vector<KnobBinding<SplattingKnobs>> table = {
      {{"vpls",
        KnobType::Int,
        1,
        16384,
        1024,
        "pixel lights sampled per run, over all lights",
        {256, 4096},
        {256},
        true},
       &SplattingKnobs::vpls},
      {{"i_low",
        KnobType::Real,
        1e-4,
        1e4,
        16.0,
        "a splat ends where its light gives less than this x lum|Phi| / (pi s^2) (s: the region's side); a diffuse "
        "splat reaches s / sqrt(i_low)",
        {4.0, 64.0},
        {64.0},
        true},
       &SplattingKnobs::iLow},
      {{"widen",
        KnobType::Real,
        0.0,
        1.0,
        0.02,
        "metres: a glossy lobe widens within this distance of its light",
        {0.0, 0.05},
        {},
        false},
       &SplattingKnobs::widen},
      {{"far_levels",
        KnobType::Int,
        0,
        3,
        2,
        "far-field levels: level k splats the first n / 16^k of a light's n samples 4^k times as far (their "
        "weight n / that), for about k + 1 times the splats' cost",
        {0, 1, 3},
        {0},
        true},
       &SplattingKnobs::farLevels},
  };
  return table;
}

namespace {

constexpr int kMaxLevels = 14;

int paddedSide(int size) {
  int p = 1;
  while (p < size) p *= 2;
  return p;
}

/// The flux light i sends into the region (luminance): what its sample budget follows.
double lightWeight(const SceneLight& l, const Region& region) {
  const double r = region.radius();
  if (l.type == LightType::Directional) return capture::luminance(l.irradiance) * 4.0 * r * r;
  const double d = cv::norm(region.centre() - l.position);
  const double solid = d > r ? 2.0 * CV_PI * (1.0 - std::sqrt(1.0 - (r / d) * (r / d))) : 4.0 * CV_PI;
  return capture::luminance(l.intensity) * solid;
}

/// The light and the ambient for splat_texel.glsl: a light's share of the ambient's bounce is 1 / the lights
/// with samples (each light's RSM tiles the surfaces it sees once).
void setTexelUniforms(const gl::Program& p, const FrameResources& frame, const SceneLight& l, float ambientShare) {
  p.set("uLightType", shaderLightType(l.type));
  setVec3(p, "uLightPosition", l.position);
  setVec3(p, "uLightDirection", l.direction);
  setVec3(p, "uLightPower", l.type == LightType::Directional ? l.irradiance : l.intensity);
  setAmbientUniforms(p, frame);
  p.set("uAmbientShare", ambientShare);
}

/// The reach of a texel's occlusion in its RSM (splat::rsmOcclusion): an eighth of the region's side.
float aoRadius(const Region& region) { return static_cast<float>(region.side / 8.0); }

void bindRsms(const FrameResources& frame) {
  const Rsm& r = frame.rsmRho();
  const Rsm& m = frame.rsmMu();
  r.position.bind(0), r.normal.bind(1), r.flux.bind(2), r.direct.bind(3);
  m.position.bind(4), m.normal.bind(5), m.flux.bind(6), m.direct.bind(7);
}

}  // namespace

TechniqueInfo splattingTechniqueInfo() {
  TechniqueInfo t;
  t.name = "splatting";
  t.description =
      "Splatting: importance-sampled pixel lights of the RSMs splatted over their significant regions, on real pixels "
      "and the object";
  t.real = true;
  t.virtualObject = true;
  t.stagePrefixes = {"splat."};
  t.knobs = groupOf("splat", splattingKnobTable());
  t.create = [](const TechniqueSetup& s) { return std::make_unique<SplattingTechnique>(s); };
  t.estimateBytes = [](const KnobValues& values, const KnobValues& frame, bool real, bool virtualObject, int w, int h,
                       size_t) {
    const SplattingKnobs k = knobsFrom(splattingKnobTable(), values);
    // Two importance pyramids over the padded RSM (4/3 of its texels), the lights (3 records per sample for
    // the delta, 1 for the object, plus one sample per light), the two outputs.
    const auto p = static_cast<size_t>(paddedSide(static_cast<int>(knobsFrom(frameKnobTable(), frame).rsmSize)));
    const size_t pyramid = 2 * (4 * p * p / 3 + 1) * sizeof(float);
    const size_t samples = static_cast<size_t>(k.vpls) + kMaxLights;
    return pyramid + ((real ? 3 : 0) + (virtualObject ? 1 : 0)) * samples * sizeof(splat::PixelLight) +
           2 * 16 * static_cast<size_t>(w) * static_cast<size_t>(h);
  };
  return t;
}

SplattingTechnique::SplattingTechnique(const TechniqueSetup& setup)
    : knobs_(knobsFrom(splattingKnobTable(), setup.knobs)),
      real_(setup.real),
      virtual_(setup.virtualObject),
      importanceProgram_(gl::Program::compute("lighting/techniques/splatting/splat_importance.comp")),
      reduceProgram_(gl::Program::compute("lighting/techniques/splatting/splat_reduce.comp")),
      sampleProgram_(gl::Program::compute("lighting/techniques/splatting/splat_sample.comp")),
      splatProgram_(gl::Program::graphics("lighting/techniques/splatting/splat.vert",
                                          "lighting/techniques/splatting/splat.frag")),
      out_(setup.frame->techniqueView().width, setup.frame->techniqueView().height) {
  // Pyramid layout for the frame's RSM size: level 0 padded to a power of two, then halves down to 1 x 1.
  padded_ = paddedSide(setup.frame->rsmSize());
  int offset = 0;
  for (int side = padded_; side >= 1; side /= 2) {
    levelOffsets_.push_back(offset);
    offset += side * side;
  }
  levels_ = static_cast<int>(levelOffsets_.size());
  if (levels_ > kMaxLevels) throw std::invalid_argument("splatting: the RSM is too large for its importance pyramid");
  deltaPyramid_ = gl::Buffer::storage(static_cast<size_t>(offset) * sizeof(float));
  objectPyramid_ = gl::Buffer::storage(static_cast<size_t>(offset) * sizeof(float));
  const size_t samples = static_cast<size_t>(knobs_.vpls) + kMaxLights;
  if (real_) deltaLights_ = gl::Buffer::storage(3 * samples * sizeof(splat::PixelLight));
  if (virtual_) objectLights_ = gl::Buffer::storage(samples * sizeof(splat::PixelLight));
}

void SplattingTechnique::beginLights(const FrameResources& frame, gl::Profiler*) {
  const auto& lights = frame.lights();
  std::vector<double> w(lights.size());
  double sum = 0;
  for (size_t i = 0; i < lights.size(); ++i) sum += (w[i] = std::max(0.0, lightWeight(lights[i], *frame.region())));
  budget_.assign(lights.size(), 0);
  for (size_t i = 0; i < lights.size(); ++i)
    if (w[i] > 0 && sum > 0) budget_[i] = std::max(1, static_cast<int>(std::floor(knobs_.vpls * w[i] / sum)));
  deltaRecords_ = objectRecords_ = samplesSoFar_ = 0;
  sampled_.clear();
  const auto sampled = std::count_if(budget_.begin(), budget_.end(), [](int n) { return n > 0; });
  ambientShare_ = sampled > 0 ? 1.0f / static_cast<float>(sampled) : 0.0f;
  const double s = frame.region()->side;
  iLowScale_ = static_cast<float>(knobs_.iLow / (CV_PI * s * s));
}

void SplattingTechnique::light(const FrameResources& frame, size_t index, gl::Profiler* profiler) {
  const int n = index < budget_.size() ? budget_[index] : 0;
  if (n <= 0) return;
  {
    auto s = timed(profiler, "splat.importance");
    const gl::Program& p = importanceProgram_;
    p.use();
    p.set("uSize", frame.rsmSize());
    p.set("uPadded", padded_);
    setObjectLobes(p, frame);
    setTexelUniforms(p, frame, frame.lights().at(index), ambientShare_);
    aoRadius_ = aoRadius(*frame.region());
    p.set("uAoRadius", aoRadius_);
    bindRsms(frame);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, deltaPyramid_.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, objectPyramid_.id());
    const auto groups = static_cast<GLuint>((padded_ + 7) / 8);
    glDispatchCompute(groups, groups, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    const gl::Program& r = reduceProgram_;
    r.use();
    for (const gl::Buffer* b : {&deltaPyramid_, &objectPyramid_}) {
      if ((b == &deltaPyramid_ && !real_) || (b == &objectPyramid_ && !virtual_)) continue;
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, b->id());
      for (int k = 1; k < levels_; ++k) {
        const int side = padded_ >> k;
        r.set("uSrcOffset", levelOffsets_[static_cast<size_t>(k - 1)]);
        r.set("uDstOffset", levelOffsets_[static_cast<size_t>(k)]);
        r.set("uDstSide", side);
        glDispatchCompute(static_cast<GLuint>((side + 7) / 8), static_cast<GLuint>((side + 7) / 8), 1);
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      }
    }
  }
  auto s = timed(profiler, "splat.sample");
  if (real_) {
    sampleLight(frame, index, true, n, samplesSoFar_, deltaRecords_);
    deltaRecords_ += 3 * n;
  }
  if (virtual_) {
    sampleLight(frame, index, false, n, samplesSoFar_, objectRecords_);
    objectRecords_ += n;
  }
  lastSamples_ = {samplesSoFar_, n};
  sampled_.push_back(lastSamples_);
  samplesSoFar_ += n;
}

void SplattingTechnique::sampleLight(const FrameResources& frame, size_t index, bool delta, int count, int firstSample,
                                     int firstRecord) {
  const gl::Program& p = sampleProgram_;
  p.use();
  const SceneLight& l = frame.lights().at(index);
  p.set("uMode", delta ? 0 : 1);
  p.set("uCount", count);
  p.set("uFirstSample", firstSample);
  p.set("uFirstRecord", firstRecord);
  p.set("uLevels", levels_);
  for (int k = 0; k < kMaxLevels; ++k)
    p.set("uLevelOffset[" + std::to_string(k) + "]", k < levels_ ? levelOffsets_[static_cast<size_t>(k)] : 0);
  setTexelUniforms(p, frame, l, ambientShare_);
  p.set("uWiden", static_cast<float>(knobs_.widen));
  setObjectLobes(p, frame);
  bindRsms(frame);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, (delta ? deltaPyramid_ : objectPyramid_).id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, (delta ? deltaLights_ : objectLights_).id());
  glDispatchCompute(static_cast<GLuint>((count + 63) / 64), 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
}

void SplattingTechnique::update(const FrameResources& frame, gl::Profiler* profiler) {
  auto s = timed(profiler, "splat.splat");
  out_.fb.bind();
  glViewport(0, 0, frame.techniqueView().width, frame.techniqueView().height);
  const float zero[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(out_.fb.id(), GL_COLOR, 0, zero);
  glClearNamedFramebufferfv(out_.fb.id(), GL_COLOR, 1, zero);
  if (!frame.region()) return;
  glDisable(GL_DEPTH_TEST);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE);
  glBlendEquation(GL_FUNC_ADD);
  const gl::Program& p = splatProgram_;
  p.use();
  const CameraView& cam = frame.camera();
  const auto vp = toGl(projectionFromIntrinsics(cam.intrinsics, cam.nearPlane, cam.farPlane) *
                       capture::inversePose(cam.T_world_camera));
  p.setMat4("uViewProj", vp.data());
  frame.techniqueView().bind();
  emptyVao_.bind();
  // Level 0: every record over its own box, in one draw; far level k (splat.h splatFar): per light the
  // records of its first farSamples(n, k) samples over the shell out to I_low / 16^k, weighted.
  const auto draw = [&](int target, const gl::Buffer& records, int perSample, int total,
                        const std::vector<std::pair<int, int>>& groups) {
    if (total <= 0) return;
    p.set("uTarget", target);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, records.id());
    p.set("uLevel", 0);
    p.set("uFarLevels", knobs_.farLevels);
    p.set("uWeight", 1.0f);
    p.set("uILowScale", iLowScale_);
    p.set("uFirstRecord", 0);
    glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, total);
    float scale = iLowScale_;
    for (int k = 1; k <= knobs_.farLevels; ++k) {
      scale /= static_cast<float>(splat::kFarStride);
      p.set("uLevel", k);
      p.set("uILowScale", scale);
      for (const auto& [first, n] : groups) {
        const int m = splat::farSamples(n, k);
        if (m <= 0) continue;
        p.set("uWeight", splat::farWeight(n, k));
        p.set("uFirstRecord", perSample * first);
        glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, perSample * m);
      }
    }
  };
  if (real_) draw(0, deltaLights_, 3, deltaRecords_, sampled_);
  if (virtual_) draw(1, objectLights_, 1, objectRecords_, sampled_);
  glDisable(GL_BLEND);
  gl::checkGlError("SplattingTechnique::update()");
}

std::vector<splat::PixelLight> SplattingTechnique::downloadLights(bool delta) const {
  const int n = delta ? deltaRecords_ : objectRecords_;
  std::vector<splat::PixelLight> out(static_cast<size_t>(n));
  if (n > 0)
    (delta ? deltaLights_ : objectLights_)
        .download(0, static_cast<GLsizeiptr>(out.size() * sizeof(splat::PixelLight)), out.data());
  return out;
}

cv::Mat SplattingTechnique::downloadImportance(bool delta) const {
  cv::Mat m(padded_, padded_, CV_32F);
  (delta ? deltaPyramid_ : objectPyramid_).download(0, static_cast<GLsizeiptr>(m.total() * sizeof(float)), m.ptr());
  return m;
}

cv::Mat SplattingTechnique::debugImage(const std::string& view, const DebugContext& context,
                                       nlohmann::json& info) const {
  if (view == "splat_overdraw") {
    // Splats that reached each pixel (the outputs' alpha), black = 0, white = the largest count.
    cv::Mat a = download4(out_.realDelta), b = download4(out_.virtualIrradiance);
    cv::Mat img(a.size(), CV_8UC3);
    double peak = 1, sum = 0;
    for (int i = 0; i < static_cast<int>(a.total()); ++i)
      peak = std::max(peak, double(a.at<cv::Vec4f>(i)[3] + b.at<cv::Vec4f>(i)[3]));
    for (int i = 0; i < static_cast<int>(a.total()); ++i) {
      const double c = a.at<cv::Vec4f>(i)[3] + b.at<cv::Vec4f>(i)[3];
      sum += c;
      const auto v = cv::saturate_cast<uchar>(255.0 * std::sqrt(c / peak));
      img.at<cv::Vec3b>(i) = {v, v, v};
    }
    info["max_splats_per_pixel"] = peak;
    info["mean_splats_per_pixel"] = sum / std::max<double>(1.0, static_cast<double>(a.total()));
    // At render_scale < 1 the splats land on the reduced grid: shown at the frame's size, a texel per block.
    if (!context.composite.empty() && img.size() != context.composite.size())
      cv::resize(img, img, context.composite.size(), 0, 0, cv::INTER_NEAREST);
    return img;
  }
  if (view == "splat_vpls") {
    // The last light's importance (delta where the object serves real pixels, else the object's), grey by
    // sqrt, with the texels its samples chose in yellow.
    const bool delta = real_;
    const cv::Mat imp = downloadImportance(delta);
    double peak = 0;
    for (int i = 0; i < static_cast<int>(imp.total()); ++i) peak = std::max(peak, double(imp.at<float>(i)));
    cv::Mat img(imp.size(), CV_8UC3, cv::Scalar(0, 0, 0));
    for (int i = 0; i < static_cast<int>(imp.total()); ++i) {
      const auto v = cv::saturate_cast<uchar>(peak > 0 ? 200.0 * std::sqrt(imp.at<float>(i) / peak) : 0.0);
      img.at<cv::Vec3b>(i) = {v, v, v};
    }
    // The texels the light's samples warped to (splat.h warp on the same importance, as the GPU warps).
    const splat::Pyramid pyr = splat::buildPyramid(imp);
    int marked = 0;
    for (int k = 0; k < lastSamples_.second; ++k) {
      const splat::Warped w = splat::warp(pyr, splat::samplePoint(lastSamples_.first + k));
      if (w.texel.x < 0 || w.texel.y < 0 || w.texel.x >= img.cols || w.texel.y >= img.rows) continue;
      img.at<cv::Vec3b>(w.texel.y, w.texel.x) = {0, 230, 255};  // BGR yellow
      ++marked;
    }
    info["importance_peak"] = peak;
    info["sampled_texels_marked"] = marked;
    return img;
  }
  return {};
}

nlohmann::json SplattingTechnique::stats() const {
  return {{"samples", samplesSoFar_}, {"delta_lights", deltaRecords_}, {"object_lights", objectRecords_}};
}

size_t SplattingTechnique::gpuBytes() const {
  size_t sum = out_.bytes();
  for (const gl::Buffer* b : {&deltaPyramid_, &objectPyramid_, &deltaLights_, &objectLights_})
    sum += static_cast<size_t>(b->id() ? b->size() : 0);
  return sum;
}

}  // namespace mrgi::lighting
