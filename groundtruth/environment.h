#pragma once
/// An HDR environment (equirectangular, linear radiance) as a light of the path tracer: looked up by
/// direction and importance-sampled in proportion to luminance x sin(theta), so a sun of 10^4 that covers a
/// few texels is found by next-event estimation instead of by chance.
///
/// Mapping (world y up): theta = acos(d.y) runs down the rows (row 0 = straight up), phi = atan2(d.x, -d.z)
/// runs along the columns (u = 0.5 at -z). Radiance is piecewise constant over texels, the sampling pdf too.
#include <opencv2/core.hpp>
#include <vector>

namespace mrgi::groundtruth {

class EnvironmentMap {
 public:
  /// radiance: CV_32FC3 linear RGB, width = 2 x height; non-finite and negative values become 0. Each
  /// texel is multiplied by `scale`.
  explicit EnvironmentMap(const cv::Mat& radiance, float scale = 1.f);

  int width() const { return image_.cols; }
  int height() const { return image_.rows; }
  const cv::Mat& image() const { return image_; }

  /// (u, v) in [0, 1)^2 of a unit direction, and back (texel centres: u = (x + 0.5) / W).
  static cv::Vec2f uvOf(const cv::Vec3f& d);
  static cv::Vec3f directionOf(float u, float v);

  /// Radiance arriving from direction d (nearest texel).
  cv::Vec3f radiance(const cv::Vec3f& d) const;

  struct Sample {
    cv::Vec3f direction;
    cv::Vec3f radiance;
    float pdf = 0;  ///< per steradian
  };
  /// A direction drawn with pdf proportional to luminance x sin(theta) (texel by the tables, uniform in
  /// (u, v) within it); u1, u2, u3 uniform in [0, 1). pdf 0 for a black map.
  Sample sample(float u1, float u2, float u3) const;
  /// The pdf (per steradian) sample() draws d with.
  float pdf(const cv::Vec3f& d) const;
  /// Total power weight: integral of luminance over the sphere (W/m^2 of a unit sphere's irradiance sum).
  double integral() const { return integral_; }

 private:
  cv::Mat image_;
  std::vector<float> rowCdf_;    ///< height + 1 entries, 0 .. 1
  std::vector<float> colCdf_;    ///< height x (width + 1)
  std::vector<float> texelPdf_;  ///< per texel: probability of choosing it
  double integral_ = 0;
};

}  // namespace mrgi::groundtruth
