#include "reconstruction/distant_lights.h"

#include <algorithm>
#include <cmath>

#include "reconstruction/mesh_rays.h"
#include "reconstruction/point_index.h"

namespace mrgi::reconstruction {
namespace {

/// A surface point the search uses: where it is, which way it faces, its irradiance pi L / albedo, and its
/// neighbours on the same surface (within DistantLightOptions::edgeRadiusM, normals within 25 degrees).
struct Sample {
  cv::Vec3d origin, normal;
  cv::Vec3d irradiance;
  std::vector<uint32_t> neighbours;
};

/// How much light from w each sample takes: n . w where it faces w and a ray towards w leaves the room, else 0.
std::vector<double> litBy(const std::vector<Sample>& samples, const cv::Vec3d& w, const MeshRays& rays) {
  std::vector<double> c(samples.size(), 0.0);
  cv::parallel_for_(cv::Range(0, static_cast<int>(samples.size())), [&](const cv::Range& r) {
    for (int i = r.start; i < r.end; ++i) {
      const Sample& s = samples[static_cast<size_t>(i)];
      const double facing = s.normal.dot(w);
      if (facing > 0 && !rays.occluded(s.origin, w, 1e3)) c[static_cast<size_t>(i)] = facing;
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
};

Fit fitDirection(const std::vector<Sample>& samples, const cv::Vec3d& w, const MeshRays& rays,
                 const DistantLightOptions& o) {
  const size_t n = samples.size();
  const std::vector<double> c = litBy(samples, w, rays);
  Fit f;
  f.litShare =
      static_cast<double>(std::count_if(c.begin(), c.end(), [](double x) { return x > 0; })) / static_cast<double>(n);
  if (f.litShare < o.minLitShare || f.litShare > 1 - o.minLitShare) return f;
  // Edge pairs: lit i, shadowed j facing the light too (shadowed by the room, not turned away from it).
  std::vector<cv::Vec3d> perUnit;  // (y_i - y_j) / c_i
  double sum = 0, sumSq = 0;
  cv::Vec3d shadowed(0, 0, 0);
  int shadowedCount = 0;
  for (size_t i = 0; i < n; ++i) {
    if (c[i] > 0) continue;
    if (samples[i].normal.dot(w) > 0) shadowed += samples[i].irradiance, ++shadowedCount;
  }
  for (size_t i = 0; i < n; ++i) {
    if (!(c[i] > o.minFacing)) continue;
    for (const uint32_t j : samples[i].neighbours) {
      if (c[j] > 0 || samples[j].normal.dot(w) <= o.minFacing) continue;
      const cv::Vec3d d = samples[i].irradiance - samples[j].irradiance;
      sum += d[1];
      sumSq += d[1] * d[1];
      perUnit.push_back(d / c[i]);
    }
  }
  f.edges = static_cast<int>(perUnit.size());
  if (f.edges < o.minEdges || !(sumSq > 0)) return f;
  f.score = sum / std::sqrt(sumSq);
  f.consistency = sum / std::sqrt(sumSq * f.edges);
  // The light's irradiance: the median of its edges' estimates, channel by channel.
  for (int k = 0; k < 3; ++k) {
    std::vector<double> v;
    v.reserve(perUnit.size());
    for (const auto& d : perUnit) v.push_back(d[k]);
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    f.sun[k] = v[v.size() / 2];
  }
  if (shadowedCount > 0) f.rest = shadowed / static_cast<double>(shadowedCount);
  return f;
}

/// The coarse search's measure: the share of the irradiance's variance (green) that rest + sun c(w) explains,
/// fitted by least squares over every sample. Smooth, so a coarse set of directions finds the light's
/// neighbourhood; the edges then find the light.
double explainedBy(const std::vector<Sample>& samples, const cv::Vec3d& w, const MeshRays& rays) {
  const size_t n = samples.size();
  const std::vector<double> c = litBy(samples, w, rays);
  double mc = 0, my = 0;
  for (size_t i = 0; i < n; ++i) mc += c[i], my += samples[i].irradiance[1];
  mc /= static_cast<double>(n);
  my /= static_cast<double>(n);
  double vc = 0, vy = 0, cov = 0;
  for (size_t i = 0; i < n; ++i) {
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

}  // namespace

std::optional<DistantLight> findDistantLight(const std::vector<cv::Vec3f>& positions,
                                             const std::vector<cv::Vec3f>& normals,
                                             const std::vector<cv::Vec3f>& radiance,
                                             const std::vector<cv::Vec3f>& albedo, const MeshRays& rays,
                                             const DistantLightOptions& o) {
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
  const size_t stride = std::max<size_t>(1, usable.size() / static_cast<size_t>(std::max(1, o.maxPoints)));
  std::vector<Sample> samples;
  std::vector<cv::Vec3f> where;
  for (size_t j = 0; j < usable.size(); j += stride) {
    const size_t i = usable[j];
    Sample s;
    s.normal = cv::normalize(cv::Vec3d(normals[i]));
    s.origin = cv::Vec3d(positions[i]) + o.rayOffsetM * s.normal;
    for (int k = 0; k < 3; ++k) s.irradiance[k] = CV_PI * radiance[i][k] / albedo[i][k];
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
  Fit best;
  cv::Vec3d bestW = coarse.front().second;
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
  if (best.score < 0) return std::nullopt;
  double step = spacing / 8;
  for (int round = 0; round < o.refineSteps; ++round, step /= 2) searchAround(bestW, step, 3);
  if (best.consistency < o.minConsistency) return std::nullopt;
  DistantLight light;
  light.towards = bestW;
  light.irradiance = best.sun;
  light.rest = best.rest;
  light.consistency = best.consistency;
  light.edges = best.edges;
  light.litShare = best.litShare;
  return light;
}

}  // namespace mrgi::reconstruction
