#include "compositor/compositor.h"

#include <cstring>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <vector>

#include "capture/colour.h"
#include "gl/error.h"

namespace mrgi::compositor {

cv::Mat compositeReference(const cv::Mat& background, const cv::Mat& delta, const cv::Mat& virtualMask,
                           double exposure) {
  CV_Assert(background.type() == CV_8UC3);
  cv::Mat linear = capture::decodeSrgb(background);
  if (!delta.empty()) {
    CV_Assert(delta.type() == CV_32FC3 && delta.size() == background.size());
    for (int y = 0; y < linear.rows; ++y) {
      auto* l = linear.ptr<cv::Vec3f>(y);
      const auto* d = delta.ptr<cv::Vec3f>(y);
      const uchar* m = virtualMask.empty() ? nullptr : virtualMask.ptr<uchar>(y);
      const float e = static_cast<float>(exposure);
      for (int x = 0; x < linear.cols; ++x) l[x] = (m && m[x] > 127) ? d[x] * e : l[x] + d[x] * e;
    }
  }
  return capture::encodeSrgb(linear);
}

Compositor::Compositor(int width, int height)
    : width_(width),
      height_(height),
      program_(gl::Program::graphics("lighting/gl/fullscreen.vert", "compositor/composite.frag")),
      background_(GL_TEXTURE_2D, GL_RGBA8, width, height),
      delta_(GL_TEXTURE_2D, GL_RGBA32F, width, height),
      output_(GL_TEXTURE_2D, GL_RGBA8, width, height) {
  background_.setFilter(GL_NEAREST, GL_NEAREST);
  delta_.setFilter(GL_NEAREST, GL_NEAREST);
  output_.setFilter(GL_LINEAR, GL_NEAREST);  // a view that zooms in (live, present) shows whole pixels
  framebuffer_.attachColour(0, output_);
  framebuffer_.finalise(1);
}

void Compositor::setExposure(double exposure) { program_.set("uExposure", static_cast<float>(exposure)); }

cv::Mat Compositor::composite(const cv::Mat& background, const cv::Mat& delta, const cv::Mat& virtualMask,
                              gl::Profiler* profiler) {
  CV_Assert(background.type() == CV_8UC3 && background.cols == width_ && background.rows == height_);
  std::optional<gl::Profiler::Scope> scope;
  if (profiler) scope.emplace(*profiler, "composite", true);
  cv::Mat delta4(height_, width_, CV_32FC4, cv::Scalar(0, 0, 0, 0));
  if (!delta.empty()) {
    CV_Assert(delta.type() == CV_32FC3 && delta.size() == background.size());
    for (int y = 0; y < height_; ++y) {
      const auto* d = delta.ptr<cv::Vec3f>(y);
      const uchar* m = virtualMask.empty() ? nullptr : virtualMask.ptr<uchar>(y);
      auto* o = delta4.ptr<cv::Vec4f>(y);
      for (int x = 0; x < width_; ++x) o[x] = {d[x][0], d[x][1], d[x][2], (m && m[x] > 127) ? 1.f : 0.f};
    }
  }
  delta_.upload(GL_RGBA, GL_FLOAT, delta4.ptr(), 4);
  return merge(background, delta_);
}

cv::Mat Compositor::composite(const cv::Mat& background, const gl::Texture& delta, gl::Profiler* profiler) {
  CV_Assert(background.type() == CV_8UC3 && background.cols == width_ && background.rows == height_);
  CV_Assert(delta.width() == width_ && delta.height() == height_);
  std::optional<gl::Profiler::Scope> scope;
  if (profiler) scope.emplace(*profiler, "composite", true);
  return merge(background, delta);
}

cv::Mat Compositor::merge(const cv::Mat& background, const gl::Texture& delta) {
  cv::Mat rgba;
  cv::cvtColor(background, rgba, cv::COLOR_RGB2RGBA);
  background_.upload(GL_RGBA, GL_UNSIGNED_BYTE, rgba.ptr(), 4);
  framebuffer_.bind();
  glViewport(0, 0, width_, height_);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  program_.use();
  background_.bind(0);
  delta.bind(1);
  vao_.bind();
  glDrawArrays(GL_TRIANGLES, 0, 3);

  if (readback_ == Readback::None) return {};
  const GLsizeiptr bytes = static_cast<GLsizeiptr>(width_) * height_ * 4;
  if (readback_ == Readback::Later) {
    if (reads_.size() >= 3) {
      ready_.push_back(finish(reads_.front(), true));
      reads_.erase(reads_.begin());
    }
    Read r;
    if (spare_.empty()) {
      r.pixels = gl::Buffer(bytes, nullptr, GL_MAP_READ_BIT);
    } else {
      r.pixels = std::move(spare_.back());
      spare_.pop_back();
    }
    glBindBuffer(GL_PIXEL_PACK_BUFFER, r.pixels.id());
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(output_.id(), 0, GL_RGBA, GL_UNSIGNED_BYTE, static_cast<GLsizei>(bytes), nullptr);
    glBindBuffer(GL_PIXEL_PACK_BUFFER, 0);
    r.fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
    glFlush();  // the read starts now, not when the next frame's work forces it
    gl::checkGlError("Compositor::composite() (read into a pixel buffer)");
    reads_.push_back(std::move(r));
    return {};
  }
  cv::Mat out = readOutput();
  gl::checkGlError("Compositor::composite()");
  return out;
}

Compositor::~Compositor() {
  for (Read& r : reads_)
    if (r.fence) glDeleteSync(r.fence);
}

void Compositor::setReadback(Readback mode) { readback_ = mode; }

cv::Mat Compositor::readOutput() const {
  cv::Mat out4(height_, width_, CV_8UC4), out;
  output_.download(GL_RGBA, GL_UNSIGNED_BYTE, out4.ptr(), static_cast<GLsizei>(out4.total() * 4), 4);
  cv::cvtColor(out4, out, cv::COLOR_RGBA2RGB);
  return out;
}

cv::Mat Compositor::finish(Read& r, bool wait) {
  GLenum state = glClientWaitSync(r.fence, 0, 0);
  if (state == GL_TIMEOUT_EXPIRED) {
    if (!wait) return {};
    gl::countSynchronousReadback();  // the CPU waits for the GPU here
    state = glClientWaitSync(r.fence, GL_SYNC_FLUSH_COMMANDS_BIT, 10'000'000'000ull);
  }
  if (state != GL_ALREADY_SIGNALED && state != GL_CONDITION_SATISFIED)
    throw gl::GlError("Compositor: a composite's read did not finish (glClientWaitSync " + std::to_string(state) + ")");
  glDeleteSync(r.fence);
  r.fence = nullptr;
  const GLsizeiptr bytes = static_cast<GLsizeiptr>(width_) * height_ * 4;
  cv::Mat out4(height_, width_, CV_8UC4);
  const void* mapped = glMapNamedBufferRange(r.pixels.id(), 0, bytes, GL_MAP_READ_BIT);
  if (!mapped) throw gl::GlError("Compositor: cannot map a composite's pixel buffer");
  std::memcpy(out4.ptr(), mapped, static_cast<size_t>(bytes));
  glUnmapNamedBuffer(r.pixels.id());
  spare_.push_back(std::move(r.pixels));
  cv::Mat out;
  cv::cvtColor(out4, out, cv::COLOR_RGBA2RGB);
  return out;
}

std::vector<cv::Mat> Compositor::takeComposites(bool wait) {
  std::vector<cv::Mat> out = std::move(ready_);
  ready_.clear();
  while (!reads_.empty()) {
    cv::Mat m = finish(reads_.front(), wait);
    if (m.empty()) break;  // still in flight (and so are the later ones)
    out.push_back(std::move(m));
    reads_.erase(reads_.begin());
  }
  return out;
}

}  // namespace mrgi::compositor

namespace mrgi::compositor {
void Compositor::present(int width, int height) const {
  // Rows are stored top-first, GL's default framebuffer is bottom-first: flip while blitting.
  glBlitNamedFramebuffer(framebuffer_.id(), 0, 0, 0, width_, height_, 0, height, width, 0, GL_COLOR_BUFFER_BIT,
                         GL_LINEAR);
}
}  // namespace mrgi::compositor
