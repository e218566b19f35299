#pragma once
/// Kinect-VAL (LightSkin, shared/papers/000; algorithms.md §4): virtual area lights (VALs) from RGB-D pixels
/// and from the virtual object's RSM light the virtual object through sparse shading points distributed over
/// its surface in model space. This header is the plain C++ reference of every step; the GPU path
/// (val_*.comp, val_mesh.vert/.frag) computes the same numbers and tests hold the two together.
///
/// Per VAL j (Lambertian disc: centre l_j, normal n_j, flux φ_j, area a_j, exitance φ_j/a_j) and receiver x
/// (normal n, view direction v), d = |l_j − x|:
///   w_j = a_j cos ϑ_j / (π d² + a_j)            disc form factor (exact on the axis), ≤ 1 for every d
///   E_j = (φ_j / a_j) w_j cos ϑ_i               irradiance (W/m²), ϑ_i at the receiver; ≤ φ_j / a_j as d → 0
///   S_j = (φ_j / a_j) w_j cos^k γ               glossy, γ between reflect(−v, n) and l_j − x (0 below the horizon)
/// (algorithms.md writes φ_j w_j, which is W, not W/m²: its φ is the disc's exitance.)
/// Outgoing radiance: L = (albedo/π) Σ E_j + specular · c_k Σ S_j, c_k = (k + 1) / (2π).
/// Sparse points average two VPLs (diffuse, glossy) with weights ε + lum(E_j) / (mean exitance luminance)
/// (a dark VAL pulls the averaged light less; the paper's weights w_j cos are flux-blind), renormalise them so that
/// they reproduce E and S at the point (eq. 11), interpolate them per vertex over the 8 nearest sparse points (eq.
/// 12–13) and evaluate them per pixel.
#include <cstdint>
#include <opencv2/core.hpp>
#include <random>
#include <unordered_map>
#include <vector>

#include "capture/types.h"
#include "lighting/frame/frame.h"
#include "lighting/material.h"
#include "lighting/scene_file.h"
#include "lighting/techniques/kinect_val/real_vals.h"

namespace mrgi::lighting {

/// Numerical guards shared by the CPU and GPU paths.
constexpr float kValEpsilon = 1e-10f;  ///< ε of eq. 7 and 13
constexpr float kValMinCos = 0.05f;    ///< smallest cos ϑ' dividing in eq. 11 (diffuse VPL)
constexpr float kValMinLobe = 1e-3f;   ///< smallest cos^k γ' dividing in eq. 11 (glossy VPL)
constexpr float kValMinDist2 = 1e-6f;  ///< (1 mm)²: smallest squared distance to an averaged VPL

/// Disc form factor w_j (without the receiver cosine); 0 behind the disc, ≤ 1 for any distance.
float discFormFactor(const Val& val, const cv::Vec3f& x);

/// A shading point: position, unit normal, unit direction towards the viewer, Phong exponent.
struct Receiver {
  cv::Vec3f position, normal, view;
  float exponent = 0;
};

/// Sums of one receiver over a set of VALs (eq. 7 plus what the occlusion needs).
struct ValGather {
  cv::Vec3f E{0, 0, 0};     ///< Σ E_j, W/m²
  cv::Vec3f S{0, 0, 0};     ///< Σ S_j
  cv::Vec3f ld{0, 0, 0};    ///< Σ wd_j l_j
  float wd = 0;             ///< Σ wd_j
  cv::Vec3f ls{0, 0, 0};    ///< Σ ws_j l_j
  float ws = 0;             ///< Σ ws_j
  cv::Vec3f ldSq{0, 0, 0};  ///< Σ wd_j l_j² per axis (spread of the diffuse light)
  cv::Vec3f lsSq{0, 0, 0};
};
ValGather gatherReference(const Receiver& r, const std::vector<Val>& vals);

/// The two averaged, renormalised VPLs of a sparse point (GPU layout: 4 × vec4).
struct SparseVpl {
  cv::Vec3f Ld{0, 0, 0};  ///< diffuse VPL "intensity": E = Ld cos / d²
  float occlusionD = 1;   ///< 1 − o applied (diagnostic)
  cv::Vec3f ld{0, 0, 0};  ///< diffuse VPL position
  float radiusD = 0;      ///< spread of the diffuse light (sphere S_a radius)
  cv::Vec3f Ls{0, 0, 0};  ///< glossy VPL: S = Ls cos^k γ / d²
  float occlusionS = 1;
  cv::Vec3f ls{0, 0, 0};
  float radiusS = 0;
};
static_assert(sizeof(SparseVpl) == 64);
SparseVpl normalizeReference(const ValGather& g, const Receiver& r);

/// (E, S) of a VPL pair at a receiver (eq. 10 with the same guards as eq. 11).
void evaluateVpl(const SparseVpl& v, const Receiver& r, cv::Vec3f& E, cv::Vec3f& S);
/// Outgoing radiance of a receiver with a material from its (E, S).
cv::Vec3f valRadiance(const cv::Vec3f& E, const cv::Vec3f& S, const cv::Vec3f& albedo, const cv::Vec3f& specular,
                      float exponent);

/// Sparse shading points of one mesh, in model space.
struct SparsePoints {
  std::vector<cv::Vec3f> positions, normals;
  std::vector<float> discRadius;  ///< occluder disc: farthest vertex of the point's Voronoi cell
};
/// `count` area-uniform, low-discrepancy points (stratified over the triangle-area CDF, R2 sequence inside
/// triangles); normals interpolated from the vertex normals. Deterministic.
SparsePoints sampleSparsePoints(const Mesh& mesh, int count);

/// Per-vertex interpolation: the K (≤ 8) nearest sparse points (k-d tree) and normalised weights
/// w = (1 − d/d_max) <n_v, n_x>+ (eq. 12); a vertex on a sparse point takes that point alone; ε-uniform
/// weights when every weight is 0. Also fills points.discRadius.
struct VertexWeights {
  static constexpr int kNeighbours = 8;
  std::vector<int32_t> index;  ///< vertexCount × 8 (−1 = unused)
  std::vector<float> weight;   ///< vertexCount × 8, summing to 1
};
VertexWeights vertexWeights(const Mesh& mesh, SparsePoints& points);

/// Interpolated VPL pair at vertex v (eq. 13).
SparseVpl interpolateVpl(const VertexWeights& w, size_t vertex, const std::vector<SparseVpl>& sparse);

/// Occlusion of the sparse points' VPLs by the other sparse points as discs (§3.3): sphere S_a of radius
/// spread around each averaged light, projected areas by Nusselt (π F), squares of side √(πF) at the
/// projected centres, o = Σ overlap / area(S_a) clamped to 1, faded linearly to 0 for occluders inside S_a;
/// Ld, Ls scaled by (1 − o). Positions/normals in the same (world) frame as the VPLs.
void occludeReference(const std::vector<cv::Vec3f>& positions, const std::vector<cv::Vec3f>& normals,
                      const std::vector<float>& discRadius, std::vector<SparseVpl>& vpls);

/// VALs from the virtual texels of an RSM (normal.w = 1): flux = the reflected flux, area = the texel's
/// footprint across the beam (direct flux / beam irradiance: E for a directional light, I/d² for a point or
/// spot) over <n, l>+ (clamped at 0.1). stride > 1 takes every stride-th texel per axis, standing for its
/// stride² block (area and flux × stride²).
std::vector<Val> valsFromRsm(const RsmTexels& rsm, const SceneLight& light, int stride = 1);

/// One light with its shadow maps as downloaded (the frame's light view and its layers).
struct LightShadowMaps {
  SceneLight light;
  LightView view;
  ShadowTexels maps;
};
/// The real VALs the virtual objects now shadow, dimmed: the camera saw them lit without the objects, so each
/// reflects exitance x E_with / E_without per channel (clamped to [0, 1]): direct light through the shadow
/// maps with and without the objects (lightVisibility), plus the ambient's irradiance π L_a in both. So the
/// object's underside gets no bounce from the table it shadows. Returns how many VALs changed.
size_t dimShadowedVals(std::vector<Val>& vals, const std::vector<LightShadowMaps>& lights,
                       const cv::Vec3d& ambientRadiance);
}  // namespace mrgi::lighting
