#include "reconstruction/room_bounce.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <thread>

#include "reconstruction/point_index.h"

namespace mrgi::reconstruction {

namespace {

/// A unit tangent frame (t, b) perpendicular to n.
void tangentFrame(const cv::Vec3d& n, cv::Vec3d& t, cv::Vec3d& b) {
  const cv::Vec3d a = std::abs(n[0]) < 0.9 ? cv::Vec3d(1, 0, 0) : cv::Vec3d(0, 1, 0);
  t = cv::normalize(a.cross(n));
  b = n.cross(t);
}

/// A fraction in [0, 1) from an integer (the vertex's turn of its ray set about the normal).
double hashToUnit(uint64_t x) {
  x ^= x >> 33, x *= 0xff51afd7ed558ccdULL, x ^= x >> 33, x *= 0xc4ceb9fe1a85ec53ULL, x ^= x >> 33;
  return static_cast<double>(x >> 11) * (1.0 / 9007199254740992.0);
}

}  // namespace

std::vector<cv::Vec3f> roomBounceIrradiance(const RoomMesh& mesh, const MeshRays& rays,
                                            const RoomBounceOptions& options) {
  const size_t n = mesh.positions.size();
  std::vector<cv::Vec3f> E(n, cv::Vec3f(0, 0, 0));
  if (n == 0 || options.rays <= 0) return E;
  // The ray set in the tangent frame: a Fibonacci spiral over the unit disc lifted to the hemisphere
  // (Malley's method: uniform over the disc is cosine-weighted over the hemisphere, so E = pi * mean L).
  const int R = options.rays;
  const double golden = CV_PI * (3.0 - std::sqrt(5.0));
  std::vector<cv::Vec3d> local(static_cast<size_t>(R));
  for (int k = 0; k < R; ++k) {
    const double r = std::sqrt((k + 0.5) / R), phi = k * golden;
    local[static_cast<size_t>(k)] = {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0, 1.0 - r * r))};
  }
  const auto sent = [&](uint32_t v) -> cv::Vec3d {
    if (v < mesh.saturated.size() && mesh.saturated[v]) return {0, 0, 0};
    return cv::Vec3d(mesh.radiance[v]);
  };
  // A vertex position the gather can use: finite and within 100 km.
  const auto usable = [](const cv::Vec3d& p) {
    return std::isfinite(p.dot(p)) && std::abs(p[0]) + std::abs(p[1]) + std::abs(p[2]) <= 1e5;
  };
  // The room's bounding box and a k-d tree over its usable vertices, for the rays that leave.
  cv::Vec3d lo(1e30, 1e30, 1e30), hi(-1e30, -1e30, -1e30);
  std::vector<cv::Vec3f> finite;
  std::vector<uint32_t> finiteIndex;
  const bool openings = mesh.openings.recorded && !mesh.openings.cells.empty();
  if (options.holeReachM > 0 || openings)
    for (size_t i = 0; i < n; ++i) {
      const cv::Vec3f& p = mesh.positions[i];
      if (!usable(cv::Vec3d(p))) continue;
      for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], double(p[c])), hi[c] = std::max(hi[c], double(p[c]));
      if (options.holeReachM <= 0) continue;
      finite.push_back(p);
      finiteIndex.push_back(static_cast<uint32_t>(i));
    }
  const bool continueHoles = !finite.empty();
  // A ray that leaves through an opening the cameras saw through (a window) meets what they saw beyond it (the sky).
  const auto throughOpening = [&](const cv::Vec3d& o, const cv::Vec3d& d, cv::Vec3d& radiance) {
    if (!openings) return false;
    const int cell = mesh.openings.beyond(lo, hi, o, d);
    if (cell < 0 || static_cast<size_t>(cell) >= mesh.openings.radiance.size()) return false;
    radiance = cv::Vec3d(mesh.openings.radiance[static_cast<size_t>(cell)]);
    return true;
  };
  const PointCloudAdaptor cloud{finite};
  std::optional<PointKdTree> tree;
  if (continueHoles) tree.emplace(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  // Where a ray from o along d leaves the box (o inside it), and the radiance of the nearest vertex there.
  const auto continued = [&](const cv::Vec3d& o, const cv::Vec3d& d, cv::Vec3d& radiance) {
    double t = 1e30;
    for (int c = 0; c < 3; ++c)
      if (std::abs(d[c]) > 1e-12) t = std::min(t, ((d[c] > 0 ? hi[c] : lo[c]) - o[c]) / d[c]);
    if (!(t >= 0 && t < 1e29)) return false;
    const cv::Vec3d q = o + t * d;
    const float query[3] = {static_cast<float>(q[0]), static_cast<float>(q[1]), static_cast<float>(q[2])};
    uint32_t nearest = 0;
    float d2 = 0;
    if (tree->knnSearch(query, 1, &nearest, &d2) != 1 || !(d2 <= options.holeReachM * options.holeReachM)) return false;
    radiance = sent(finiteIndex[nearest]);
    return true;
  };
  const size_t stride = static_cast<size_t>(std::max(1, options.vertexStride));
  std::vector<uint8_t> known(n, 0);
  const auto gather = [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      if (i % stride != 0) continue;
      const cv::Vec3d nrm(mesh.normals[i]), p(mesh.positions[i]);
      const double len = cv::norm(nrm);
      if (!(len > 0.5) || !std::isfinite(len) || !usable(p)) continue;
      const cv::Vec3d z = nrm / len;
      cv::Vec3d t, b;
      tangentFrame(z, t, b);
      const double turn = 2 * CV_PI * hashToUnit(i), c = std::cos(turn), s = std::sin(turn);
      const cv::Vec3d o = p + options.offsetM * z;
      cv::Vec3d sum(0, 0, 0);
      int hits = 0;
      for (const cv::Vec3d& l : local) {
        const double x = c * l[0] - s * l[1], y = s * l[0] + c * l[1];
        const cv::Vec3d d = x * t + y * b + l[2] * z;
        const MeshRays::Hit h = rays.intersect(o, d);
        if (h.hit) {
          const uint32_t* tri = &mesh.indices[3 * static_cast<size_t>(h.triangle)];
          sum += (1 - h.u - h.v) * sent(tri[0]) + h.u * sent(tri[1]) + h.v * sent(tri[2]);
          ++hits;
        } else if (cv::Vec3d beyond; throughOpening(o, d, beyond) || (continueHoles && continued(o, d, beyond))) {
          sum += beyond;
          ++hits;
        }
      }
      // What was never seen sends what the seen part of the hemisphere sends, once enough of it was seen.
      const cv::Vec3d missed = hits * 4 >= R ? sum / hits : options.outside;
      const cv::Vec3d e = (sum + static_cast<double>(R - hits) * missed) * (CV_PI / R);
      E[i] = cv::Vec3f(static_cast<float>(e[0]), static_cast<float>(e[1]), static_cast<float>(e[2]));
      known[i] = 1;
    }
  };
  const size_t threads = std::clamp<size_t>(
      options.threads > 0 ? static_cast<size_t>(options.threads) : std::max(1u, std::thread::hardware_concurrency()), 1,
      std::max<size_t>(1, n / 256));
  if (threads <= 1) {
    gather(0, n);
  } else {
    std::vector<std::thread> pool;
    for (size_t w = 0; w < threads; ++w) pool.emplace_back(gather, n * w / threads, n * (w + 1) / threads);
    for (auto& th : pool) th.join();
  }
  // Vertices without rays (between the sampled ones, or with no usable normal) take their known neighbours'
  // mean, ring by ring.
  const std::vector<std::vector<uint32_t>> neighbours = meshNeighbours(mesh.indices, n);
  fillFromNeighbours(E, known, neighbours);
  if (options.smoothing > 0) {
    std::vector<cv::Vec3f> next(n);
    for (int pass = 0; pass < options.smoothing; ++pass) {
      for (size_t i = 0; i < n; ++i) {
        cv::Vec3f sum = E[i];
        for (uint32_t j : neighbours[i]) sum += E[j];
        next[i] = sum / static_cast<float>(1 + neighbours[i].size());
      }
      E.swap(next);
    }
  }
  return E;
}

}  // namespace mrgi::reconstruction
