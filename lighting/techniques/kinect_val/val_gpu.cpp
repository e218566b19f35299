#include "lighting/techniques/kinect_val/val_gpu.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "gl/error.h"

namespace mrgi::lighting {

ValGpu::ValGpu(int kCache)
    : kCache_(kCache),
      gather_(gl::Program::compute("lighting/techniques/kinect_val/val_gather.comp", {{"K_CACHE", std::to_string(kCache)}})),
      occlude_(gl::Program::compute("lighting/techniques/kinect_val/val_occlude.comp")) {
  if (kCache < 16 || kCache > 512) throw std::invalid_argument("K_cache must be in 16..512, got " + std::to_string(kCache));
}

void ValGpu::ensure(gl::Buffer& b, size_t bytes) {
  bytes = std::max<size_t>(bytes, 64);
  if (static_cast<size_t>(b.size()) < bytes) b = gl::Buffer(static_cast<GLsizeiptr>(bytes), nullptr);
}

void ValGpu::setVals(const std::vector<Val>& vals) {
  valCount_ = vals.size();
  ensure(vals_, vals.size() * sizeof(Val));
  if (!vals.empty()) vals_.upload(0, static_cast<GLsizeiptr>(vals.size() * sizeof(Val)), vals.data());
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
