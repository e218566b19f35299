#pragma once
/// Light estimation from a calibrated fisheye image (shared/notes/algorithms.md §8): per-pixel directions
/// and solid angles through OpenCV's fisheye model (equidistant / Kannala-Brandt), and median cut
/// (Debevec 2005) on the solid-angle-weighted luminance with summed-area tables in double, optionally
/// with the variance-minimising split (Viriyothai & Debevec 2009) and an energy-concentration criterion
/// choosing the number of lights.
///
/// Units: the image holds linear radiance L (any consistent unit); a light's `power` is the region's
/// sum of L * dOmega per RGB channel, i.e. the irradiance it delivers at normal incidence, so that
/// E(n) = sum_i power_i <n, direction_i>+ approximates the integral of L <n, w>+ dw over the view.
#include <array>
#include <opencv2/core.hpp>
#include <vector>

#include "capture/types.h"

namespace mrgi::reconstruction {

/// Per-pixel geometry of a calibrated fisheye image.
struct FisheyeRays {
  cv::Mat directions;  ///< CV_32FC3 unit vectors in the fisheye camera frame (x right, y down, z forward)
  cv::Mat solidAngle;  ///< CV_64FC1 steradians subtended by each pixel; 0 outside the model's valid field
  double totalSolidAngle = 0;
};

/// Inverts the Kannala-Brandt model per pixel (Newton on theta_d(theta)); pixels whose four corners are
/// not all inside maxThetaRad of the axis (or where the model stops being monotonic) get solid angle 0.
/// Pixel solid angles are exact spherical quadrilaterals between the pixel-corner rays.
FisheyeRays fisheyeRays(const capture::FisheyeCalibration& calibration, double maxThetaRad = CV_PI * 0.6);

/// Angle of the ray through pixel (u, v) from the optical axis and its unit direction; false where the
/// model is not invertible.
bool fisheyePixelToRay(const capture::FisheyeCalibration& c, double u, double v, cv::Vec3d& direction);

/// Linear radiance from a fisheye frame: 8-bit sRGB is decoded, floats are taken as linear; divided by
/// exposure; NaN/negative -> 0. `saturated` (optional, CV_8UC1 255) flags 8-bit pixels with any channel
/// >= 250 and float pixels >= saturationLevel.
cv::Mat linearRadiance(const cv::Mat& image, double exposure = 1.0, cv::Mat* saturated = nullptr,
                       double saturationLevel = 1e30);

struct EstimatedLight {
  cv::Vec3d direction;    ///< unit, towards the light, fisheye camera frame (or world after lightsToWorld)
  cv::Vec3d power;        ///< RGB, sum of L * dOmega over the region
  double solidAngle = 0;  ///< steradians covered by the region
  cv::Rect region;        ///< pixels of the fisheye image
  /// Half-angle (radians) of the disc of uniform radiance the light stands for (0: a point direction); its
  /// irradiance at angle theta is normalIrradiance * capture::capCosine(cos theta, sin angularRadius), which
  /// keeps the part of a region straddling a surface's horizon that is still above it.
  double angularRadius = 0;
};
/// Irradiance at normal incidence of a light holding `power` over a disc of its half-angle: power (1 + cos a) / 2.
inline cv::Vec3d normalIrradiance(const EstimatedLight& l) { return l.power * (0.5 * (1 + std::cos(l.angularRadius))); }
/// The largest half-angle a light is given (80 degrees): wider is not a light.
constexpr double kMaxLightAngularRadius = 80 * CV_PI / 180;

struct MedianCutOptions {
  int count = 16;              ///< number of lights (2^k gives classic median cut; others split the strongest first)
  bool varianceSplit = false;  ///< choose the cut minimising the energy-weighted spatial variance of both halves
  /// count <= 0: choose the number of lights. A region is split while its energy-weighted angular spread
  /// exceeds maxSpreadRad and it holds more than minEnergyFraction of the total, up to maxCount.
  double maxSpreadRad = 0.15;
  double minEnergyFraction = 0.002;
  int maxCount = 256;
};

/// Median cut on radiance (CV_32FC3 linear, same size as rays). Total power of the lights equals the
/// image's total sum of L * dOmega (up to double round-off). Zero-energy regions still give a light
/// (power 0, direction = the region's solid-angle centroid).
std::vector<EstimatedLight> medianCut(const cv::Mat& radiance, const FisheyeRays& rays,
                                      const MedianCutOptions& options = {});

/// Lights for what casts shadows, spherical harmonics for the rest. The radiance is split per pixel at a
/// luminance threshold T = `threshold` x the image's solid-angle-weighted mean luminance: the part above T
/// (lamps, windows, the sun: compact and bright) goes to the median cut's lights, the part up to T (the dim
/// ceiling, walls, sky) is projected onto SH bands 0-2. Equal-energy median cut alone gives a whole dim
/// region one light, which is far off for normals facing away from the bright parts.
struct LightSplitOptions {
  /// The bright part is cut with the variance-minimising split (equal energy leaves a large window to a few
  /// lights at its centre, off for normals at grazing angles to it).
  MedianCutOptions medianCut = [] {
    MedianCutOptions m;
    m.varianceSplit = true;
    return m;
  }();
  /// 0: by the field. A whole sphere (a probe, the room seen from the object) takes 2, measured best over
  /// 0.5-8 with the irradiance fit on the five Blender worlds and three Radiance probes; a fisheye's partial
  /// field takes 1, as measured on the Blender worlds seen through it (2 left its near-horizon normals
  /// 1.5-3 points further off).
  double threshold = 0;
  /// The remainder's SH bands 1-2 fitted to the image's irradiance (fitIrradiance): at `fitNormals` normals
  /// over the sphere (a Fibonacci lattice), the lights' irradiance plus the SH's clamped-cosine irradiance is
  /// matched to the image's, each normal weighed by 1 / the image's irradiance there squared, then Lawson's
  /// reweighting towards the smallest largest error; band 0 takes what the lights leave of the image's total,
  /// so lights and remainder still hold it. The projection alone is the best SH of the radiance, not of the
  /// irradiance: with point lights the dark side of a map with a bright window or sky came out 14-34 % off
  /// (`LightSplit.EveryNormalOfAWholeSphereMap…`), fitted 1.4-8.9 %, with the lights' extents and their
  /// common scale 1.2-4.5 %.
  bool fitIrradiance = true;
  int fitNormals = 256;
  /// Each light's half-angle (EstimatedLight::angularRadius) as this multiple of the half-angle of the disc
  /// with its region's mean resultant length R (cos a = 2 R - 1; bright energy weighed); 0: point
  /// directions. Measured over 0-1 with the irradiance fit on the five Blender worlds and three Radiance
  /// probes as whole spheres: 0.75 (worst normal 4.3 %; 0.5: 4.6 %, 1: 5.6 %, points: 8.9 %).
  double lightExtent = 0.75;
  /// The irradiance fit also scales the lights' powers by one common factor in [0.5, 2] (band 0 takes the
  /// difference, so the total holds): the lights then stand for more or less of the bright regions than their
  /// own energy, as the remainder's three bands need (whole-sphere maps: worst normal 4.5 %; with the extents but
  /// without the scale, uffizi's 8.2 %). Off where a light's own power matters more than the irradiance (a room's
  /// lamps).
  bool fitLightScale = true;
};
struct LightSplit {
  std::vector<EstimatedLight> lights;
  /// The remainder's radiance as SH, 9 RGB coefficients in the convention of lighting/sh.h (index l(l+1)+m,
  /// no Condon-Shortley phase), directions in the fisheye camera frame; its irradiance at a normal is
  /// sum_lm A_l c_lm y_lm(n) with A = (pi, 2 pi / 3, pi / 4). Lights and remainder hold the image's total.
  std::array<cv::Vec3d, 9> ambientSh{};
  /// The remainder pixel by pixel: the image with every pixel brighter than T scaled down to luminance T (the excess
  /// is the lights'). CV_32FC3, the image's size.
  cv::Mat remainder;
  double thresholdLuminance = 0;  ///< T
};
LightSplit splitLights(const cv::Mat& radiance, const FisheyeRays& rays, const LightSplitOptions& options = {});
/// The threshold multiple splitLights uses for this field (LightSplitOptions::threshold, or by the field when 0).
double splitThreshold(const LightSplitOptions& options, const FisheyeRays& rays);
/// Irradiance at unit normal n from the split: the lights' sum plus the remainder's SH irradiance.
cv::Vec3d irradianceFromSplit(const LightSplit& split, const cv::Vec3d& n);
/// The 9 real SH basis values of bands 0-2 at unit direction d (lighting/sh.h's convention).
std::array<double, 9> shBasis2(const cv::Vec3d& d);
/// Irradiance at unit normal n of a radiance given as SH bands 0-2: sum_lm A_l c_lm y_lm(n),
/// A = (pi, 2 pi / 3, pi / 4).
cv::Vec3d shIrradiance(const std::array<cv::Vec3d, 9>& sh, const cv::Vec3d& n);
/// The same, each channel clamped at 0 (the shading pass's shAmbientIrradiance is its GPU twin).
cv::Vec3d ambientShIrradiance(const std::array<cv::Vec3d, 9>& sh, const cv::Vec3d& n);

/// Sum of L * dOmega over the valid field (the reference total for medianCut).
cv::Vec3d totalPower(const cv::Mat& radiance, const FisheyeRays& rays);

/// Lights rotated into the world by the fisheye camera's pose.
std::vector<EstimatedLight> lightsToWorld(std::vector<EstimatedLight> lights, const capture::Pose& T_world_fisheye);

/// Irradiance at a surface with unit normal n: from the lights, and by direct integration of the image.
cv::Vec3d irradianceFromLights(const std::vector<EstimatedLight>& lights, const cv::Vec3d& n);
cv::Vec3d irradianceFromImage(const cv::Mat& radiance, const FisheyeRays& rays, const cv::Vec3d& n);

/// Renders an equirectangular (lat-long) radiance map through the fisheye model: each pixel looks up the
/// map in direction R_world_fisheye * ray (world y up; map u = atan2(x, -z), v = acos(y)); bilinear.
cv::Mat renderFisheyeFromLatLong(const cv::Mat& latlong, const FisheyeRays& rays, const cv::Matx33d& R_world_fisheye);

}  // namespace mrgi::reconstruction
