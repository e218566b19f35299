#pragma once
/// The differential-rendering compositor (algorithms.md §3, Algorithm 1) in linear light:
/// real pixels = background + delta, virtual pixels = their own shaded radiance; sRGB decode/encode only
/// at the boundaries, the background otherwise untouched.
#include <opencv2/core.hpp>

#include "gl/objects.h"
#include "gl/profiler.h"
#include "gl/program.h"

namespace mrgi::compositor {

/// CPU reference of the GPU merge (same math): background RGB8 sRGB; delta CV_32FC3 linear (empty = 0);
/// virtualMask CV_8UC1, 255 on virtual pixels (empty = none), whose radiance is taken from delta.
/// `exposure`: the camera image's linear value per unit scene radiance (capture::RgbdFrame::exposure);
/// delta and virtual radiance are scene radiance and are scaled by it.
cv::Mat compositeReference(const cv::Mat& background, const cv::Mat& delta, const cv::Mat& virtualMask, double exposure = 1.0);

class Compositor {
 public:
  /// Needs a current GL 4.5 context. width x height is the output (camera colour) resolution.
  Compositor(int width, int height);

  /// Same contract as compositeReference, on the GPU; returns RGB8. Timed as "composite".
  cv::Mat composite(const cv::Mat& background, const cv::Mat& delta, const cv::Mat& virtualMask, gl::Profiler* profiler);

  /// Same merge with the delta already on the GPU: RGBA32F, rgb = delta or virtual radiance, a = 1 on
  /// virtual pixels (lighting::LightingPipeline::shade()).
  cv::Mat composite(const cv::Mat& background, const gl::Texture& delta, gl::Profiler* profiler);

  /// The camera exposure of the frames that follow (compositeReference's `exposure`); 1 by default.
  void setExposure(double exposure);

  const gl::Texture& output() const { return output_; }
  /// Draws the last composite into the default framebuffer (window backend), scaled to width x height.
  void present(int width, int height) const;

 private:
  int width_, height_;
  gl::Program program_;
  gl::Texture background_, delta_, output_;
  gl::Framebuffer framebuffer_;
  gl::VertexArray vao_;
  /// Uploads the background and draws the merge with delta (the two composite() overloads' shared tail).
  cv::Mat merge(const cv::Mat& background, const gl::Texture& delta);
};

}  // namespace mrgi::compositor
