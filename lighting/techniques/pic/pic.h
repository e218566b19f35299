#pragma once
/// Precomputed illuminance composition (shared/notes/algorithms.md §6), the plain C++ reference: surfels over
/// the static room, their hierarchy by agglomerative clustering, SH caches linked to a cut of it with Embree
/// visibility, and the runtime (light the surfels, pull the flux up, gather each cache's SH radiance over its
/// links, shade by the clamped-cosine or a Phong lobe). The GPU runtime (pic_*.comp, pic_readout.frag) is its
/// twin; tests hold them together.
///
/// Ambient: the shading pass lights the object by the whole ambient; the room hides part of it. Each cache
/// therefore also holds a transfer matrix T (its bands^2 x 9): the SH projection of the directions it sees the
/// room in, against the ambient's 9 coefficients, so that the ambient the room hides is -T a at run time for
/// any ambient a (uniform or SH), and what the room sends is added by its surfels' flux.
#include <array>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "lighting/ambient.h"
#include "lighting/scene_file.h"

namespace mrgi::reconstruction {
class MeshRays;
}

namespace mrgi::lighting::pic {

/// The static geometry: triangles with a linear albedo per vertex (and optionally a normal per vertex; else
/// the triangles' own, by their winding).
struct SurfaceMesh {
  std::vector<cv::Vec3f> positions, normals, albedo;
  std::vector<uint32_t> indices;
  size_t triangles() const { return indices.size() / 3; }
};
double meshArea(const SurfaceMesh& mesh);

struct Surfel {
  cv::Vec3f position, normal, albedo;
  float area = 0;
  uint32_t triangle = 0;
  cv::Vec2f barycentric{0, 0};  ///< of the triangle's 2nd and 3rd vertex (to re-read a changed albedo)
};
/// The surfels' albedo read again from the mesh's (same triangles, new vertex albedo).
void updateAlbedo(std::vector<Surfel>& surfels, const SurfaceMesh& mesh);

struct SurfelOptions {
  int count = 4096;         ///< surfels over the whole mesh (each of area A_mesh / count)
  int relaxIterations = 3;  ///< tangential repulsion steps (0: the Halton placement alone)
};
/// Area-proportional placement: surfel j lies at the cumulative area (j + 1/2) / count of the mesh (so each
/// triangle receives its area's share, small triangles pooling until they hold one), at the j-th point of a
/// 2D Halton set (bases 2, 3) within its triangle; then relaxed: each moves away from its six nearest
/// neighbours within the tangent plane and is put back on the mesh by a ray along its normal (it keeps its
/// place when no surface is within reach). Every surfel has area A_mesh / count: their total is the mesh's.
/// `rays` (of the same mesh) is needed for relaxation only.
std::vector<Surfel> placeSurfels(const SurfaceMesh& mesh, const SurfelOptions& options,
                                 const reconstruction::MeshRays* rays = nullptr);

/// The mean distance of each surfel to its nearest neighbour, over all surfels, and its coefficient of
/// variation (what relaxation lowers).
std::pair<double, double> nearestNeighbourSpread(const std::vector<Surfel>& surfels);

struct Node {
  cv::Vec3f position, normal;  ///< area-weighted mean position, normalised area-weighted normal
  float area = 0;              ///< sum of its surfels' areas
  int32_t child[2] = {-1, -1};
  int32_t parent = -1;
  int32_t level = 0;  ///< 0 for a surfel, 1 + the larger child level otherwise
};

/// Nodes 0 .. surfels-1 are the surfels (same order); every merge appends one node, so children precede
/// their parents and pulling flux up is one forward pass (or one pass per level on the GPU).
struct Hierarchy {
  std::vector<Node> nodes;
  size_t leaves = 0;
  int32_t root = -1;
  double eMax = 1;  ///< the largest extent of the surfels' bounding box (the distance's normaliser)
  int levels() const { return root >= 0 ? nodes[static_cast<size_t>(root)].level + 1 : 0; }
};

struct ClusterOptions {
  double cn = 0.1;      ///< normal term weight C_n
  double cb = 0.02;     ///< balance term weight C_b
  int candidates = 12;  ///< nearest cluster centres searched for each cluster's best partner
};
/// d(a, b) = |x_a - x_b|^2 / e_max^2 + C_n (1 - <n_a, n_b>) + C_b |A_a - A_b| / max(A_a, A_b).
double clusterDistance(const Node& a, const Node& b, double eMax, const ClusterOptions& options);
/// Agglomerative clustering by rounds of reciprocal nearest neighbours: every cluster finds its closest
/// partner (clusterDistance) among its `candidates` nearest cluster centres; pairs that chose each other merge
/// (when none did, the closest pair found merges). Deterministic.
Hierarchy buildHierarchy(const std::vector<Surfel>& surfels, const ClusterOptions& options = {});

/// A cut through the hierarchy of at most `count` nodes, refined top-down: from the root, the node of the
/// largest weight is replaced by its children until the cut holds `count` nodes (a leaf stays). With
/// dropEmpty, nodes of weight <= 0 (and what lies under them) are left out. Sorted by node index; ties in
/// weight go to the larger index. Shared by the caches' links and the bounce receivers.
std::vector<int32_t> refineCut(const Hierarchy& hierarchy, size_t count, const std::function<double(int32_t)>& weight,
                               bool dropEmpty);

/// Caches and their links.
struct LinkOptions {
  int bands = 4;          ///< SH bands of the caches' radiance, 1..8
  int links = 128;        ///< linked nodes per cache (n_L)
  int raysPerSurfel = 1;  ///< visibility rays from a cache to each surfel (points over its disc)
};
struct CacheLinks {
  int bands = 0, links = 0;
  std::vector<cv::Vec3f> positions;
  /// Per cache `links` entries: the node (-1: unused) and its factor G (bands^2 values): the cache's SH
  /// radiance from that node is its flux times G (G = F_SH / A_node, F_SH the summed solid-angle factors of
  /// its surfels, visibility included).
  std::vector<int32_t> node;
  std::vector<float> factor;
  /// Per cache, bands^2 x 9 (row-major): T_ij = sum over the surfels it sees (front or back) of
  /// Omega y_i(w) y_j(w): the ambient coefficients a_j (3 bands, sh.h) it loses behind the room are T a.
  std::vector<float> transfer;
  /// Per cache: the solid angle (sr) of the surfels it sees from behind over all it sees (near 1: the cache
  /// lies inside or under the geometry; interpolation weighs it down).
  std::vector<float> backFraction;
  size_t caches() const { return positions.size(); }
  size_t bytes() const;
};
/// The solid angle of a surfel of area A at distance d seen at cosine c (at its own normal): A c / (d^2 +
/// A / pi), the on-axis disc's exact irradiance weight; finite as d -> 0 (at most pi).
double surfelSolidAngle(double area, double cosine, double d);
/// Links every cache: the solid-angle factors of each surfel (visibility by `rays`, the room's mesh), summed
/// up the hierarchy, then the cut refined top-down by the largest band-0 factor until `links` nodes (nodes the
/// cache cannot see are left out). `progress` (optional) receives the fraction done.
CacheLinks linkCaches(const Hierarchy& hierarchy, const std::vector<Surfel>& surfels,
                      const reconstruction::MeshRays& rays, const std::vector<cv::Vec3f>& positions,
                      const LinkOptions& options, const std::function<void(double)>& progress = {});

/// Receivers of the progressive bounces: the hierarchy's cut of `count` nodes (the largest area split first),
/// each with a cache at its centre lifted along its normal (2 mm + a tenth of its radius). A surfel reads its
/// receiver's radiance about its own normal.
struct Receivers {
  std::vector<int32_t> nodes;        ///< the cut
  std::vector<int32_t> ofSurfel;     ///< per surfel: its receiver (index into nodes)
  std::vector<cv::Vec3f> positions;  ///< the receivers' caches
};
Receivers bounceReceivers(const Hierarchy& hierarchy, int count);
/// The irradiance each surfel receives from its receiver's SH radiance (gatherCaches over the receivers'
/// links, the hidden ambient included: a surfel in a corner loses ambient), about its normal.
std::vector<cv::Vec3f> bounceIrradiance(const std::vector<Surfel>& surfels, const Receivers& receivers,
                                        const std::vector<cv::Vec3f>& receiverSh, int bands);

/// The ambient as the shading pass has it (lighting/ambient.h).
using Ambient = lighting::Ambient;

/// Per surfel and light (surfel-major): 1 where nothing of `rays` lies between the surfel (lifted 1 mm along
/// its normal) and the light.
std::vector<uint8_t> surfelVisibility(const std::vector<Surfel>& surfels, const std::vector<SceneLight>& lights,
                                      const reconstruction::MeshRays& rays);
/// Leaves' outgoing flux: albedo x (direct light (lighting::unshadowedIrradiance) x visibility + the ambient's
/// irradiance + `bounce`) x area (bounce: the previous bounce's irradiance per surfel, may be empty). Finite, never
/// negative.
std::vector<cv::Vec3f> surfelFlux(const std::vector<Surfel>& surfels, const std::vector<SceneLight>& lights,
                                  const std::vector<uint8_t>& visibility, const Ambient& ambient,
                                  const std::vector<cv::Vec3f>& bounce = {});

/// Sizes `leafFlux` to the hierarchy and sets every inner node to the sum of its children.
std::vector<cv::Vec3f> pullUp(const Hierarchy& hierarchy, const std::vector<cv::Vec3f>& leafFlux);

/// Each cache's SH radiance (caches x bands^2 x rgb): sum over its links of flux x G, minus the ambient the
/// room hides (T a).
std::vector<cv::Vec3f> gatherCaches(const CacheLinks& links, const std::vector<cv::Vec3f>& nodeFlux,
                                    const Ambient& ambient);

/// Shading from SH radiance (bands^2 rgb values): irradiance about n (clamped-cosine convolution, pi s_l(1))
/// and the radiance averaged over the normalised Phong lobe of exponent `exponent` about r (s_l(exponent)).
cv::Vec3f shIrradiance(const cv::Vec3f* sh, int bands, const cv::Vec3f& n);
cv::Vec3f shLobeRadiance(const cv::Vec3f* sh, int bands, const cv::Vec3f& r, double exponent);

/// Caches on a regular grid of `resolution`^3 centres over the cube (centre, side).
std::vector<cv::Vec3f> gridCaches(const cv::Vec3f& centre, float side, int resolution);
/// Trilinear interpolation of a grid's caches at x (clamped to the grid), each corner weighed by its
/// (1 - backFraction) too (renormalised; plain trilinear where every corner is behind geometry).
std::vector<cv::Vec3f> interpolateGrid(const std::vector<cv::Vec3f>& cacheSh, const CacheLinks& links,
                                       const cv::Vec3f& centre, float side, int resolution, const cv::Vec3f& x);

// ---- saved precompute
/// What linkCaches and the hierarchy hold, in a file: "MRGIPIC1", `key`, then each part's arrays (size and
/// bytes). load* returns false (nothing changed) for a missing, foreign (other key) or damaged file; save*
/// writes a temporary file and renames it into place (a reader never sees half a file).
struct MeshPrecompute {
  std::vector<Surfel> surfels;
  Hierarchy hierarchy;
  Receivers receivers;
  CacheLinks receiverLinks;
};
void saveMeshPrecompute(const std::string& path, uint64_t key, const MeshPrecompute& p);
bool loadMeshPrecompute(const std::string& path, uint64_t key, MeshPrecompute& p);
void saveCacheLinks(const std::string& path, uint64_t key, const CacheLinks& links);
bool loadCacheLinks(const std::string& path, uint64_t key, CacheLinks& links);

// ---- compression
/// YCoCg (algorithms.md §6) and its exact inverse.
cv::Vec3f toYCoCg(const cv::Vec3f& rgb);
cv::Vec3f fromYCoCg(const cv::Vec3f& ycocg);
/// Chroma compression of SH radiance: Y keeps every band, Co and Cg the first `chromaBands`; returns RGB.
std::vector<cv::Vec3f> compressChroma(const std::vector<cv::Vec3f>& sh, int bands, int chromaBands);
/// RGB9E5 shared-exponent packing of a non-negative colour (9-bit mantissas, 5-bit exponent, bias 15);
/// negative and NaN channels pack as 0, values above the largest (65408) clamp to it.
uint32_t packRgb9e5(const cv::Vec3f& rgb);
cv::Vec3f unpackRgb9e5(uint32_t packed);

}  // namespace mrgi::lighting::pic
