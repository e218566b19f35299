#pragma once
/// Imperfect volumes (shared/papers/004; algorithms.md §7) for mixed reality: the plain C++ reference of the
/// GPU passes (iv_voxelise.comp, iv_gather.comp, iv_readout.frag).
///
/// Points on the scene's surfaces (N random points per triangle, uniform barycentric) mark the voxels of a
/// grid around the virtual objects occupied, in two versions: rho (real + virtual) and mu (real only), as DLPV
/// does. Each occupied voxel keeps the light its surface sends out: the mean reflected radiance of its points
/// (the technique lights them with the direct light and the unoccluded ambient) and their summed normal — a Lambertian
/// surface element, seen from its front at the same radiance from every direction. (Two SH bands, as the paper stores
/// it, make the same surface 25 % too bright seen head-on and leak 7 % of its flux backwards.)
///
/// Per voxel near a surface, N rays over the sphere (a spherical Fibonacci set, the same for every voxel)
/// start past the voxel's own bounding sphere ((sqrt 3 / 2) voxel) and march one voxel per step to the first
/// occupied voxel or the border. A hit within `range` returns that voxel's exitant radiance towards the ray's
/// origin; everything else returns the ambient radiance of the ray's direction (the room or the sky beyond
/// what the volume holds). In rho the objects hide nothing: a ray goes on through their voxels to the first
/// voxel with real points (its real points' light as the objects leave them lit) and adds the light the first
/// object voxel on its way reflects of the lights (the ambient the objects hide from real surfaces, and what
/// they reflect of it, are the shading pass's: lighting/object_shadow.h). The incident radiance is stored as SH of
/// `bands` bands per colour channel (convention of lighting/sh.h): c_i = 4 pi / N sum_j L(w_j) y_i(w_j). Further
/// bounces: occupied voxels reflect the previous bounce's incident light (albedo / pi times its irradiance about their
/// normal) and the rays are cast again; the bounces add up.
///
/// Reconstruction at a surface point x with normal n: p = x + n voxel / 2; of the 27 voxels around p, the
/// six nearest to p whose centre lies in front of x (cos theta > 0, theta between n and centre - x), other
/// than the voxel holding x and other occupied voxels (their rays start inside the surface and see past it:
/// under a lid they would see the sky above it), weighted by cos theta; E(n) = sum_l pi s_l(1) c_lm y_lm(n)
/// (the clamped cosine). Occupied voxels are used only when no free one qualifies.
///
/// The real-pixel delta is E^rho - E^mu (what the object adds: the lights' bounce off it, and what its shadow
/// takes from the real surfaces' bounce); the virtual object's is E^mu minus the unoccluded ambient the shading
/// pass already adds.
#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <utility>
#include <vector>

#include "lighting/ambient.h"

namespace mrgi::lighting::iv {

/// Axis-aligned in the lighting world; voxel (i, j, k) spans origin + voxel * [i, i+1] x [j, j+1] x [k, k+1].
struct Grid {
  cv::Vec3d origin{0, 0, 0};
  double voxel = 1.0;
  int resolution = 32;
  size_t count() const { return size_t(resolution) * resolution * resolution; }
  size_t index(int i, int j, int k) const { return (size_t(k) * resolution + j) * resolution + i; }
  cv::Vec3d centre(int i, int j, int k) const { return origin + voxel * cv::Vec3d(i + 0.5, j + 0.5, k + 0.5); }
  /// The voxel holding p; false outside the grid. Computed in float, as the GPU passes do.
  bool voxelOf(const cv::Vec3d& p, cv::Vec3i& v) const;
};

/// A point on a surface: its reflected direct radiance in both versions of the scene (mu: without the
/// virtual objects, which may shadow it in rho).
struct Point {
  cv::Vec3f position, normal;                           ///< lighting world, unit normal
  cv::Vec3f albedo{0.5f, 0.5f, 0.5f};                   ///< linear
  cv::Vec3f radianceRho{0, 0, 0}, radianceMu{0, 0, 0};  ///< W/m^2/sr, Lambertian
  /// A virtual point's radiance from the lights alone (radianceRho less the ambient): what it sends the real
  /// surfaces in rho.
  cv::Vec3f radianceLights{0, 0, 0};
  bool isVirtual = false;
};

/// Uniform point in the triangle (a, b, c) for r1, r2 in [0, 1): (1 - sqrt r1) a + (1 - r2) sqrt r1 b + r2 sqrt r1 c.
cv::Vec3f trianglePoint(const cv::Vec3f& a, const cv::Vec3f& b, const cv::Vec3f& c, float r1, float r2);
/// The j-th of n sample pairs (r1, r2) of a triangle: a 2D Halton set (bases 2, 3) offset per triangle by
/// a hash of its index, so neighbouring triangles do not repeat one pattern. Deterministic (GPU twin).
cv::Vec2f sampleOf(uint32_t triangle, int j);

/// N unit directions over the sphere: the spherical Fibonacci set (equal areas, stratified).
std::vector<cv::Vec3f> rayDirections(int n);

enum Occupancy : uint8_t { kEmpty = 0, kReal = 1, kVirtual = 2 };

/// Occupied voxels and the light their surfaces send out.
struct Volume {
  Grid grid;
  std::vector<uint8_t> occupancy;  ///< Occupancy bits per voxel
  /// Per voxel, rgb = mean exitant radiance of its points (W/m^2/sr), w = their count; normals = the sum of
  /// their unit normals (xyz). Rho over all points, mu over the real ones.
  std::vector<cv::Vec4f> exitantRho, exitantMu, normalRho, normalMu;
  std::vector<cv::Vec3f> albedoRho, albedoMu;  ///< mean albedo of the points
  /// rgb: mean exitant radiance of the real points as the objects leave them lit (their radianceRho: the
  /// table in the object's shadow is dark), the light the object's own rays see on real surfaces.
  std::vector<cv::Vec4f> exitantMuLit;
  /// rgb: mean radianceLights of the virtual points, w = their count (their normals' sum: normalRho - normalMu).
  std::vector<cv::Vec4f> exitantVirtual;
  explicit Volume(const Grid& g = {});
  bool occupied(size_t v, bool rho) const { return rho ? occupancy[v] != kEmpty : (occupancy[v] & kReal) != 0; }
};

/// Marks each point's voxel (points outside the grid are dropped) and accumulates its light.
Volume voxelise(const Grid& grid, const std::vector<Point>& points);

/// The radiance the volume does not hold: the shading pass's ambient (lighting/ambient.h; radiance(w) of
/// direction w towards the scene).
using Ambient = lighting::Ambient;

struct Options {
  int rays = 64;            ///< per voxel, 1..1024
  int bands = 3;            ///< SH bands of the incident radiance, 1..8
  double range = 0.3;       ///< metres: a hit farther than this returns the ambient
  int bounces = 1;          ///< 0: ambient occlusion only (no light from the volume's surfaces), up to 3
  bool everyVoxel = false;  ///< cast from every voxel, not only near surfaces (debug slices, tests)
};

/// The gathered light of one scene version.
struct Incident {
  int bands = 0;
  std::vector<uint8_t> computed;  ///< voxels whose rays were cast (near a surface)
  std::vector<float> sh;          ///< voxels x 3 channels x bands^2: incident radiance (ambient + bounces)
  std::vector<float> occlusion;   ///< voxels: fraction of rays that hit within range (ambient occlusion)
  /// Per voxel: what its surface reflects of bounces 1 .. B-1 (zero for one bounce); with the direct light
  /// it sends, what a surface point's own rays see when they hit it.
  std::vector<cv::Vec3f> reflectedSum;
  const float* at(size_t v) const { return sh.data() + v * 3 * size_t(bands) * bands; }
};

/// Voxels whose rays are needed: those within one voxel (26-neighbourhood) of an occupied one (non-zero in
/// `occupied`, one entry per voxel; a Volume's occupancy: either version), where reconstruction reads.
std::vector<uint8_t> neededVoxels(const Grid& grid, const std::vector<uint8_t>& occupied);

/// Casts the rays of every needed voxel for the rho (real points as the objects leave them lit, the objects
/// lending their reflection of the lights and hiding nothing) or mu (real only) scene.
Incident gather(const Volume& volume, bool rho, const Options& options, const Ambient& ambient);

/// A ray from voxel centre `from` (past its bounding sphere, one voxel per step, until it leaves the grid): the
/// first voxel with real points (-1: none) and the first with virtual points up to it (-1: none; in rho the
/// objects hide nothing, they add their light), each with its march distance (from the voxel's centre).
struct SurfaceHits {
  int64_t real = -1, object = -1;
  float realDistance = 0, objectDistance = 0;
};
SurfaceHits marchSurfaces(const Volume& volume, const cv::Vec3i& from, const cv::Vec3f& direction);

/// The first occupied voxel along a ray from surface point x: samples at (k + 1/2) voxel along the ray,
/// x's own voxel skipped (its surface is x's own); -1 when the ray leaves the grid. `distance` gets the march
/// distance of the hit;
/// `exit` gets the distance of the first sample outside the grid when it leaves.
int64_t marchFromPoint(const Volume& volume, bool rho, const cv::Vec3f& x, const cv::Vec3f& direction,
                       float* distance = nullptr, float* exit = nullptr);

/// The coarser grid the object's own rays continue in once they leave the region's grid (knob
/// outer_resolution): centred on `inner`, its side the inner side + 2 `range` (whatever a ray from inside the
/// inner grid can reach within range), `resolution` voxels per axis. It holds the real points outside the inner
/// grid only (the mu scene: a ray from an object is not blocked by the objects).
Grid outerGrid(const Grid& inner, double range, int resolution);
/// A ray continued in the outer volume from distance `from` (where it left the inner grid): samples at
/// from + k outer voxels, x's own outer voxel skipped, the first occupied one (real points); -1 when it
/// leaves the outer grid. `distance` as marchFromPoint().
int64_t marchOuter(const Volume& outer, const cv::Vec3f& x, const cv::Vec3f& direction, float from,
                   float* distance = nullptr);
/// Per voxel with real points: the ambient irradiance the virtual objects hide from its surface (W/m^2),
/// sum over the rays of `dirs` in front of its mean real normal of L_ambient cos theta 4 pi / N, for rays
/// marched through the rho occupancy (as the gather: past the voxel's bounding sphere) whose first hit
/// within range is a voxel holding a virtual point. The real points' light is injected with the unoccluded
/// ambient; under the object that is far too bright outdoors (the sky is most of the ground's light there),
/// so the light the object's own rays see on real surfaces is exitantMuLit - albedoMu / pi x this.
std::vector<cv::Vec3f> ambientHiddenByObjects(const Volume& volume, const Options& options, const Ambient& ambient,
                                              const std::vector<cv::Vec3f>& dirs);

/// A surface point's own gather (the virtual object's pixels, knob object_rays): the rays of `dirs` in
/// front of n, marched from x through the mu occupancy (the objects are not in the way of their own rays);
/// each that hits a voxel within range brings what that voxel's surface sends towards x (its front only):
/// its real points' radiance as the objects leave them lit (exitantMuLit less albedo / pi x `hidden`, the
/// ambient the objects hide from it, when given; bounces > 0) plus what it
/// reflects of further bounces (incident.reflectedSum, of the mu gather) — in place of the ambient of its
/// direction. Returns the change against the unoccluded ambient, sum over those rays of
/// (L_hit - L_ambient) cos theta 4 pi / N (N = dirs.size()): exactly 0 where nothing is hit, so the shading
/// pass's unoccluded ambient stays as it is. With `outer` (outerGrid; mu only) a ray that leaves the grid
/// goes on through it (marchOuter) and a hit there brings its real points' light as the objects leave it
/// lit (exitantMuLit; farther from the objects, neither the ambient they hide nor further bounces).
cv::Vec3f pointGather(const Volume& volume, bool rho, const Incident& incident, const Options& options,
                      const Ambient& ambient, const std::vector<cv::Vec3f>& dirs, const cv::Vec3f& x,
                      const cv::Vec3f& n, const std::vector<cv::Vec3f>* hidden = nullptr,
                      const Volume* outer = nullptr);

/// A sphere enclosing the virtual objects (lighting world).
struct Bound {
  cv::Vec3f centre{0, 0, 0};
  float radius = 0;
};
/// k unit directions stratified over the spherical cap about unit `axis` whose half-angle has cosine
/// cosAlpha: cos theta uniform in [cosAlpha, 1] in k equal bands, azimuth by the golden angle (equal areas).
std::vector<cv::Vec3f> capDirections(const cv::Vec3f& axis, float cosAlpha, int k);
/// What the virtual objects change along a voxel's rays lies inside the cone their bounding sphere subtends:
/// seen from a voxel 15 cm off, a few degrees, which N directions over the whole sphere hit by chance, some
/// voxels by one ray and their neighbours by none (blotches on the real surfaces around, from voxel to voxel).
/// Per voxel of `computed` outside `bound`: minus the first gather's (L_rho - L_mu) y(w) 4 pi / N over the
/// directions of `dirs` inside the cone, plus the same difference over `coneRays` rays stratified over the
/// cone (capDirections) times its solid angle 2 pi (1 - cos alpha) / coneRays. Added to rho's incident SH
/// (Incident::sh's layout, `bands` bands), the real-pixel delta E^rho - E^mu then samples the objects as
/// densely from every voxel. Voxels inside the bound (the cone is the whole sphere) get nothing.
std::vector<float> coneCorrection(const Volume& volume, const std::vector<uint8_t>& computed, const Options& options,
                                  const Ambient& ambient, const std::vector<cv::Vec3f>& dirs, const Bound& bound,
                                  int coneRays);

/// The voxels the reconstruction reads at surface point x with unit normal n, with their weights (cos theta);
/// empty where none qualifies (above).
std::vector<std::pair<size_t, float>> readVoxels(const Volume& volume, const std::vector<uint8_t>& computed,
                                                 const cv::Vec3f& x, const cv::Vec3f& n);
/// Irradiance (W/m^2) at surface point x with unit normal n from the incident SH (reconstruction above).
/// Zero where no voxel qualifies.
cv::Vec3f irradiance(const Volume& volume, const Incident& incident, const cv::Vec3f& x, const cv::Vec3f& n);
/// Ambient occlusion at x: the weighted occlusion (fraction of the sphere's rays blocked within range) of the
/// same voxels; a flat open floor reads 0.5. -1 where no voxel qualifies (outside the grid).
float occlusion(const Volume& volume, const Incident& incident, const cv::Vec3f& x, const cv::Vec3f& n);

/// The ambient's irradiance with nothing occluding it, sum_l pi s_l(1) c_lm y_lm(n) over its bands 0-2 plus
/// pi times the uniform part.
cv::Vec3f unoccludedAmbient(const Ambient& ambient, const cv::Vec3f& n);

}  // namespace mrgi::lighting::iv
