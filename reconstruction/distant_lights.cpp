#include "reconstruction/distant_lights.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "capture/colour.h"
#include "reconstruction/mesh_rays.h"
#include "reconstruction/point_index.h"
#include "reconstruction/room_model.h"

namespace mrgi::reconstruction {
namespace {

/// A surface point the search uses: where it is, which way it faces, its irradiance pi L / albedo, and its
/// neighbours on the same surface (within DistantLightOptions::edgeRadiusM, normals within 25 degrees).
struct Sample {
  cv::Vec3d origin, normal;
  cv::Vec3d irradiance;        ///< pi L / albedo
  cv::Vec3d radiance, albedo;  ///< L, and the albedo given
  cv::Vec3b clipped{0, 0, 0};  ///< per channel: L is a lower bound (at or above the sensor's white)
  std::vector<uint32_t> neighbours;
};

/// How much light from w each sample takes: n . w where it faces w and a ray towards w leaves the room through
/// an opening, 0 where it faces away or the room is in the way, -1 (unknown) where the ray leaves through a gap.
std::vector<double> litBy(const std::vector<Sample>& samples, const cv::Vec3d& w, const DistantLightRays& rays) {
  std::vector<double> c(samples.size(), 0.0);
  cv::parallel_for_(cv::Range(0, static_cast<int>(samples.size())), [&](const cv::Range& r) {
    for (int i = r.start; i < r.end; ++i) {
      const Sample& s = samples[static_cast<size_t>(i)];
      const double facing = s.normal.dot(w);
      if (facing > 0) c[static_cast<size_t>(i)] = rays.reaches(s.origin, w) * facing;
    }
  });
  return c;
}

/// How well a direction explains the room's light at the shadow edges it predicts: for every pair of neighbours
/// it lights one of (c = n . w > 0, nothing on the way) and leaves the other in shadow, the lit one's irradiance
/// less the shadowed one's is the light's, c times over. The true direction's edges all show it (the patches'
/// edges and the shadows' of the room's own geometry); any other's cut through evenly lit surfaces, their
/// differences of either sign. Smooth light (a lamp's falloff, the walls' bounce) and albedo that changes
/// elsewhere than at the edges cancel in the differences.
struct Fit {
  double score = -1;       ///< sum of the green differences over their root sum of squares (-1: no candidate)
  double consistency = 0;  ///< mean over root mean square of those differences: 1 when every edge agrees
  int edges = 0;           ///< neighbour pairs across a predicted edge
  double litShare = 0;
  cv::Vec3d sun{0, 0, 0}, rest{0, 0, 0};
  cv::Vec3b lowerBound{0, 0, 0};
  int pieces = 0, piecesShowing = 0;  ///< surface pieces it both lights and shadows; of them, brighter where lit
};

/// The weighted median of (value, weight) pairs (0 when empty).
double weightedMedian(std::vector<std::pair<double, double>> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  double total = 0;
  for (const auto& [x, wt] : v) total += wt;
  double run = 0;
  for (const auto& [x, wt] : v)
    if ((run += wt) >= 0.5 * total) return x;
  return v.back().first;
}

/// Fit::sun and Fit::lowerBound from the lit and shadowed pieces of the room's surfaces (fitDirection).
void regionSteps(const std::vector<Sample>& samples, const std::vector<double>& c, const cv::Vec3d& w,
                 const DistantLightOptions& o, Fit& f) {
  constexpr double kPieceM = 0.3;
  constexpr size_t kMinSide = 4;
  std::map<std::array<int, 4>, std::array<std::vector<size_t>, 2>> pieces;  // [0] lit, [1] shadowed
  for (size_t i = 0; i < samples.size(); ++i) {
    const Sample& s = samples[i];
    const bool lit = c[i] > o.minFacing, shadowed = c[i] == 0 && s.normal.dot(w) > o.minFacing;
    if (!lit && !shadowed) continue;
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (std::abs(s.normal[k]) > std::abs(s.normal[axis])) axis = k;
    const std::array<int, 4> key{static_cast<int>(std::floor(s.origin[0] / kPieceM)),
                                 static_cast<int>(std::floor(s.origin[1] / kPieceM)),
                                 static_cast<int>(std::floor(s.origin[2] / kPieceM)), 2 * axis + (s.normal[axis] > 0)};
    pieces[key][lit ? 0 : 1].push_back(i);
  }
  std::vector<std::pair<double, double>> measured[3], bound[3];
  const auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  for (const auto& [key, sides] : pieces) {
    const auto& [lit, shadowed] = sides;
    if (lit.size() < kMinSide || shadowed.size() < kMinSide) continue;
    std::vector<double> cs;
    for (size_t i : lit) cs.push_back(c[i]);
    const double facing = median(cs);
    cv::Vec3d Ll, Ls, a;
    bool litClipped = false, shadowClipped = false;
    for (int k = 0; k < 3; ++k) {
      std::vector<double> l, sh, al;
      size_t lc = 0, sc = 0;
      for (size_t i : lit) l.push_back(samples[i].radiance[k]), lc += samples[i].clipped[k];
      for (size_t i : shadowed) sh.push_back(samples[i].radiance[k]), sc += samples[i].clipped[k];
      for (size_t i : shadowed) al.push_back(samples[i].albedo[k]);
      Ll[k] = median(l), Ls[k] = median(sh), a[k] = median(al);
      // Half a side clipped: its median is the sensor's white, a lower bound of its radiance.
      litClipped = litClipped || 2 * lc >= lit.size();
      shadowClipped = shadowClipped || 2 * sc >= shadowed.size();
    }
    if (shadowClipped) continue;
    ++f.pieces;
    // A piece the light's predicted edge crosses only in the model (the fused geometry a little off, the patch's
    // true edge outside the piece): its lit side no brighter than its shadowed one. Kept when most of its lit
    // samples are brighter than three quarters of its shadowed ones.
    {
      std::vector<double> sh;
      for (size_t i : shadowed) sh.push_back(capture::luminance(samples[i].radiance));
      std::nth_element(sh.begin(), sh.begin() + static_cast<long>(3 * sh.size() / 4), sh.end());
      const double q3 = sh[3 * sh.size() / 4];
      size_t brighter = 0;
      for (size_t i : lit) brighter += capture::luminance(samples[i].radiance) > q3;
      if (5 * brighter < 3 * lit.size()) continue;
    }
    ++f.piecesShowing;
    const double weight = static_cast<double>(std::min(lit.size(), shadowed.size()));
    for (int k = 0; k < 3; ++k)
      (litClipped ? bound[k] : measured[k]).emplace_back(CV_PI * (Ll[k] - Ls[k]) / (a[k] * facing), weight);
  }
  // The clipped pieces bound it from below. Its colour is the measured pieces' (a clipped piece's channels clip one
  // by one, the first ones least bound: its colour is not the light's); where their median is under the bound's in
  // luminance, it is raised as a whole to it. With no measured piece, the bound alone (every channel a lower bound).
  cv::Vec3d m, b;
  for (int k = 0; k < 3; ++k) m[k] = weightedMedian(measured[k]), b[k] = weightedMedian(bound[k]);
  const double lm = capture::luminance(m), lb = capture::luminance(b);
  if (!measured[0].empty() && lm > 0) {
    const bool raised = !bound[0].empty() && lb > lm;
    f.sun = raised ? m * (lb / lm) : m;
    for (int k = 0; k < 3; ++k) f.lowerBound[k] = raised;
  } else {
    f.sun = b;
    for (int k = 0; k < 3; ++k) f.lowerBound[k] = !bound[0].empty();
  }
}

Fit fitDirection(const std::vector<Sample>& samples, const cv::Vec3d& w, const DistantLightRays& rays,
                 const DistantLightOptions& o) {
  const size_t n = samples.size();
  const std::vector<double> c = litBy(samples, w, rays);
  Fit f;
  f.litShare =
      static_cast<double>(std::count_if(c.begin(), c.end(), [](double x) { return x > 0; })) / static_cast<double>(n);
  if (f.litShare < o.minLitShare || f.litShare > 1 - o.minLitShare) return f;
  // Edge pairs: lit i, shadowed j facing the light too (shadowed by the room, not turned away from it).
  double sum = 0, sumSq = 0;
  cv::Vec3d shadowed(0, 0, 0);
  int shadowedCount = 0;
  for (size_t i = 0; i < n; ++i) {
    if (c[i] != 0) continue;  // lit, or unknown
    if (samples[i].normal.dot(w) > 0) shadowed += samples[i].irradiance, ++shadowedCount;
  }
  for (size_t i = 0; i < n; ++i) {
    if (!(c[i] > o.minFacing)) continue;
    for (const uint32_t j : samples[i].neighbours) {
      if (c[j] != 0 || samples[j].normal.dot(w) <= o.minFacing) continue;
      const double d = samples[i].irradiance[1] - samples[j].irradiance[1];
      sum += d;
      sumSq += d * d;
      ++f.edges;
    }
  }
  if (f.edges < o.minEdges || !(sumSq > 0)) return f;
  f.score = sum / std::sqrt(sumSq);
  f.consistency = sum / std::sqrt(sumSq * f.edges);
  if (shadowedCount > 0) f.rest = shadowed / static_cast<double>(shadowedCount);
  return f;
}

/// The direction's fit with the light's irradiance measured (Fit::sun, lowerBound, pieces): once, for the
/// direction the search chose (or was given), not for every direction it tries.
Fit measureDirection(const std::vector<Sample>& samples, const cv::Vec3d& w, const DistantLightRays& rays,
                     const DistantLightOptions& o) {
  Fit f = fitDirection(samples, w, rays, o);
  if (f.score < 0) return f;
  // The light's irradiance from the patches either side of its edges: on each 30 cm piece of one surface (one
  // albedo, one light from elsewhere) that it both lights and leaves in the room's shadow, the lit samples' median
  // radiance over the shadowed ones' is (E + S c) / E, E = pi L_shadowed / albedo (the albedo given, the shadowed
  // side's): S = pi (L_lit - L_shadowed) / (albedo c). Medians, so that a boundary predicted a few centimetres
  // off (the fused geometry, its voxels) mixes a few samples in, not the answer. A piece whose lit side is
  // clipped in any channel bounds S from below; the pieces agree by their weighted median.
  regionSteps(samples, litBy(samples, w, rays), w, o, f);
  return f;
}

/// The coarse search's measure: the share of the irradiance's variance (green) that rest + sun c(w) explains,
/// fitted by least squares over every sample. Smooth, so a coarse set of directions finds the light's
/// neighbourhood; the edges then find the light.
double explainedBy(const std::vector<Sample>& samples, const cv::Vec3d& w, const DistantLightRays& rays) {
  const std::vector<double> c = litBy(samples, w, rays);
  double mc = 0, my = 0, known = 0;
  for (size_t i = 0; i < c.size(); ++i)
    if (c[i] >= 0) mc += c[i], my += samples[i].irradiance[1], ++known;
  if (!(known > 0)) return 0;
  mc /= known;
  my /= known;
  double vc = 0, vy = 0, cov = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    if (c[i] < 0) continue;
    const double dc = c[i] - mc, dy = samples[i].irradiance[1] - my;
    vc += dc * dc, vy += dy * dy, cov += dc * dy;
  }
  if (!(vc > 0) || !(vy > 0) || !(cov > 0)) return 0;
  return cov * cov / (vc * vy);
}

/// Two unit vectors completing `w` to an orthonormal basis.
void basisAround(const cv::Vec3d& w, cv::Vec3d& u, cv::Vec3d& v) {
  const cv::Vec3d a = std::abs(w[2]) < 0.9 ? cv::Vec3d(0, 0, 1) : cv::Vec3d(1, 0, 0);
  u = cv::normalize(a.cross(w));
  v = w.cross(u);
}

/// The search: a coarse set of directions, the best few searched around by their edges, the best refined.
/// False when no direction predicts enough edges.
bool search(const std::vector<Sample>& samples, const DistantLightRays& rays, const DistantLightOptions& o, Fit& best,
            cv::Vec3d& bestW) {
  // The coarse search: a Fibonacci set over the hemisphere above the room (the sun, a sky: light from outside comes
  // from above its horizon), judged by how much of the irradiance each explains.
  const cv::Vec3d up = cv::normalize(o.up);
  cv::Vec3d ux, uy;
  basisAround(up, ux, uy);
  const int candidates = std::max(8, o.candidates);
  std::vector<std::pair<double, cv::Vec3d>> coarse;
  const double golden = CV_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < candidates; ++i) {
    const double z = 1.0 - (i + 0.5) / candidates * (1.0 - o.minElevationSin),
                 r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const cv::Vec3d w = r * std::cos(golden * i) * ux + r * std::sin(golden * i) * uy + z * up;
    coarse.emplace_back(explainedBy(samples, w, rays), w);
  }
  const size_t keep = std::min<size_t>(coarse.size(), static_cast<size_t>(std::max(1, o.coarseKept)));
  std::partial_sort(coarse.begin(), coarse.begin() + static_cast<long>(keep), coarse.end(),
                    [](const auto& a, const auto& b) { return a.first > b.first; });
  // Around each of the best few, the edges decide: a 9 x 9 grid spanning the coarse spacing, then finer grids
  // around the best so far.
  const double spacing = std::sqrt(2 * CV_PI * (1.0 - o.minElevationSin) / candidates);
  bestW = coarse.front().second;
  const auto searchAround = [&](const cv::Vec3d& centre, double step, int half) {
    cv::Vec3d u, v;
    basisAround(centre, u, v);
    for (int a = -half; a <= half; ++a)
      for (int b = -half; b <= half; ++b) {
        const cv::Vec3d w = cv::normalize(centre + std::tan(a * step) * u + std::tan(b * step) * v);
        const Fit f = fitDirection(samples, w, rays, o);
        if (f.score > best.score) best = f, bestW = w;
      }
  };
  for (size_t k = 0; k < keep; ++k) searchAround(coarse[k].second, spacing / 4, 4);
  if (best.score < 0) return false;
  double step = spacing / 8;
  for (int round = 0; round < o.refineSteps; ++round, step /= 2) searchAround(bestW, step, 3);
  return true;
}

}  // namespace

DistantLightRays::DistantLightRays(const std::vector<cv::Vec3f>& positions, const MeshRays& rays,
                                   const RoomOpenings* openings)
    : rays_(rays), openings_(openings), lo_(cv::Vec3d::all(1e30)), hi_(cv::Vec3d::all(-1e30)) {
  for (const cv::Vec3f& p : positions)
    for (int k = 0; k < 3; ++k) lo_[k] = std::min(lo_[k], p[k] - 0.05), hi_[k] = std::max(hi_[k], p[k] + 0.05);
}

int DistantLightRays::opening(const cv::Vec3d& origin, const cv::Vec3d& w) const {
  return openings_ ? openings_->beyond(lo_, hi_, origin, w) : -1;
}

double DistantLightRays::lightOn(const cv::Vec3d& position, const cv::Vec3d& normal, const cv::Vec3d& w,
                                 double offsetM) const {
  const double facing = normal.dot(w);
  return facing > 0 && reaches(position + offsetM * normal, w) == 1 ? facing : 0.0;
}

int DistantLightRays::reaches(const cv::Vec3d& origin, const cv::Vec3d& w) const {
  if (rays_.occluded(origin, w, 1e3)) return 0;
  if (!openings_ || !openings_->recorded) return 1;
  return opening(origin, w) >= 0 ? 1 : -1;
}

std::optional<DistantLight> findDistantLight(const std::vector<cv::Vec3f>& positions,
                                             const std::vector<cv::Vec3f>& normals,
                                             const std::vector<cv::Vec3f>& radiance,
                                             const std::vector<cv::Vec3f>& albedo,
                                             const std::vector<uint8_t>& saturated, const MeshRays& rays,
                                             const DistantLightOptions& o, const RoomOpenings* openings) {
  const size_t count = std::min({positions.size(), normals.size(), radiance.size(), albedo.size()});
  std::vector<size_t> usable;
  for (size_t i = 0; i < count; ++i) {
    const cv::Vec3f& a = albedo[i];
    const cv::Vec3f& l = radiance[i];
    const cv::Vec3f& nn = normals[i];
    bool ok = cv::norm(nn) > 0.5;
    for (int k = 0; k < 3 && ok; ++k) ok = a[k] > 0.01f && std::isfinite(l[k]) && l[k] >= 0;
    if (ok) usable.push_back(i);
  }
  if (usable.size() < 100) return std::nullopt;
  const DistantLightRays reach(positions, rays, openings);
  const size_t stride = std::max<size_t>(1, usable.size() / static_cast<size_t>(std::max(1, o.maxPoints)));
  std::vector<Sample> samples;
  std::vector<cv::Vec3f> where;
  for (size_t j = 0; j < usable.size(); j += stride) {
    const size_t i = usable[j];
    Sample s;
    s.normal = cv::normalize(cv::Vec3d(normals[i]));
    s.origin = cv::Vec3d(positions[i]) + o.rayOffsetM * s.normal;
    for (int k = 0; k < 3; ++k) {
      s.radiance[k] = radiance[i][k];
      s.albedo[k] = albedo[i][k];
      s.irradiance[k] = CV_PI * radiance[i][k] / albedo[i][k];
      s.clipped[k] = (i < saturated.size() && saturated[i]) || radiance[i][k] >= o.clipRadiance;
    }
    samples.push_back(s);
    where.push_back(positions[i]);
  }
  {
    const PointCloudAdaptor cloud{where};
    const PointKdTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    constexpr size_t kNeighbours = 8;
    const float r2 = static_cast<float>(o.edgeRadiusM * o.edgeRadiusM);
    for (size_t i = 0; i < samples.size(); ++i) {
      uint32_t idx[kNeighbours];
      float d2[kNeighbours];
      const size_t found = tree.knnSearch(&where[i][0], kNeighbours, idx, d2);
      for (size_t k = 0; k < found; ++k)
        if (idx[k] != i && d2[k] <= r2 && samples[idx[k]].normal.dot(samples[i].normal) > 0.9)
          samples[i].neighbours.push_back(idx[k]);
    }
  }

  Fit best;
  cv::Vec3d bestW;
  if (o.towards) {
    bestW = cv::normalize(*o.towards);
    best = measureDirection(samples, bestW, reach, o);
    if (best.score < 0) return std::nullopt;
  } else {
    if (!search(samples, reach, o, best, bestW)) return std::nullopt;
    best = measureDirection(samples, bestW, reach, o);
    if (best.consistency < o.minConsistency || best.score < o.minScore) return std::nullopt;
    if (!(capture::luminance(best.sun) >= o.minContrast * capture::luminance(best.rest))) return std::nullopt;
    if (best.piecesShowing < o.minPiecesShowing || best.piecesShowing < o.minPieceShare * best.pieces)
      return std::nullopt;
  }
  DistantLight light;
  light.towards = bestW;
  light.irradiance = best.sun;
  light.rest = best.rest;
  light.consistency = best.consistency;
  light.edges = best.edges;
  light.litShare = best.litShare;
  for (int k = 0; k < 3; ++k) light.lowerBound[k] = best.lowerBound[k] != 0;
  light.pieces = best.pieces;
  light.piecesShowing = best.piecesShowing;
  return light;
}

}  // namespace mrgi::reconstruction
