#pragma once
/// Technique outputs at a reduced resolution (the frame knob `render_scale`), brought back to the frame's
/// pixels by joint bilateral upsampling in the shading pass (lighting/upsample.glsl is the GPU twin).
///
/// The reduced G-buffer takes, per block of factor x factor frame pixels, the values of one of them (the
/// pixel at factor / 2 into the block on each axis, `reducedSource`), so every reduced texel is an exact
/// sample of the frame's surfaces. A frame pixel p takes the four reduced texels around it with bilinear
/// weights in the frame's pixel grid, each multiplied by how much its surface is p's:
///   w = [same surface class] x exp(-(s / 0.3)^2) x max(n_p . n_q, 0)^8,
/// the class being real or which virtual object (the G-buffer normal's w), s = |n_p . (x_q - x_p)| / |x_q - x_p|
/// the sine of the angle the offset to the texel's surface point leaves p's tangent plane at (0 along one
/// smooth surface, near 1 across a depth step: scale-free, so it needs no camera or units), n the unit normals.
/// Where those four give no weight (a surface narrower than a block: a thin leg, a gap between objects),
/// the best single texel of the 4 x 4 around it by the same surface weight stands in; none: zero. A smooth
/// field comes back within bilinear interpolation's error over `factor` pixels; an edge between surfaces keeps
/// each side's own values.
#include <opencv2/core.hpp>

namespace mrgi::lighting {

/// Reduced size of a frame side of `size` pixels at 1/factor.
inline int reducedSize(int size, int factor) { return (size + factor - 1) / factor; }
/// The frame pixel (one axis) reduced texel i takes its surface from.
inline int reducedSource(int i, int factor, int size) {
  const int p = i * factor + factor / 2;
  return p < size ? p : size - 1;
}
/// The integer divisor of the frame knob `render_scale` (1 / scale, rounded, 1..4).
int renderFactor(double renderScale);

/// How much reduced texel q's surface is frame pixel p's (see above), 0..1. p, q: G-buffer position (xyz
/// lighting world, w = 1 where a surface was seen) and normal (xyz unit, w = object index + 1, 0 real).
float upsampleWeight(const cv::Vec4f& positionP, const cv::Vec4f& normalP, const cv::Vec4f& positionQ,
                     const cv::Vec4f& normalQ);

/// A G-buffer channel (CV_32FC4, the frame's size) at 1/factor: each texel the channel at its source pixel.
cv::Mat reduceGBuffer(const cv::Mat& channel, int factor);

/// Frame pixel (x, y)'s value of `value` (CV_32FC4, the reduced size; rgb used) given the reduced G-buffer
/// (`lowPosition`, `lowNormal`) and the pixel's own position and normal. Zero where no surface was seen.
cv::Vec3f upsampleAt(const cv::Mat& value, const cv::Mat& lowPosition, const cv::Mat& lowNormal, int factor, int x,
                     int y, const cv::Vec4f& position, const cv::Vec4f& normal);

/// upsampleAt over every frame pixel of `position` / `normal` (CV_32FC4, the frame's size): CV_32FC4, a = 1
/// where a surface was seen.
cv::Mat upsample(const cv::Mat& value, const cv::Mat& lowPosition, const cv::Mat& lowNormal, const cv::Mat& position,
                 const cv::Mat& normal, int factor);

}  // namespace mrgi::lighting
