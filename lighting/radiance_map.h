#pragma once
/// A radiance map over every direction, sharper than the SH bands 0-2 the ambient carries: a lat-long image
/// (row v: polar angle from +z over [v, v + 1) pi / H; column u: azimuth from +x towards +y over
/// [u, u + 1) 2 pi / W, as reconstruction::latLongRays) with its box-filtered levels. What the objects hide of a
/// room lies in the cap each one covers, tens of degrees wide beside it; three SH bands blur a bright wall or
/// ceiling across the whole sphere. The shading pass samples the same levels the same way
/// (lighting/radiance_map.glsl, a texture with GL_LINEAR_MIPMAP_LINEAR, the azimuth repeating, the polar angle
/// clamped); this is its C++ twin.
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

namespace mrgi::lighting {

class RadianceMap {
 public:
  /// `latLong`: CV_32FC3 or CV_64FC3, width even and twice the height, at least 8 x 4; negative or non-finite
  /// radiance throws std::invalid_argument (the map is built by the caller: a room seen from the objects).
  explicit RadianceMap(const cv::Mat& latLong);
  /// Level 0 (the map itself) and each next level a 2 x 2 (at the last ones 2 x 1) mean of the one before,
  /// down to 1 x 1. CV_32FC3.
  const std::vector<cv::Mat>& levels() const { return levels_; }
  int width() const { return levels_.front().cols; }
  int height() const { return levels_.front().rows; }
  float maxLevel() const { return static_cast<float>(levels_.size() - 1); }
  /// The radiance arriving from unit direction w (towards the scene), bilinear within a level and linear
  /// between the two levels about `lod` (clamped to [0, maxLevel()]), as GL's textureLod.
  cv::Vec3f sample(const cv::Vec3f& w, float lod) const;
  /// The solid angle of a level-0 texel at the equator (sr).
  float texelSolidAngle() const;
  /// The level whose texels at the equator each cover `solidAngle` (sr); 0 below level 0's texel.
  float lodFor(float solidAngle) const;
  /// How many directions capMean reads in a cap (1 - cos alpha given): one per level-0 texel it covers, 1 to
  /// kCapSamples.
  int capSamples(float oneMinusCosAlpha) const;
  /// The mean radiance over the cap of half-angle alpha about unit w (1 - cos alpha given, without cancellation
  /// for a tiny cap), each direction weighted by its cosine about n, from capSamples() equal-solid-angle
  /// directions of the cap, each read at the level of a quarter of its share of the cap. Directions under n's
  /// horizon weigh nothing; when all do, the radiance along w.
  cv::Vec3f capMean(const cv::Vec3f& w, float oneMinusCosAlpha, const cv::Vec3f& n) const;
  /// The most directions capMean reads in a cap: exact for a cap of uniform radiance, within 1.5 % for a smooth sky
  /// and 3 % for a cap of 30 degrees or more that a bright edge crosses (RadianceMap tests); 16 directions read 3 %
  /// over the path tracer's shadow of a sphere beside it, 32 within its noise (ObjectShadow.UnderARoom...).
  static constexpr int kCapSamples = 32;

 private:
  std::vector<cv::Mat> levels_;
};

}  // namespace mrgi::lighting
