#pragma once
/// How the lights see the region that matters: the region, the lights worth rendering for it, each light's view
/// (and the objects' own), the RSM and shadow-map texels as read back, and the C++ twins of
/// lighting/direct_light.glsl's shadow tests.
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "gl/objects.h"
#include "lighting/scene.h"

namespace mrgi::lighting {

/// The region that matters for the virtual objects: an axis-aligned cube in the lighting world, centred on
/// the objects' bounding box, side = size factor x its largest edge (never below 1 mm). Light views are
/// fitted to it; volume techniques place their grids in it.
struct Region {
  cv::Vec3d origin{0, 0, 0};  ///< the corner with the smallest coordinates
  double side = 1.0;
  cv::Vec3d centre() const { return origin + cv::Vec3d::all(0.5 * side); }
  /// Radius of the bounding sphere.
  double radius() const { return 0.5 * std::sqrt(3.0) * side; }
};
Region fitRegion(const cv::Vec3d& lo, const cv::Vec3d& hi, double sizeFactor);

/// The most unshadowed irradiance `light` can give a point of the region's bounding sphere, whatever the
/// point's normal (W/m^2 per channel): a directional light's irradiance; a point light's intensity over the
/// squared distance to the sphere's nearest point; a spot's the same, or exactly 0 when its cone misses the
/// sphere. Infinite for a point or spot light inside the sphere. Bounds the light's share of everything the
/// objects change: their direct light, the shadow they cast (its receivers lie behind them from the light),
/// what they bounce.
cv::Vec3d irradianceBound(const SceneLight& light, const Region& region);
/// The lights worth rendering for the region, by index in `lights` (in order): the dimmest lights (by
/// irradianceBound, ascending) are left out for as long as, in every channel, the bounds of those left out
/// sum to at most `cutoff` of the sum over all lights with a finite bound plus the ambient's irradiance
/// (pi x ambient radiance). cutoff 0: every light. A light with an infinite bound is always kept.
std::vector<size_t> lightsThatMatter(const std::vector<SceneLight>& lights, const cv::Vec3d& ambientRadiance,
                                     const Region& region, double cutoff);

/// How one light sees the region: perspective for point/spot lights (frustum around the region's bounding
/// sphere), orthographic for directional ones (fitted to the region).
struct LightView {
  cv::Matx44d viewProj;
  double focalPixels = 0;  ///< perspective
  double texelArea = 0;    ///< orthographic, m^2
  double shadowBias = 0;   ///< metres
  /// The objects' shadow map: the same light fitted to the objects' bounding sphere (holding them alone).
  /// objectShadowBias < 0: none (a point light too close to the objects for one view; RSM^rho tests them).
  cv::Matx44d objectViewProj = cv::Matx44d::eye();
  double objectShadowBias = -1;  ///< metres
  /// Where the objects' bounding sphere begins seen from the light, in the shadow test's distance (along the
  /// direction for a directional light, from the light otherwise): a light with extent searches its soft
  /// shadow's blockers from there.
  double objectNear = 0;
  bool soft = false;  ///< the objects' shadow is soft (a light with extent among frame knob soft_shadow_lights)
};
LightView fitLightView(const SceneLight& light, const Region& region, int rsmSize);
/// Adds the objects' view to `view`: orthographic over the sphere (centre, radius) for a directional light,
/// a perspective frustum around it for a point or spot light (none when the light is within 1.05 radii).
void fitObjectView(LightView& view, const SceneLight& light, const cv::Vec3d& centre, double radius, int size);

/// RSM texels as read back from the GPU (CV_32FC4 each, size x size): world position (w = 1 where a surface
/// was seen), normal facing the light (w = object index + 1 on virtual surfaces, 0 on real ones), reflected flux
/// (albedo x flux through the texel, W), incident flux through the texel (W).
struct RsmTexels {
  cv::Mat position, normal, flux, direct;
};

/// One light's shadow maps as downloaded (CV_32FC4 world positions, w = 1 where a surface was seen):
/// RSM^mu, and either the objects' map or, where the light's view has none, RSM^rho (the other empty).
struct ShadowTexels {
  cv::Mat rho, mu, objects;
};

/// The GPU textures of one reflective shadow map (RGBA32F, size x size, nearest filtering).
struct Rsm {
  gl::Texture position, normal, flux, direct, depth;
  gl::Framebuffer fb;
};

/// C++ twin of lighting/direct_light.glsl: one shadow-map test (1 lit, 0 occluded; bias < 0: no map, lit),
/// a light's visibility with or without the objects, and a light's irradiance before shadowing.
float shadowTest(const cv::Mat& positions, const SceneLight& light, const cv::Matx44d& viewProj, double bias,
                 cv::Vec3d x, const cv::Vec3d& n);
/// direct_light.glsl's mapCoordinates: where p falls in a light's map ([0, 1]^2) through its view and projection;
/// nullopt behind the light or outside the map.
std::optional<cv::Vec2d> mapCoordinates(const cv::Matx44d& viewProj, const cv::Vec3d& p);

/// direct_light.glsl's smoothShadowTest: the map tested at the four texels around x's projection, weighed
/// bilinearly (a virtual surface's test of the real surfaces' map).
float smoothShadowTest(const cv::Mat& positions, const SceneLight& light, const cv::Matx44d& viewProj, double bias,
                       cv::Vec3d x, const cv::Vec3d& n);
/// direct_light.glsl's virtualVisibility: lightVisibility with the objects for a virtual surface (the shading
/// pass's virtual pixels), the real surfaces' map tested smoothly.
float virtualLightVisibility(const ShadowTexels& maps, const SceneLight& light, const LightView& view,
                             const cv::Vec3d& x, const cv::Vec3d& n, bool soft = true);
/// soft: the objects' soft shadow of a light with extent (the shading pass's; techniques' own passes take the
/// hard test of its centre).
float lightVisibility(const ShadowTexels& maps, const SceneLight& light, const LightView& view, bool withObjects,
                      const cv::Vec3d& x, const cv::Vec3d& n, bool soft = true);
/// The objects' soft shadow of a light with extent (SceneLight::extent > 0): the fraction of the light's disc
/// the objects leave visible from x. Percentage-closer soft shadows on the objects' map: the blockers' mean
/// distance from kSoftShadowSearchTaps taps over the widest penumbra the objects' sphere allows (none blocked:
/// lit; all: the umbra), then the penumbra's
/// width w = (d_self - d_blocker) tan a (a sphere lamp of radius r: (d_self - d_blocker) r / d_blocker) and the
/// fraction of kSoftShadowTaps taps over a disc of radius w, perpendicular to the light, that nothing nearer the
/// light covers. For a directional disc light and an occluder at one distance this is the disc's visible
/// fraction exactly (up to the taps); the taps lie on a Vogel spiral.
float softObjectsShadow(const cv::Mat& objects, const SceneLight& light, const LightView& view, cv::Vec3d x,
                        const cv::Vec3d& n);
constexpr int kSoftShadowTaps = 16, kSoftShadowSearchTaps = 8;
cv::Vec3d unshadowedIrradiance(const SceneLight& light, const cv::Vec3d& x, const cv::Vec3d& n);

}  // namespace mrgi::lighting
