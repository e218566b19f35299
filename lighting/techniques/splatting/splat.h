#pragma once
/// Splatting indirect illumination (shared/papers/001; algorithms.md §2 and §5) for mixed reality: the plain
/// C++ reference of the GPU passes.
///
/// Pixel lights. Every texel of a reflective shadow map is a pixel light (VPL) at x_p with normal n_p and
/// reflected flux Φ_p; its radiant intensity towards a unit direction ω is
///   diffuse  I_p(ω) = Φ_p / π <n_p, ω>₊                      (a Lambertian patch; algorithms.md §2)
///   glossy   I_p(ω) = Φ_p (P' + 1) / (2π) <r_p, ω>₊^P'  (<n_p, ω> > 0)
/// with r_p the light's mirror direction at the texel and Φ_p the flux the glossy lobe reflects (specular ×
/// the incident flux); the lobe is normalised, so it sends Φ_p out (less what falls below the surface).
/// Near the pixel light the exponent is widened: P'(d) = min(P, P d / a), a the widening distance, so the
/// lobe does not focus a singular spot onto a receiver that touches it (algorithms.md §5).
/// A receiver at x with normal n gets
///   E_p(x) = I_p(ω) <n, −ω>₊ / (d² + A_p / π),   ω = (x − x_p) / d, d = |x − x_p|
/// where A_p is the texel's surface footprint: the disc clamp of Kinect-VAL's form factor, so E stays below
/// Φ_p / A_p as d → 0 and equals I cos / d² far away.
///
/// Splat bounds. E_p ≤ B(α, r) = I_0 cos^n α / r² (α the angle to the lobe axis: n_p with n = 1 for a diffuse
/// light, r_p with n = P for a glossy one; I_0 the lobe's peak intensity), so outside the region
/// r(α) = sqrt(I_0 cos^n α / I_low) every receiver gets less than I_low. In units of R = sqrt(I_0 / I_low)
/// the region's outline is F(x) = x^{n/(n+2)} sqrt(1 − x^{4/(n+2)}) along the axis x ∈ [0, 1]; it lies in
/// the ellipse centred at c(n) = (n/(n+2))^{(n+2)/4} with half-height h(n) = F(c(n)) and half-width
/// max(c, 1 − c). A widened glossy lobe adds the ball of radius a around the light (inside it P' < P).
///
/// Importance sampling by hierarchical warping (§5): the importance map's pyramid of sums is descended from
/// its top; at each level the sample's y is warped into the top or bottom half, Φ_r = Φ_top / (Φ_top +
/// Φ_bottom), y' = y / Φ_r or (y − Φ_r) / (1 − Φ_r) (the paper's scaled form, same map), then x within the
/// chosen half (method A); the sample's weight is the product of 1/(2Φ) of each choice, i.e. 1 / (texels ×
/// pdf). The warped estimate (1/N) Σ f(t_s) texels w_s of Σ_t f_t is unbiased wherever the importance is
/// non-zero. Importance p = lum(Φ) (1 − AO) (1 + P): dark, occluded and diffuse texels get fewer samples
/// (AO: rsmOcclusion, from the RSM itself).
///
/// Mixed reality: the real-pixel delta is the splat of RSM^rho's lights minus RSM^mu's. Both are sampled at
/// the same texels with the same weights from one importance map that is non-zero only where the two RSMs
/// differ (the object, and the real surfaces it shadows), so identical texels cancel exactly and with no
/// virtual object the delta is exactly 0. The object's indirect light is the splat of RSM^rho's lights
/// (its own texels excluded: a surface does not light itself).
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "lighting/scene_file.h"

namespace mrgi::lighting::splat {

/// One pixel light as the GPU reads it (std430, 4 × vec4).
struct PixelLight {
  cv::Vec3f position;  ///< x_p, lighting world
  float area = 0;      ///< A_p, m² (the texel's footprint on the surface)
  cv::Vec3f normal;    ///< n_p, unit, facing the light
  float exponent = 0;  ///< P: 0 = diffuse, > 0 glossy about `axis`
  cv::Vec3f flux;      ///< Φ_p, W, times the sample's weight (negative for a subtracted light)
  float widen = 0;     ///< a, metres (glossy only; 0 = no widening)
  cv::Vec3f axis;      ///< r_p (glossy) or n_p (diffuse), unit
  float pad = 0;
};
static_assert(sizeof(PixelLight) == 64);

/// Peak radiant intensity per unit flux of the lobe: 1/π (diffuse) or (P + 1) / (2π).
float peakPerFlux(float exponent);
/// Exponent at distance d: min(P, P d / a) (P when a ≤ 0).
float widenedExponent(float exponent, float d, float widen);
/// Radiant intensity towards unit ω (W/sr), widened at distance d.
cv::Vec3f intensity(const PixelLight& l, const cv::Vec3f& w, float d);
/// Irradiance the light sends to the receiver (x, n), W/m²; 0 on the light itself (d = 0).
cv::Vec3f irradiance(const PixelLight& l, const cv::Vec3f& x, const cv::Vec3f& n);

/// The significant region's outline F(x) and the ellipse around it (units of R).
float outline(float x, float n);
struct Ellipse {
  float centre = 0, halfWidth = 0, halfHeight = 0;
};
Ellipse boundingEllipse(float n);
/// World-space box around a light's significant region for the cut-off I_low (W/m², luminance; > 0):
/// centre, three unit axes (the first along the lobe axis) and half extents; it holds the ellipsoid of
/// boundingEllipse() scaled by R = sqrt(I_0 / I_low) and, for a widened glossy lobe, the ball of radius a.
struct SplatBox {
  cv::Vec3f centre, axes[3];
  cv::Vec3f half{0, 0, 0};
};
SplatBox splatBox(const PixelLight& l, float iLow);
/// I_low of a light when it scales with the light: scale x lum|Phi| (the technique's splats; splat.vert).
float scaledILow(const PixelLight& l, float scale);
/// Whether x lies in the box.
bool insideBox(const SplatBox& b, const cv::Vec3f& x);
/// A far level's weight at x: 1 in the box, falling linearly to 0 at kBoxFade times its half extents beyond
/// its faces (splatFar cross-fades the levels with it: a face would otherwise step a far representative's
/// weight, a seam across the surfaces it crosses). The band lies outside the box, where the light is below
/// I_low: a fade inside it would hand light above I_low to the far levels, whose few representatives stand
/// for the other samples' lobes only on average (a glossy caustic moved 3 cm).
constexpr float kBoxFade = 0.04f;
float boxCoverage(const SplatBox& b, const cv::Vec3f& x);
/// The bounded splat: irradiance() where x lies in splatBox(l, iLow), 0 elsewhere.
cv::Vec3f splatIrradiance(const PixelLight& l, const cv::Vec3f& x, const cv::Vec3f& n, float iLow);

/// Far-field levels. A light's significant region at a fixed I_low cuts its faint, wide tail; the tail of a
/// diffuse light falls off slowly (the flux it puts on a plane beyond r falls as 1/r), so larger boxes pay
/// but cost their area. Level 0 splats every sample of a light over splatBox(l, iLow); level k >= 1 splats only
/// the first farSamples(n, k) = ceil(n / 16^k) of the light's n samples over the shell splatBox(l, iLow / 16^k)
/// minus level k - 1's box, weighted n / farSamples(n, k). The shells are cross-faded: level k weighs a point
/// by F_k - F_{k-1} (F_k = boxCoverage of its box below the outermost level, the box's indicator at it,
/// F_{-1} = 0), which telescope to the outermost box's indicator, so a far representative's weight ramps in
/// as its exact splat ramps out instead of stepping n / farSamples(n, 1) times at its level-0 box (a seam
/// across the object); the splats below the outermost level cover their band. The first samples of a light are a
/// contiguous run of the R2 sequence (themselves low-discrepancy), and a level's weighted subset estimates the same sum
/// as all n (their weights already hold 1/n), so over the levels each sample's expected splat is the bounded splat over
/// the outermost box, which reaches 4^k times as far as level 0's, for about k + 1 times level 0's cost (16x the
/// area for 1/16 of the lights). GLSL twin in splat.vert / splat.frag.
constexpr int kFarStride = 16;  ///< samples per far light, and the ratio of I_low between levels
/// Samples of a light of n that splat at far level k (k = 0: all n).
int farSamples(int count, int level);
/// The weight of far level k: n / farSamples(n, k) (1 at level 0; 0 when the light has no samples).
float farWeight(int count, int level);
/// Sample `sample` (0-based within its light of `count` samples) splatted over `levels` far levels at (x, n):
/// level 0's bounded splat plus each far level's shell, weighted.
cv::Vec3f splatFar(const PixelLight& l, const cv::Vec3f& x, const cv::Vec3f& n, float iLow, int sample, int count,
                   int levels);

/// Sum pyramid of an importance map (square, side a power of two; level 0 = the map).
struct Pyramid {
  std::vector<cv::Mat> levels;  ///< CV_64F, level k side = side >> k; the last is 1 x 1
};
/// Builds the pyramid of a CV_32F or CV_64F map padded with zeros to the next power-of-two square.
Pyramid buildPyramid(const cv::Mat& importance);
/// A warped sample: the texel and its weight 1 / (texels × pdf) (texels = side² of level 0); weight 0 and
/// texel (-1, -1) when the map is all zero.
struct Warped {
  cv::Point texel{-1, -1};
  double weight = 0;
};
Warped warp(const Pyramid& p, cv::Vec2d u);
/// The i-th of n sample points in [0, 1)²: the R2 low-discrepancy sequence (deterministic; GPU twin).
cv::Vec2d samplePoint(int i);
/// The warped estimate of Σ f over the map's texels with n samples: (1/n) Σ f(t_s) texels w_s.
double warpedEstimate(const Pyramid& p, const cv::Mat& f, int n);

/// A texel's footprint on its surface (m²): across the beam direct / beam (the beam's brightest channel:
/// W/m² at the texel, intensity / d² or the sun's irradiance) over cos θ clamped at 0.1 (splat_texel.glsl).
float texelArea(const cv::Vec3f& direct, const cv::Vec3f& beam, float cosine);
/// The ambient's bounce off a texel, the share one light's RSM carries (each light's RSM tiles the surfaces it
/// sees once, so with L lights each carries 1 / L): albedo E_ambient A share, albedo = flux / direct per
/// channel (clamped to [0, 1]; 0 without direct light). The RSMs hold only the lights' direct bounce; outdoors
/// the sky's bounce off the table is most of what the object receives.
cv::Vec3f ambientFlux(const cv::Vec3f& flux, const cv::Vec3f& direct, const cv::Vec3f& eAmbient, float area,
                      float share);

/// The ambient occlusion of an RSM texel (CV_32FC4 world positions, w = 1 where a surface was seen, and
/// normals), from the RSM itself as screen-space AO from the light: of 16 neighbours (8 directions at 2 and 5
/// texels) each that lies within `radius` metres of the texel's point and above its tangent plane (more than
/// asin 0.2 ≈ 11.5° up) occludes 1 − d / radius; AO = their sum / 16, at most 0.9, so that no lit texel drops
/// out of the sampling (the warped estimate stays unbiased). 0 for an empty texel. GLSL twin in
/// splat_importance.comp.
float rsmOcclusion(const cv::Mat& position, const cv::Mat& normal, cv::Point t, float radius);

/// The ambient a surface patch of area A blocks, seen from in front of it, as a negative Lambertian light:
/// −π L_ambient(−n) A share (L the ambient's radiance looking along −n, the sky behind the patch). Summed
/// with the light the patch sends, a receiver's irradiance trades the sky behind the patch for the patch:
/// on the object, the ambient the real surfaces hide; on real surfaces, the ambient the object hides.
cv::Vec3f occluderFlux(const cv::Vec3f& ambientBehind, float area, float share);

/// Importance of one texel: lum(Φ) (1 − AO) (1 + P), 0 for non-finite or negative input.
double importance(const cv::Vec3f& flux, float ao, float exponent);

/// Σ_p E_p at (x, n), without bounds (the gather the splats approximate).
cv::Vec3f gather(const std::vector<PixelLight>& lights, const cv::Vec3f& x, const cv::Vec3f& n);
/// Σ_p E_p at (x, n), each light only within its splat box.
cv::Vec3f gatherBounded(const std::vector<PixelLight>& lights, const cv::Vec3f& x, const cv::Vec3f& n, float iLow);

}  // namespace mrgi::lighting::splat
