#include "compositor/compositor.h"

#include <optional>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "gl/error.h"
#include "capture/colour.h"

namespace mrgi::compositor {

cv::Mat compositeReference(const cv::Mat& background, const cv::Mat& delta, const cv::Mat& virtualMask, double exposure) {
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

  cv::Mat out4(height_, width_, CV_8UC4);
  output_.download(GL_RGBA, GL_UNSIGNED_BYTE, out4.ptr(), static_cast<GLsizei>(out4.total() * 4), 4);
  gl::checkGlError("Compositor::composite()");
  cv::Mat out;
  cv::cvtColor(out4, out, cv::COLOR_RGBA2RGB);
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
