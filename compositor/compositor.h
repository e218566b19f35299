#pragma once
/// The differential-rendering compositor (algorithms.md §3, Algorithm 1) in linear light:
/// real pixels = background + delta, virtual pixels = their own shaded radiance; sRGB decode/encode only
/// at the boundaries, the background otherwise untouched.
#include <opencv2/core.hpp>
#include <vector>

#include "gl/objects.h"
#include "gl/profiler.h"
#include "gl/program.h"

namespace mrgi::compositor {

/// CPU reference of the GPU merge (same math): background RGB8 sRGB; delta CV_32FC3 linear (empty = 0);
/// virtualMask CV_8UC1, 255 on virtual pixels (empty = none), whose radiance is taken from delta.
/// `exposure`: the camera image's linear value per unit scene radiance (capture::RgbdFrame::exposure);
/// delta and virtual radiance are scene radiance and are scaled by it.
cv::Mat compositeReference(const cv::Mat& background, const cv::Mat& delta, const cv::Mat& virtualMask,
                           double exposure = 1.0);

class Compositor {
 public:
  /// Needs a current GL 4.5 context. width x height is the output (camera colour) resolution.
  Compositor(int width, int height);
  ~Compositor();
  Compositor(const Compositor&) = delete;
  Compositor& operator=(const Compositor&) = delete;

  /// Same contract as compositeReference, on the GPU; returns RGB8. Timed as "composite".
  cv::Mat composite(const cv::Mat& background, const cv::Mat& delta, const cv::Mat& virtualMask,
                    gl::Profiler* profiler);

  /// Same merge with the delta already on the GPU: RGBA32F, rgb = delta or virtual radiance, a = 1 on
  /// virtual pixels (lighting::LightingPipeline::shade()).
  cv::Mat composite(const cv::Mat& background, const gl::Texture& delta, gl::Profiler* profiler);

  /// The camera exposure of the frames that follow (compositeReference's `exposure`); 1 by default.
  void setExposure(double exposure);

  /// What composite() does with the merged image once drawn.
  enum class Readback {
    Now,    ///< reads it back at once and returns it (the CPU waits for the GPU)
    Later,  ///< starts a read into a pixel buffer and returns an empty image; takeComposites() hands it over
    None,   ///< leaves it on the GPU (output(), present()) and returns an empty image
  };
  void setReadback(Readback mode);
  /// Readback::Later: the composites whose reads have finished, oldest first, in the order they were drawn;
  /// wait = true also waits for the rest (at the end of a run). At most 3 reads are in flight: a fourth
  /// composite() first waits for the oldest.
  std::vector<cv::Mat> takeComposites(bool wait);

  const gl::Texture& output() const { return output_; }
  /// The last composite read back now (RGB8), whatever the readback mode (a view that needs it on the CPU).
  cv::Mat readOutput() const;
  /// Draws the last composite into the default framebuffer (window backend), scaled to width x height.
  void present(int width, int height) const;

 private:
  int width_, height_;
  gl::Program program_;
  gl::Texture background_, delta_, output_;
  gl::Framebuffer framebuffer_;
  gl::VertexArray vao_;
  Readback readback_ = Readback::Now;
  struct Read {
    gl::Buffer pixels;  ///< GL_PIXEL_PACK_BUFFER target of the read
    GLsync fence = nullptr;
  };
  std::vector<Read> reads_;  ///< in flight, oldest first
  std::vector<gl::Buffer> spare_;
  std::vector<cv::Mat> ready_;  ///< finished reads not yet taken
  cv::Mat finish(Read& r, bool wait);
  /// Uploads the background and draws the merge with delta (the two composite() overloads' shared tail).
  cv::Mat merge(const cv::Mat& background, const gl::Texture& delta);
};

}  // namespace mrgi::compositor
