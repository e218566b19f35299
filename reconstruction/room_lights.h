#pragma once
/// Lights from the room model: the fused radiance as seen from a point (the virtual objects' centre), split
/// into a few lights for what casts shadows and spherical harmonics for the rest (splitLights, the same
/// split as the fisheye path). Lights sit where the room's surfaces are (point lights at the bright
/// regions' radiance-weighted hit positions), so their shadows and falloff are right across the object.
///
/// Saturated surfaces (lamps, windows: every observation clipped) carry only a lower bound of their
/// radiance. Their radiance is that bound times a gain: set by the user, or estimated with the white-patch
/// assumption: the brightest surfaces the lamps light near the centre have albedo `whiteAlbedo`, i.e. the
/// 95th percentile over lit, unsaturated vertices of g_i = (pi L_i / whiteAlbedo - E_rest(n_i)) /
/// E_bound_i(n_i), where E_rest is the unsaturated environment's irradiance and E_bound the saturated
/// regions' at the bound. Never below 1: the clip level is a true lower bound.
#include <array>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "reconstruction/distant_lights.h"
#include "reconstruction/light_estimation.h"
#include "reconstruction/room_model.h"

namespace mrgi::reconstruction {

class MeshRays;

struct RoomLightOptions {
  int mapWidth = 256;  ///< lat-long environment map width (height = width / 2)
  LightSplitOptions split = [] {
    LightSplitOptions s;
    s.medianCut.count = 4;
    // Threshold 1, not a whole sphere's 2: with four lights, 2 leaves the lamp alone above it and the median
    // cut splits it into all four, the dominant one a third of its intensity (RoomLights.OneLamp…).
    s.threshold = 1.0;
    // A room's lamps keep their power: they cast the shadows (a common scale fitted to the irradiance put
    // tabletop-scan's lamp 17 % over its true irradiance).
    s.fitLightScale = false;
    return s;
  }();
  double saturatedGain = 0;     ///< > 0: the gain on saturated radiance; 0: estimated (white patch)
  double whiteAlbedo = 0.8;     ///< the white patch's albedo for the estimate
  double estimateRadius = 5.0;  ///< metres around the centre whose vertices inform the estimate (5: a room; its whitest
                                ///< lit surfaces are the white patch)
  double maxGain = 1e4;         ///< the estimate's ceiling
  /// Lamps and windows are compact: when saturated surfaces cover more than this fraction of the solid
  /// angle the room covers, they are lit surfaces clipped by an over-exposed camera, not emitters; the gain
  /// stays 1 (the bound) and `overExposed` says so.
  double maxSaturatedFraction = 0.05;
  /// A light whose region lies nearer than this to the centre (the surface the object stands on, lit) is
  /// kept as a directional light: a point light there would sit inside or against the object.
  double minPointDistance = 0.25;
  /// Search the room's shadow edges for a distant light the camera never saw (findDistantLight: the sun through a
  /// window), and light by it: its direction from the edges, its irradiance from the steps across them over the
  /// albedo the room's other light gives the shadowed side. Clipped surfaces it lights are then sunlit surfaces,
  /// not lamps.
  bool findDistant = false;
  DistantLightOptions distant;
  double distantAngularRadius = 0.0047;  ///< the light's half-angle (radians; the sun's)
};

struct RoomLight {
  bool point = true;              ///< false: no surface was hit in its region (directional)
  bool distant = false;           ///< found from the room's shadow edges (RoomLightOptions::findDistant), not seen
  cv::Vec3d position{0, 0, 0};    ///< lighting world (point)
  cv::Vec3d direction{0, 0, 0};   ///< unit, from the centre towards the light
  cv::Vec3d intensity{0, 0, 0};   ///< W/sr (point): power x distance^2
  cv::Vec3d irradiance{0, 0, 0};  ///< at the centre, normal incidence (normalIrradiance of the split's light)
  double angularRadius = 0;       ///< half-angle it is seen under from the centre (EstimatedLight::angularRadius)
  double saturatedFraction = 0;   ///< of its energy, from saturated surfaces
};

struct RoomLights {
  std::vector<RoomLight> lights;
  std::array<cv::Vec3d, 9> ambientSh{};  ///< remainder, lighting/sh.h convention, world directions
  /// The room seen from the centre without its saturated surfaces (lamps, windows) as SH bands 0-2, the
  /// directions it does not cover filled as in `environment`: what the surfaces alone send (lights listed
  /// apart from the room leave this).
  std::array<cv::Vec3d, 9> surfacesSh{};
  /// The same light as a lat-long radiance map (CV_32FC3, mapWidth x mapWidth / 2, saturated directions zero):
  /// what the objects hide of the surfaces across the caps they cover, sharper than three bands.
  cv::Mat surfaces;
  cv::Vec3d ambientRadiance{0, 0, 0};  ///< the remainder's mean radiance (SH band 0)
  double gain = 1;                     ///< applied to saturated radiance
  bool gainEstimated = false;
  int gainSamples = 0;                  ///< vertices the estimate used
  double saturatedFraction = 0;         ///< of the covered solid angle, saturated
  bool overExposed = false;             ///< saturatedFraction > maxSaturatedFraction: no estimate
  double coverage = 0;                  ///< solid-angle fraction of the sphere that hit the room
  cv::Mat environment;                  ///< CV_32FC3 lat-long radiance after the gain (row 0: +z)
  LightSplit split;                     ///< the split itself (its lights' directions are world)
  std::optional<DistantLight> distant;  ///< the light found from the shadow edges (also among `lights`)
  size_t sunlitClipped = 0;             ///< clipped vertices it lights (taken as surfaces, not lamps)
  /// Clipped vertices of wide patches a lamp's clipped body lights (a ceiling around a lamp below it): taken as
  /// surfaces, not lamps.
  size_t lampLitClipped = 0;
};

/// The room's lat-long directions and pixel solid angles (row v: polar angle from +z; column u: azimuth
/// from +x towards +y), in the FisheyeRays form splitLights takes.
FisheyeRays latLongRays(int width);

/// Throws std::invalid_argument for an empty mesh or options out of range. `rays`: rays against `room` itself,
/// when the caller has them (else they are built here).
RoomLights estimateRoomLights(const RoomMesh& room, const cv::Vec3d& centre, const RoomLightOptions& options = {},
                              const MeshRays* rays = nullptr);

/// The room's albedo under its own lights (`lights`, as seen from `centre`: a lamp's size from its angular radius
/// there) and the light it sends itself (its bounce; what it does not cover at the lights' mean ambient), as the
/// room's preview shows it and the distant light is measured against. `rays`: against `room`.
RoomAlbedo albedoUnderRoomLights(const RoomMesh& room, const RoomLights& lights, const cv::Vec3d& centre,
                                 const MeshRays& rays);

/// The distant light found from the room's shadow edges (RoomLights::distant) as summary.json and room-lights
/// --json give it: towards, irradiance (and which channels only bound it), its edges' agreement and count, the
/// share of the room it lights, the clipped vertices it lights; null when none was found.
nlohmann::json distantLightFacts(const RoomLights& lights);

}  // namespace mrgi::reconstruction
