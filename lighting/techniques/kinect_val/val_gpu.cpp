#include "lighting/techniques/kinect_val/val_gpu.h"

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <string>

#include "gl/error.h"

namespace mrgi::lighting {

ValGpu::ValGpu(int kCache)
    : kCache_(kCache),
      gather_(gl::Program::compute("lighting/techniques/kinect_val/val_gather.comp",
                                   {{"K_CACHE", std::to_string(kCache)}})),
      occlude_(gl::Program::compute("lighting/techniques/kinect_val/val_occlude.comp")),
      rsmVals_(gl::Program::compute("lighting/techniques/kinect_val/val_rsm.comp")),
      dim_(gl::Program::compute("lighting/techniques/kinect_val/val_dim.comp")),
      weights_(gl::Program::compute("lighting/techniques/kinect_val/val_weights.comp")) {
  if (kCache < 16 || kCache > 512)
    throw std::invalid_argument("K_cache must be in 16..512, got " + std::to_string(kCache));
  const Counts none;
  counts_ = gl::Buffer(sizeof(Counts), &none);
}

namespace {
void barrier() { glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT); }
}  // namespace

size_t ValGpu::rsmValCapacity(int rsmSize, int stride) {
  stride = std::max(stride, 1);
  const int first = stride / 2;
  const size_t side = rsmSize > first ? static_cast<size_t>((rsmSize - first + stride - 1) / stride) : 0;
  return side * side;
}

void ValGpu::beginVirtual(size_t capacity) {
  virtualCapacity_ = capacity;
  ensure(virtual_, capacity * sizeof(Val));
  const uint32_t zero = 0;
  counts_.upload(offsetof(Counts, virtualVals), sizeof zero, &zero);
}

void ValGpu::appendRsmVals(const Rsm& rsm, const SceneLight& light, int stride) {
  rsmVals_.use();
  rsmVals_.set("uStride", std::max(stride, 1));
  rsmVals_.set("uCapacity", static_cast<int>(virtualCapacity_));
  rsmVals_.set("uLightType", light.type == LightType::Point ? 0 : light.type == LightType::Spot ? 1 : 2);
  setVec3(rsmVals_, "uLightPosition", light.position);
  setVec3(rsmVals_, "uLightDirection", light.direction);
  setVec3(rsmVals_, "uLightPower", light.type == LightType::Directional ? light.irradiance : light.intensity);
  rsm.position.bind(0);
  rsm.normal.bind(1);
  rsm.flux.bind(2);
  rsm.direct.bind(3);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, virtual_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, counts_.id());
  glDispatchCompute(1, 1, 1);
  barrier();
  gl::checkGlError("ValGpu::appendRsmVals()");
}

void ValGpu::assemble(const std::vector<Val>& real, const FrameResources& frame) {
  const size_t n = real.size();
  valCount_ = n + virtualCapacity_;
  ensure(vals_, valCount_ * sizeof(Val));
  if (n) vals_.upload(0, static_cast<GLsizeiptr>(n * sizeof(Val)), real.data());
  const uint32_t zero = 0;
  counts_.upload(offsetof(Counts, dimmed), sizeof zero, &zero);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, vals_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, counts_.id());
  if (n && !frame.lights().empty()) {
    dim_.use();
    setLightUniforms(dim_, frame.lights(), frame.lightViews());
    frame.bindShadowMaps();
    dim_.set("uRealCount", static_cast<int>(n));
    setVec3(dim_, "uAmbientIrradiance", CV_PI * frame.ambient());
    glDispatchCompute(static_cast<GLuint>((n + 63) / 64), 1, 1);
    barrier();
  }
  if (virtualCapacity_)
    glCopyNamedBufferSubData(virtual_.id(), vals_.id(), 0, static_cast<GLintptr>(n * sizeof(Val)),
                             static_cast<GLsizeiptr>(virtualCapacity_ * sizeof(Val)));
  barrier();
  weights_.use();
  weights_.set("uRealCount", static_cast<int>(n));
  weights_.set("uCapacity", static_cast<int>(valCount_));
  glDispatchCompute(1, 1, 1);
  barrier();
  gl::checkGlError("ValGpu::assemble()");
}

ValGpu::Counts ValGpu::downloadCounts() const {
  Counts c;
  counts_.download(0, sizeof c, &c);
  return c;
}

std::vector<Val> ValGpu::downloadVals() const {
  std::vector<Val> out(std::min<size_t>(downloadCounts().all, valCount_));
  if (!out.empty()) vals_.download(0, static_cast<GLsizeiptr>(out.size() * sizeof(Val)), out.data());
  return out;
}

void ValGpu::ensure(gl::Buffer& b, size_t bytes) {
  bytes = std::max<size_t>(bytes, 64);
  if (static_cast<size_t>(b.size()) < bytes) b = gl::Buffer(static_cast<GLsizeiptr>(bytes), nullptr);
}

void ValGpu::setVals(const std::vector<Val>& vals) {
  valCount_ = vals.size();
  ensure(vals_, vals.size() * sizeof(Val));
  if (!vals.empty()) vals_.upload(0, static_cast<GLsizeiptr>(vals.size() * sizeof(Val)), vals.data());
  Counts c;
  c.all = c.real = static_cast<uint32_t>(vals.size());
  counts_.upload(0, sizeof c, &c);
}

void ValGpu::gather(const std::vector<Receiver>& receivers) {
  receiverCount_ = receivers.size();
  std::vector<cv::Vec4f> packed(receivers.size() * 3);
  for (size_t i = 0; i < receivers.size(); ++i) {
    const Receiver& r = receivers[i];
    packed[3 * i] = {r.position[0], r.position[1], r.position[2], r.exponent};
    packed[3 * i + 1] = {r.normal[0], r.normal[1], r.normal[2], 0.f};
    packed[3 * i + 2] = {r.view[0], r.view[1], r.view[2], 0.f};
  }
  ensure(receivers_, packed.size() * sizeof(cv::Vec4f));
  ensure(vpls_, receivers.size() * sizeof(SparseVpl));
  ensure(sums_, receivers.size() * 2 * sizeof(cv::Vec4f));
  if (receivers.empty()) return;
  receivers_.upload(0, static_cast<GLsizeiptr>(packed.size() * sizeof(cv::Vec4f)), packed.data());
  const size_t chunks = std::max<size_t>(1, (valCount_ + kValsPerDispatch - 1) / kValsPerDispatch);
  ensure(partial_, chunks > 1 ? receivers.size() * 5 * sizeof(cv::Vec4f) : 0);  // untouched by a single chunk
  gather_.use();
  gather_.set("uReceiverCount", static_cast<int>(receivers.size()));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, vals_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, receivers_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, vpls_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, sums_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, partial_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, counts_.id());
  for (size_t c = 0; c < chunks; ++c) {
    gather_.set("uValBegin", static_cast<int>(c * kValsPerDispatch));
    gather_.set("uValEnd", static_cast<int>(std::min(valCount_, (c + 1) * kValsPerDispatch)));
    gather_.set("uFirstChunk", c == 0 ? 1 : 0);
    gather_.set("uLastChunk", c + 1 == chunks ? 1 : 0);
    glDispatchCompute(static_cast<GLuint>((receivers.size() + 63) / 64), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  }
  gl::checkGlError("ValGpu::gather()");
}

void ValGpu::occlude(const std::vector<cv::Vec3f>& positions, const std::vector<cv::Vec3f>& normals,
                     const std::vector<float>& discRadius) {
  if (positions.size() != receiverCount_ || normals.size() != receiverCount_ || discRadius.size() != receiverCount_)
    throw std::invalid_argument("ValGpu::occlude(): one occluder per receiver of the last gather");
  if (positions.empty()) return;
  std::vector<cv::Vec4f> packed(positions.size() * 2);
  for (size_t i = 0; i < positions.size(); ++i) {
    packed[2 * i] = {positions[i][0], positions[i][1], positions[i][2], discRadius[i]};
    packed[2 * i + 1] = {normals[i][0], normals[i][1], normals[i][2], 0.f};
  }
  ensure(occluders_, packed.size() * sizeof(cv::Vec4f));
  occluders_.upload(0, static_cast<GLsizeiptr>(packed.size() * sizeof(cv::Vec4f)), packed.data());
  ensure(vplsScratch_, receiverCount_ * sizeof(SparseVpl));
  occlude_.use();
  occlude_.set("uCount", static_cast<int>(receiverCount_));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, occluders_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, vpls_.id());
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, vplsScratch_.id());
  glDispatchCompute(static_cast<GLuint>((receiverCount_ + 63) / 64), 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  std::swap(vpls_, vplsScratch_);
  gl::checkGlError("ValGpu::occlude()");
}

std::vector<SparseVpl> ValGpu::downloadVpls() const {
  std::vector<SparseVpl> out(receiverCount_);
  if (!out.empty()) vpls_.download(0, static_cast<GLsizeiptr>(out.size() * sizeof(SparseVpl)), out.data());
  return out;
}

void ValGpu::downloadSums(std::vector<cv::Vec3f>& E, std::vector<cv::Vec3f>& S) const {
  std::vector<cv::Vec4f> raw(receiverCount_ * 2);
  if (!raw.empty()) sums_.download(0, static_cast<GLsizeiptr>(raw.size() * sizeof(cv::Vec4f)), raw.data());
  E.resize(receiverCount_);
  S.resize(receiverCount_);
  for (size_t i = 0; i < receiverCount_; ++i) {
    E[i] = {raw[2 * i][0], raw[2 * i][1], raw[2 * i][2]};
    S[i] = {raw[2 * i + 1][0], raw[2 * i + 1][1], raw[2 * i + 1][2]};
  }
}

}  // namespace mrgi::lighting
