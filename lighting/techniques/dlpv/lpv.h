#pragma once
/// Light propagation volumes with delta injection (DLPV, algorithms.md §3): the grid, the injection and
/// propagation math as a plain C++ reference of the GLSL passes (lighting/lpv.glsl, lpv_inject.*,
/// lpv_propagate.comp), and the irradiance readout. Two SH bands (4 coefficients) per colour channel,
/// convention of lighting/sh.h. A cell stores radiant intensity (W/sr) as SH; radiance = intensity / cell².
#include <array>
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

#include "lighting/frame/frame.h"
#include "lighting/scene_file.h"

namespace mrgi::lighting {

/// Face solid angles seen from the centre of a neighbouring cell (algorithms.md §3), steradians.
constexpr double kFrontFaceSolidAngle = 0.4006696846;  ///< 4 asin(1/10): the face opposite the shared one
constexpr double kSideFaceSolidAngle = 0.4234413544;   ///< each of the 4 side faces
/// Direct light enters the volume as a clamped-cosine lobe along its travel direction; with two SH bands
/// the irradiance read back from a lobe of flux F facing a surface head-on is (7/12) F / cell², so the lobe
/// is scaled by 12/7 to read back the removed irradiance exactly at normal incidence.
constexpr double kDirectLobeScale = 12.0 / 7.0;

/// Axis-aligned in the lighting world; cell (i, j, k) spans origin + cellSize * [i, i+1] x ...
struct LpvGrid {
  cv::Vec3d origin{0, 0, 0};
  double cellSize = 1.0;
  int resolution = 32;
  double side() const { return cellSize * resolution; }
  cv::Vec3d centre() const { return origin + cv::Vec3d::all(0.5 * side()); }
};

/// A volume centred on the world-space box [lo, hi], side = sizeFactor x its largest edge (never below
/// 1 mm), resolution cells per axis.
LpvGrid fitGrid(const cv::Vec3d& lo, const cv::Vec3d& hi, double sizeFactor, int resolution);
/// A volume filling a region with resolution cells per axis.
LpvGrid gridIn(const Region& region, int resolution);

/// SH coefficients of one cell: [channel][coefficient], coefficient order (y00, y1-1, y10, y11).
using CellSh = std::array<std::array<float, 4>, 3>;

struct LpvVolumeCpu {
  int resolution = 0;
  std::vector<CellSh> cells;  ///< index (k * res + j) * res + i
  explicit LpvVolumeCpu(int res = 0) : resolution(res), cells(size_t(res) * res * res, CellSh{}) {}
  CellSh& at(int i, int j, int k) { return cells[(size_t(k) * resolution + j) * resolution + i]; }
  const CellSh& at(int i, int j, int k) const { return cells[(size_t(k) * resolution + j) * resolution + i]; }
};

/// Clamped cosine <n, w>+ projected to two bands: (sqrt(pi)/2, sqrt(pi/3) (n.y, n.z, n.x)).
std::array<float, 4> cosineLobe(const cv::Vec3f& n);
/// SH basis (y00, y1-1, y10, y11) at unit direction d.
std::array<float, 4> basis(const cv::Vec3f& d);

enum InjectMode : unsigned { kInjectIndirect = 1u, kInjectDirect = 2u };

struct InjectParams {
  float sign = 1.0f;
  unsigned mode = kInjectIndirect;
  bool skipIdentical = false;  ///< skip texels bit-identical in `other` (delta injection)
  LightType lightType = LightType::Point;
  cv::Vec3f lightPosition{0, 0, 0};
  cv::Vec3f lightDirection{0, 0, -1};  ///< directional: travel direction
};

/// Injects every valid RSM texel: indirect = (Phi_p / pi) cos lobe about n_p, moved half a cell along n_p;
/// direct = kDirectLobeScale (Phi_t / pi) cos lobe along the light's travel direction, moved half a cell
/// towards the light. Texels outside the grid are dropped. Adds into volume.
void injectReference(const LpvGrid& grid, const RsmTexels& source, const RsmTexels* other, const InjectParams& params,
                     LpvVolumeCpu& volume);

/// Directional damping factor for flux leaving a cell with luminance SH c towards axis direction d
/// (see lpv.glsl): 1 - damping * r * (1 - <d, m>+), with m the lobe's signed main direction (band-1 vector,
/// flipped for negative lobes) and r = (sqrt(3)/2) |c1| / |c0| clamped to [0, 1] its directionality
/// (1 for a clamped-cosine lobe, 0 for isotropic light). Two-band lobes leak flux sideways and backwards;
/// a coherent beam or a shadow column should not, so that leak is what gets damped. Over several steps
/// the leak piles negative flux up beside and inside shadows (over-dark shadow centres, bleeding).
float dampingFactor(const std::array<float, 4>& luminanceSh, const cv::Vec3f& d, float damping);

/// `steps` propagation steps (Kaplanyan & Dachsbacher gather over 6 neighbours x 5 faces); returns the
/// accumulated volume (injected + every step). clampNegative: regular LPVs drop negative face flux; delta
/// volumes keep it. late (optional, the direct delta) joins the propagation lateSteps steps before the end
/// (all of them when lateSteps >= steps), so shadows blur less than bounce light. afterEachStep (optional):
/// called with the accumulated volume after each step, 1 to `steps` (without a late volume, what a call
/// with that many steps returns).
LpvVolumeCpu propagateReference(
    const LpvGrid& grid, const LpvVolumeCpu& injected, int steps, float damping, bool clampNegative,
    const LpvVolumeCpu* late = nullptr, int lateSteps = 0,
    const std::function<void(int step, const LpvVolumeCpu& accumulated)>& afterEachStep = {});

/// Irradiance (W/m²) at a surface point with unit normal n: trilinear SH at position + n * cell / 2, read as
/// E = (1/cell²) sum_l A_l c_lm y_lm(-n), A = (pi, 2 pi / 3); 0 outside the grid.
cv::Vec3f irradianceReference(const LpvGrid& grid, const LpvVolumeCpu& volume, const cv::Vec3f& position,
                              const cv::Vec3f& normal);

/// Total flux of a volume, per channel: sum over cells of the SH integral 2 sqrt(pi) c_00 (W).
cv::Vec3d totalFlux(const LpvVolumeCpu& volume);

}  // namespace mrgi::lighting
