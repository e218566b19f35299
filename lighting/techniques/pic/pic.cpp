#include "lighting/techniques/pic/pic.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <optional>
#include <queue>
#include <type_traits>

#include "lighting/frame/frame.h"
#include "lighting/sh.h"
#include "reconstruction/light_estimation.h"
#include "reconstruction/mesh_rays.h"
#include "reconstruction/point_index.h"

namespace mrgi::lighting::pic {

namespace {

double radicalInverse(uint32_t i, uint32_t base) {
  double inv = 1.0 / base, f = inv, r = 0;
  while (i > 0) {
    r += f * static_cast<double>(i % base);
    i /= base;
    f *= inv;
  }
  return r;
}

cv::Vec3f normalised(const cv::Vec3f& v, const cv::Vec3f& fallback) {
  const float n = static_cast<float>(cv::norm(v));
  return n > 1e-12f ? v / n : fallback;
}

cv::Vec3f faceNormal(const SurfaceMesh& m, size_t t) {
  const cv::Vec3f& a = m.positions[m.indices[3 * t]];
  const cv::Vec3f& b = m.positions[m.indices[3 * t + 1]];
  const cv::Vec3f& c = m.positions[m.indices[3 * t + 2]];
  return normalised((b - a).cross(c - a), cv::Vec3f(0, 0, 1));
}

/// Position, normal and albedo of triangle t at barycentrics (1 - u - v, u, v).
void surfelAt(const SurfaceMesh& m, size_t t, float u, float v, Surfel& s) {
  const uint32_t i0 = m.indices[3 * t], i1 = m.indices[3 * t + 1], i2 = m.indices[3 * t + 2];
  const float w = 1.0f - u - v;
  s.position = w * m.positions[i0] + u * m.positions[i1] + v * m.positions[i2];
  const cv::Vec3f face = faceNormal(m, t);
  s.normal = m.normals.size() == m.positions.size()
                 ? normalised(w * m.normals[i0] + u * m.normals[i1] + v * m.normals[i2], face)
                 : face;
  s.albedo = m.albedo.size() == m.positions.size() ? w * m.albedo[i0] + u * m.albedo[i1] + v * m.albedo[i2]
                                                   : cv::Vec3f(0.5f, 0.5f, 0.5f);
  s.triangle = static_cast<uint32_t>(t);
  s.barycentric = {u, v};
}

double triangleArea(const SurfaceMesh& m, size_t t) {
  const cv::Vec3f& a = m.positions[m.indices[3 * t]];
  const cv::Vec3f& b = m.positions[m.indices[3 * t + 1]];
  const cv::Vec3f& c = m.positions[m.indices[3 * t + 2]];
  const double area = 0.5 * cv::norm((b - a).cross(c - a));
  return std::isfinite(area) ? area : 0.0;
}

}  // namespace

double meshArea(const SurfaceMesh& mesh) {
  double a = 0;
  for (size_t t = 0; t < mesh.triangles(); ++t) a += triangleArea(mesh, t);
  return a;
}

std::vector<Surfel> placeSurfels(const SurfaceMesh& mesh, const SurfelOptions& options,
                                 const reconstruction::MeshRays* rays) {
  std::vector<Surfel> out;
  const size_t T = mesh.triangles();
  if (T == 0 || options.count <= 0) return out;
  std::vector<double> cumulative(T);
  double total = 0;
  for (size_t t = 0; t < T; ++t) cumulative[t] = (total += triangleArea(mesh, t));
  if (!(total > 0)) return out;
  const auto n = static_cast<size_t>(options.count);
  const float area = static_cast<float>(total / static_cast<double>(n));
  out.resize(n);
  for (size_t j = 0; j < n; ++j) {
    const double at = (static_cast<double>(j) + 0.5) / static_cast<double>(n) * total;
    size_t t = static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), at) - cumulative.begin());
    t = std::min(t, T - 1);
    const auto r1 = static_cast<float>(radicalInverse(static_cast<uint32_t>(j + 1), 2));
    const auto r2 = static_cast<float>(radicalInverse(static_cast<uint32_t>(j + 1), 3));
    const float s = std::sqrt(r1);
    surfelAt(mesh, t, (1.0f - r2) * s, r2 * s, out[j]);
    out[j].area = area;
  }
  if (!rays || options.relaxIterations <= 0 || n < 2) return out;

  // Tangential repulsion (Jacobi steps: every surfel moves from the previous positions).
  const float spacing = std::sqrt(area), reach = 1.5f * spacing;
  const size_t k = std::min<size_t>(7, n);
  for (int it = 0; it < options.relaxIterations; ++it) {
    std::vector<cv::Vec3f> pts(n);
    for (size_t i = 0; i < n; ++i) pts[i] = out[i].position;
    reconstruction::PointCloudAdaptor adaptor{pts};
    reconstruction::PointKdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    std::vector<Surfel> next = out;
    cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& range) {
      std::vector<uint32_t> idx(k);
      std::vector<float> d2(k);
      for (int i = range.start; i < range.end; ++i) {
        const Surfel& s = out[static_cast<size_t>(i)];
        const size_t found = tree.knnSearch(&pts[static_cast<size_t>(i)][0], k, idx.data(), d2.data());
        cv::Vec3f force(0, 0, 0);
        for (size_t q = 0; q < found; ++q) {
          if (idx[q] == static_cast<uint32_t>(i)) continue;
          const float d = std::sqrt(d2[q]);
          if (!(d < reach)) continue;
          const cv::Vec3f away = d > 1e-9f ? (s.position - pts[idx[q]]) / d : cv::Vec3f(0, 0, 0);
          force += away * ((reach - d) / reach);
        }
        force -= s.normal * force.dot(s.normal);
        const float f = static_cast<float>(cv::norm(force));
        if (!(f > 1e-6f)) continue;
        const cv::Vec3f moved = s.position + force * (0.25f * spacing * std::min(f, 1.0f) / f);
        // Back onto the mesh along the normal, within half a spacing either side.
        const float h = 0.5f * spacing;
        const auto hit = rays->intersect(cv::Vec3d(moved + s.normal * h), cv::Vec3d(-s.normal), 2.0 * h);
        if (!hit.hit || hit.triangle >= T) continue;
        Surfel m;
        surfelAt(mesh, hit.triangle, static_cast<float>(hit.u), static_cast<float>(hit.v), m);
        if (m.normal.dot(s.normal) < 0.5f) continue;  // another surface: stay
        m.area = area;
        next[static_cast<size_t>(i)] = m;
      }
    });
    out.swap(next);
  }
  return out;
}

void updateAlbedo(std::vector<Surfel>& surfels, const SurfaceMesh& mesh) {
  for (Surfel& s : surfels) {
    if (s.triangle >= mesh.triangles()) continue;
    const float area = s.area;
    surfelAt(mesh, s.triangle, s.barycentric[0], s.barycentric[1], s);
    s.area = area;
  }
}

std::pair<double, double> nearestNeighbourSpread(const std::vector<Surfel>& surfels) {
  const size_t n = surfels.size();
  if (n < 2) return {0.0, 0.0};
  std::vector<cv::Vec3f> pts(n);
  for (size_t i = 0; i < n; ++i) pts[i] = surfels[i].position;
  reconstruction::PointCloudAdaptor adaptor{pts};
  reconstruction::PointKdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  double sum = 0, sum2 = 0;
  for (size_t i = 0; i < n; ++i) {
    uint32_t idx[2];
    float d2[2];
    tree.knnSearch(&pts[i][0], 2, idx, d2);
    const double d = std::sqrt(static_cast<double>(idx[0] == i ? d2[1] : d2[0]));
    sum += d, sum2 += d * d;
  }
  const double mean = sum / static_cast<double>(n);
  const double var = std::max(0.0, sum2 / static_cast<double>(n) - mean * mean);
  return {mean, mean > 0 ? std::sqrt(var) / mean : 0.0};
}

double clusterDistance(const Node& a, const Node& b, double eMax, const ClusterOptions& o) {
  const cv::Vec3f dx = a.position - b.position;
  const double e2 = std::max(eMax * eMax, 1e-12);
  const double maxArea = std::max(a.area, b.area);
  const double balance = maxArea > 0 ? std::abs(a.area - b.area) / maxArea : 0.0;
  return dx.dot(dx) / e2 + o.cn * (1.0 - a.normal.dot(b.normal)) + o.cb * balance;
}

Hierarchy buildHierarchy(const std::vector<Surfel>& surfels, const ClusterOptions& options) {
  Hierarchy h;
  h.leaves = surfels.size();
  if (surfels.empty()) return h;
  h.nodes.reserve(2 * surfels.size());
  cv::Vec3f lo(1e30f, 1e30f, 1e30f), hi(-1e30f, -1e30f, -1e30f);
  for (const Surfel& s : surfels) {
    Node n;
    n.position = s.position, n.normal = s.normal, n.area = s.area;
    h.nodes.push_back(n);
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], s.position[c]), hi[c] = std::max(hi[c], s.position[c]);
  }
  h.eMax = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-6f});
  std::vector<int32_t> active(surfels.size());
  std::iota(active.begin(), active.end(), 0);
  const auto merge = [&](int32_t a, int32_t b) {
    Node n;
    const Node &A = h.nodes[static_cast<size_t>(a)], &B = h.nodes[static_cast<size_t>(b)];
    n.area = A.area + B.area;
    const float wa = n.area > 0 ? A.area / n.area : 0.5f;
    n.position = wa * A.position + (1.0f - wa) * B.position;
    n.normal = normalised(A.area * A.normal + B.area * B.normal, A.normal);
    n.child[0] = a, n.child[1] = b;
    n.level = std::max(A.level, B.level) + 1;
    const auto id = static_cast<int32_t>(h.nodes.size());
    h.nodes[static_cast<size_t>(a)].parent = h.nodes[static_cast<size_t>(b)].parent = id;
    h.nodes.push_back(n);
    return id;
  };
  while (active.size() > 1) {
    const size_t n = active.size();
    std::vector<cv::Vec3f> pts(n);
    for (size_t i = 0; i < n; ++i) pts[i] = h.nodes[static_cast<size_t>(active[i])].position;
    reconstruction::PointCloudAdaptor adaptor{pts};
    reconstruction::PointKdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    const size_t k = std::min(n, static_cast<size_t>(std::max(2, options.candidates + 1)));
    std::vector<int32_t> best(n, -1);
    std::vector<double> bestD(n, 1e300);
    cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& range) {
      std::vector<uint32_t> idx(k);
      std::vector<float> d2(k);
      for (int i = range.start; i < range.end; ++i) {
        const size_t found = tree.knnSearch(&pts[static_cast<size_t>(i)][0], k, idx.data(), d2.data());
        const Node& a = h.nodes[static_cast<size_t>(active[static_cast<size_t>(i)])];
        for (size_t q = 0; q < found; ++q) {
          const auto j = static_cast<int32_t>(idx[q]);
          if (j == i) continue;
          const double d =
              clusterDistance(a, h.nodes[static_cast<size_t>(active[static_cast<size_t>(j)])], h.eMax, options);
          if (d < bestD[static_cast<size_t>(i)] ||
              (d == bestD[static_cast<size_t>(i)] && j < best[static_cast<size_t>(i)]))
            bestD[static_cast<size_t>(i)] = d, best[static_cast<size_t>(i)] = j;
        }
      }
    });
    std::vector<uint8_t> used(n, 0);
    std::vector<int32_t> next;
    next.reserve(n);
    for (size_t i = 0; i < n; ++i) {
      const int32_t j = best[i];
      if (j > static_cast<int32_t>(i) && best[static_cast<size_t>(j)] == static_cast<int32_t>(i)) {
        used[i] = used[static_cast<size_t>(j)] = 1;
        next.push_back(merge(active[i], active[static_cast<size_t>(j)]));
      }
    }
    if (next.empty()) {
      size_t i = 0;
      for (size_t q = 1; q < n; ++q)
        if (bestD[q] < bestD[i]) i = q;
      const auto j = static_cast<size_t>(best[i] >= 0 ? best[i] : (i == 0 ? 1 : 0));
      used[i] = used[j] = 1;
      next.push_back(merge(active[i], active[j]));
    }
    for (size_t i = 0; i < n; ++i)
      if (!used[i]) next.push_back(active[i]);
    active.swap(next);
  }
  h.root = active.front();
  return h;
}

size_t CacheLinks::bytes() const {
  return positions.size() * sizeof(cv::Vec3f) + node.size() * sizeof(int32_t) + factor.size() * sizeof(float) +
         transfer.size() * sizeof(float) + backFraction.size() * sizeof(float);
}

double surfelSolidAngle(double area, double cosine, double d) {
  const double v = area * std::max(cosine, 0.0) / (d * d + area / CV_PI);
  return std::isfinite(v) ? v : 0.0;
}

std::vector<int32_t> refineCut(const Hierarchy& h, size_t count, const std::function<double(int32_t)>& weight,
                               bool dropEmpty) {
  std::vector<int32_t> done;
  if (h.root < 0) return done;
  using Item = std::pair<double, int32_t>;
  std::priority_queue<Item> open;
  const auto push = [&](int32_t k) {
    const double w = weight(k);
    if (!dropEmpty || w > 0) open.push({w, k});
  };
  push(h.root);
  while (!open.empty() && open.size() + done.size() < count) {
    const int32_t k = open.top().second;
    open.pop();
    const Node& n = h.nodes[static_cast<size_t>(k)];
    if (n.child[0] < 0) {
      done.push_back(k);
      continue;
    }
    for (int32_t child : n.child) push(child);
  }
  while (!open.empty()) done.push_back(open.top().second), open.pop();
  std::sort(done.begin(), done.end());
  return done;
}

CacheLinks linkCaches(const Hierarchy& h, const std::vector<Surfel>& surfels, const reconstruction::MeshRays& rays,
                      const std::vector<cv::Vec3f>& positions, const LinkOptions& options,
                      const std::function<void(double)>& progress) {
  CacheLinks out;
  out.bands = std::clamp(options.bands, 1, sh::kMaxBands);
  out.links = std::max(1, options.links);
  out.positions = positions;
  const int B2 = out.bands * out.bands;
  const size_t C = positions.size(), L = static_cast<size_t>(out.links), N = h.nodes.size();
  out.node.assign(C * L, -1);
  out.factor.assign(C * L * static_cast<size_t>(B2), 0.0f);
  out.transfer.assign(C * static_cast<size_t>(B2) * 9, 0.0f);
  out.backFraction.assign(C, 0.0f);
  if (h.root < 0 || surfels.size() != h.leaves) return out;
  const int spp = std::max(1, options.raysPerSurfel);
  // Points over a surfel's disc (radius sqrt(A / pi)) in its tangent frame, as offsets in (u, v) units.
  std::vector<cv::Vec2f> disc(static_cast<size_t>(spp), cv::Vec2f(0, 0));
  if (spp > 1)
    for (int q = 0; q < spp; ++q) {
      const float r = std::sqrt((static_cast<float>(q) + 0.5f) / static_cast<float>(spp));
      const float phi = static_cast<float>(q) * 2.39996323f;
      disc[static_cast<size_t>(q)] = {r * std::cos(phi), r * std::sin(phi)};
    }
  const size_t chunk = 16;
  for (size_t first = 0; first < C; first += chunk) {
    const size_t last = std::min(C, first + chunk);
    cv::parallel_for_(cv::Range(static_cast<int>(first), static_cast<int>(last)), [&](const cv::Range& range) {
      std::vector<double> S(N * static_cast<size_t>(B2));
      std::vector<double> y(static_cast<size_t>(B2)), y9(9);
      std::vector<double> T(static_cast<size_t>(B2) * 9);
      for (int ci = range.start; ci < range.end; ++ci) {
        const auto c = static_cast<size_t>(ci);
        std::fill(S.begin(), S.end(), 0.0);
        std::fill(T.begin(), T.end(), 0.0);
        const cv::Vec3d o(positions[c]);
        double front = 0, back = 0;
        for (size_t s = 0; s < surfels.size(); ++s) {
          const Surfel& sf = surfels[s];
          const cv::Vec3d n(sf.normal);
          const cv::Vec3d t0 = std::abs(n[0]) < 0.9 ? cv::normalize(n.cross(cv::Vec3d(1, 0, 0)))
                                                    : cv::normalize(n.cross(cv::Vec3d(0, 1, 0)));
          const cv::Vec3d t1 = n.cross(t0);
          const double radius = std::sqrt(static_cast<double>(sf.area) / CV_PI);
          const double a = static_cast<double>(sf.area) / spp;
          for (int q = 0; q < spp; ++q) {
            const cv::Vec2f& dq = disc[static_cast<size_t>(q)];
            const cv::Vec3d p = cv::Vec3d(sf.position) + radius * (dq[0] * t0 + dq[1] * t1);
            const cv::Vec3d v = p - o;
            const double d = cv::norm(v);
            if (!(d > 1e-6)) continue;
            const cv::Vec3d w = v / d;
            const double cosS = -n.dot(w);
            const double omega = surfelSolidAngle(a, std::abs(cosS), d);
            if (!(omega > 0)) continue;
            if (rays.occluded(o, w, std::max(0.0, d - 1e-3))) continue;
            sh::evaluate(w, out.bands, y.data());
            sh::evaluate(w, 3, y9.data());
            for (int i = 0; i < B2; ++i)
              for (int j = 0; j < 9; ++j)
                T[static_cast<size_t>(i * 9 + j)] += omega * y[static_cast<size_t>(i)] * y9[static_cast<size_t>(j)];
            if (cosS > 0) {
              front += omega;
              double* row = &S[s * static_cast<size_t>(B2)];
              for (int i = 0; i < B2; ++i) row[i] += omega * y[static_cast<size_t>(i)];
            } else {
              back += omega;
            }
          }
        }
        // Sum up the hierarchy (children precede parents).
        for (size_t k = h.leaves; k < N; ++k) {
          const Node& nd = h.nodes[k];
          double* row = &S[k * static_cast<size_t>(B2)];
          const double* a = &S[static_cast<size_t>(nd.child[0]) * static_cast<size_t>(B2)];
          const double* b = &S[static_cast<size_t>(nd.child[1]) * static_cast<size_t>(B2)];
          for (int i = 0; i < B2; ++i) row[i] = a[i] + b[i];
        }
        // The cut: refine the node with the largest band-0 factor until `links` nodes (unseen nodes left out).
        const std::vector<int32_t> done = refineCut(
            h, L, [&](int32_t k) { return S[static_cast<size_t>(k) * static_cast<size_t>(B2)]; }, true);
        for (size_t l = 0; l < done.size() && l < L; ++l) {
          const auto k = static_cast<size_t>(done[l]);
          out.node[c * L + l] = done[l];
          const double scale = 1.0 / (CV_PI * std::max(static_cast<double>(h.nodes[k].area), 1e-30));
          for (int i = 0; i < B2; ++i)
            out.factor[(c * L + l) * static_cast<size_t>(B2) + static_cast<size_t>(i)] =
                static_cast<float>(S[k * static_cast<size_t>(B2) + static_cast<size_t>(i)] * scale);
        }
        for (size_t i = 0; i < T.size(); ++i) out.transfer[c * T.size() + i] = static_cast<float>(T[i]);
        out.backFraction[c] = front + back > 0 ? static_cast<float>(back / (front + back)) : 0.0f;
      }
    });
    if (progress) progress(static_cast<double>(last) / static_cast<double>(C));
  }
  return out;
}

Receivers bounceReceivers(const Hierarchy& h, int count) {
  Receivers r;
  if (h.root < 0) return r;
  const std::vector<int32_t> done = refineCut(
      h, static_cast<size_t>(std::max(1, count)),
      [&h](int32_t k) { return static_cast<double>(h.nodes[static_cast<size_t>(k)].area); }, false);
  r.nodes = done;
  // Every surfel's receiver: its ancestor in the cut (walk the cut's subtrees down).
  r.ofSurfel.assign(h.leaves, -1);
  for (size_t i = 0; i < done.size(); ++i) {
    std::vector<int32_t> stack{done[i]};
    while (!stack.empty()) {
      const int32_t k = stack.back();
      stack.pop_back();
      const Node& n = h.nodes[static_cast<size_t>(k)];
      if (n.child[0] < 0) {
        r.ofSurfel[static_cast<size_t>(k)] = static_cast<int32_t>(i);
      } else {
        stack.push_back(n.child[0]);
        stack.push_back(n.child[1]);
      }
    }
    const Node& n = h.nodes[static_cast<size_t>(done[i])];
    const float lift = 0.002f + 0.1f * std::sqrt(n.area / static_cast<float>(CV_PI));
    r.positions.push_back(n.position + n.normal * lift);
  }
  return r;
}

std::vector<cv::Vec3f> bounceIrradiance(const std::vector<Surfel>& surfels, const Receivers& receivers,
                                        const std::vector<cv::Vec3f>& receiverSh, int bands) {
  const auto B2 = static_cast<size_t>(bands * bands);
  std::vector<cv::Vec3f> out(surfels.size(), cv::Vec3f(0, 0, 0));
  for (size_t i = 0; i < surfels.size() && i < receivers.ofSurfel.size(); ++i) {
    const int32_t k = receivers.ofSurfel[i];
    if (k < 0 || (static_cast<size_t>(k) + 1) * B2 > receiverSh.size()) continue;
    out[i] = shIrradiance(&receiverSh[static_cast<size_t>(k) * B2], bands, surfels[i].normal);
  }
  return out;
}

std::vector<uint8_t> surfelVisibility(const std::vector<Surfel>& surfels, const std::vector<SceneLight>& lights,
                                      const reconstruction::MeshRays& rays) {
  const size_t L = lights.size();
  std::vector<uint8_t> v(surfels.size() * L, 0);
  cv::parallel_for_(cv::Range(0, static_cast<int>(surfels.size())), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      const Surfel& s = surfels[static_cast<size_t>(i)];
      const cv::Vec3d o = cv::Vec3d(s.position) + 1e-3 * cv::Vec3d(s.normal);
      for (size_t l = 0; l < L; ++l) {
        const SceneLight& light = lights[l];
        cv::Vec3d d;
        double far = 1e30;
        if (light.type == LightType::Directional) {
          d = -light.direction;
        } else {
          d = light.position - o;
          far = cv::norm(d);
          if (!(far > 1e-9)) continue;
          d /= far;
          far -= 1e-3;
        }
        v[static_cast<size_t>(i) * L + l] = rays.occluded(o, d, far) ? 0 : 1;
      }
    }
  });
  return v;
}

std::vector<cv::Vec3f> surfelFlux(const std::vector<Surfel>& surfels, const std::vector<SceneLight>& lights,
                                  const std::vector<uint8_t>& visibility, const Ambient& ambient,
                                  const std::vector<cv::Vec3f>& bounce) {
  const size_t L = lights.size();
  std::vector<cv::Vec3f> out(surfels.size());
  for (size_t i = 0; i < surfels.size(); ++i) {
    const Surfel& s = surfels[i];
    cv::Vec3d e(ambient.irradiance(s.normal));
    for (size_t l = 0; l < L; ++l)
      if (visibility.size() == surfels.size() * L && visibility[i * L + l])
        e += unshadowedIrradiance(lights[l], cv::Vec3d(s.position), cv::Vec3d(s.normal));
    if (bounce.size() == surfels.size()) e += cv::Vec3d(bounce[i]);
    for (int c = 0; c < 3; ++c) {
      const double f = static_cast<double>(s.albedo[c]) * e[c] * static_cast<double>(s.area);
      out[i][c] = std::isfinite(f) ? static_cast<float>(std::max(f, 0.0)) : 0.0f;
    }
  }
  return out;
}

std::vector<cv::Vec3f> pullUp(const Hierarchy& h, const std::vector<cv::Vec3f>& leafFlux) {
  std::vector<cv::Vec3f> f(h.nodes.size(), cv::Vec3f(0, 0, 0));
  for (size_t i = 0; i < h.leaves && i < leafFlux.size(); ++i) f[i] = leafFlux[i];
  for (size_t k = h.leaves; k < h.nodes.size(); ++k)
    f[k] = f[static_cast<size_t>(h.nodes[k].child[0])] + f[static_cast<size_t>(h.nodes[k].child[1])];
  return f;
}

std::vector<cv::Vec3f> gatherCaches(const CacheLinks& links, const std::vector<cv::Vec3f>& nodeFlux,
                                    const Ambient& ambient) {
  const int B2 = links.bands * links.bands;
  const size_t C = links.caches(), L = static_cast<size_t>(links.links);
  std::vector<cv::Vec3f> out(C * static_cast<size_t>(B2), cv::Vec3f(0, 0, 0));
  const std::array<cv::Vec3f, 9> a = ambient.coefficients();
  for (size_t c = 0; c < C; ++c) {
    cv::Vec3f* sh = &out[c * static_cast<size_t>(B2)];
    for (size_t l = 0; l < L; ++l) {
      const int32_t k = links.node[c * L + l];
      if (k < 0 || static_cast<size_t>(k) >= nodeFlux.size()) continue;
      const float* g = &links.factor[(c * L + l) * static_cast<size_t>(B2)];
      for (int i = 0; i < B2; ++i) sh[i] += nodeFlux[static_cast<size_t>(k)] * g[i];
    }
    const float* T = &links.transfer[c * static_cast<size_t>(B2) * 9];
    for (int i = 0; i < B2; ++i)
      for (int j = 0; j < 9; ++j) sh[i] -= T[i * 9 + j] * a[static_cast<size_t>(j)];
  }
  return out;
}

cv::Vec3f shIrradiance(const cv::Vec3f* sh, int bands, const cv::Vec3f& n) {
  return static_cast<float>(CV_PI) * shLobeRadiance(sh, bands, n, 1.0);
}

cv::Vec3f shLobeRadiance(const cv::Vec3f* sh, int bands, const cv::Vec3f& r, double exponent) {
  bands = std::clamp(bands, 1, sh::kMaxBands);
  std::vector<double> y(static_cast<size_t>(bands * bands));
  sh::evaluate(cv::normalize(cv::Vec3d(r)), bands, y.data());
  const std::vector<double> s = sh::phongLobeFactors(std::max(0.0, exponent), bands);
  cv::Vec3d sum(0, 0, 0);
  for (int l = 0; l < bands; ++l)
    for (int m = -l; m <= l; ++m)
      sum += s[static_cast<size_t>(l)] * y[static_cast<size_t>(sh::index(l, m))] * cv::Vec3d(sh[sh::index(l, m)]);
  cv::Vec3f out(sum);
  for (int c = 0; c < 3; ++c)
    if (!std::isfinite(out[c])) out[c] = 0;
  return out;
}

std::vector<cv::Vec3f> gridCaches(const cv::Vec3f& centre, float side, int resolution) {
  std::vector<cv::Vec3f> out;
  const int R = std::max(1, resolution);
  out.reserve(static_cast<size_t>(R * R * R));
  for (int z = 0; z < R; ++z)
    for (int y = 0; y < R; ++y)
      for (int x = 0; x < R; ++x)
        out.push_back(centre + side * cv::Vec3f((x + 0.5f) / R - 0.5f, (y + 0.5f) / R - 0.5f, (z + 0.5f) / R - 0.5f));
  return out;
}

std::vector<cv::Vec3f> interpolateGrid(const std::vector<cv::Vec3f>& cacheSh, const CacheLinks& links,
                                       const cv::Vec3f& centre, float side, int resolution, const cv::Vec3f& x) {
  const int R = std::max(1, resolution);
  const auto B2 = static_cast<size_t>(links.bands * links.bands);
  std::vector<cv::Vec3f> out(B2, cv::Vec3f(0, 0, 0));
  int i0[3];
  float f[3];
  for (int a = 0; a < 3; ++a) {
    float g = (x[a] - (centre[a] - 0.5f * side)) / side * R - 0.5f;
    g = std::clamp(std::isfinite(g) ? g : 0.0f, 0.0f, static_cast<float>(R - 1));
    i0[a] = std::min(static_cast<int>(g), std::max(R - 2, 0));
    f[a] = R > 1 ? g - static_cast<float>(i0[a]) : 0.0f;
  }
  float w[8], sum = 0, plain[8];
  size_t idx[8];
  for (int k = 0; k < 8; ++k) {
    const int dx = k & 1, dy = (k >> 1) & 1, dz = (k >> 2) & 1;
    const int cx = std::min(i0[0] + dx, R - 1), cy = std::min(i0[1] + dy, R - 1), cz = std::min(i0[2] + dz, R - 1);
    idx[k] = static_cast<size_t>((cz * R + cy) * R + cx);
    plain[k] = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
    w[k] = plain[k] * (1.0f - links.backFraction[idx[k]]);
    sum += w[k];
  }
  const bool usePlain = !(sum > 1e-6f);
  if (usePlain) sum = 1.0f;
  for (int k = 0; k < 8; ++k) {
    const float wk = (usePlain ? plain[k] : w[k]) / sum;
    if (wk == 0.0f) continue;
    for (size_t i = 0; i < B2; ++i) out[i] += wk * cacheSh[idx[k] * B2 + i];
  }
  return out;
}

cv::Vec3f toYCoCg(const cv::Vec3f& rgb) {
  const float co = 0.5f * (rgb[0] - rgb[2]);
  const float t = rgb[2] + co;
  const float cg = 0.5f * (rgb[1] - t);
  return {t + cg, co, cg};
}

cv::Vec3f fromYCoCg(const cv::Vec3f& ycocg) {
  const float t = ycocg[0] - ycocg[2];
  const float g = ycocg[0] + ycocg[2];
  const float b = t - ycocg[1];
  return {t + ycocg[1], g, b};
}

std::vector<cv::Vec3f> compressChroma(const std::vector<cv::Vec3f>& sh, int bands, int chromaBands) {
  const auto B2 = static_cast<size_t>(bands * bands);
  const auto keep = static_cast<size_t>(std::clamp(chromaBands, 0, bands) * std::clamp(chromaBands, 0, bands));
  std::vector<cv::Vec3f> out(sh.size());
  for (size_t k = 0; k < sh.size(); ++k) {
    cv::Vec3f y = toYCoCg(sh[k]);
    if (B2 > 0 && k % B2 >= keep) y[1] = y[2] = 0.0f;
    out[k] = fromYCoCg(y);
  }
  return out;
}

uint32_t packRgb9e5(const cv::Vec3f& rgb) {
  constexpr int kBias = 15, kMantissa = 9, kMaxExp = 31;
  const float maxValue = 511.0f / 512.0f * 65536.0f;
  float c[3];
  for (int i = 0; i < 3; ++i) c[i] = rgb[i] > 0.0f ? std::min(rgb[i], maxValue) : 0.0f;  // NaN: 0
  const float m = std::max({c[0], c[1], c[2]});
  int e = std::max(-kBias - 1, static_cast<int>(std::floor(std::log2(std::max(m, 1e-30f))))) + 1 + kBias;
  e = std::clamp(e, 0, kMaxExp);
  double denom = std::ldexp(1.0, e - kBias - kMantissa);
  if (static_cast<int>(std::lround(m / denom)) == (1 << kMantissa)) denom *= 2, ++e;
  uint32_t out = static_cast<uint32_t>(e) << 27;
  for (int i = 0; i < 3; ++i) {
    const auto v = static_cast<uint32_t>(std::min<long>(511, std::lround(c[i] / denom)));
    out |= v << (9 * i);
  }
  return out;
}

cv::Vec3f unpackRgb9e5(uint32_t p) {
  const double scale = std::ldexp(1.0, static_cast<int>(p >> 27) - 15 - 9);
  return {static_cast<float>((p & 511u) * scale), static_cast<float>(((p >> 9) & 511u) * scale),
          static_cast<float>(((p >> 18) & 511u) * scale)};
}

namespace {

constexpr char kMagic[8] = {'M', 'R', 'G', 'I', 'P', 'I', 'C', '1'};

class Writer {
 public:
  explicit Writer(std::ofstream& out) : out_(out) {}
  template <class T>
  void value(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.write(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  template <class T>
  void array(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    value(static_cast<uint64_t>(v.size()));
    if (!v.empty())
      out_.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(T)));
  }

 private:
  std::ofstream& out_;
};

class Reader {
 public:
  explicit Reader(std::vector<char> bytes) : bytes_(std::move(bytes)) {}
  template <class T>
  bool value(T& v) {
    if (bytes_.size() - at_ < sizeof(T)) return false;
    std::memcpy(&v, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return true;
  }
  template <class T>
  bool array(std::vector<T>& v) {
    uint64_t n = 0;
    if (!value(n) || n > (bytes_.size() - at_) / sizeof(T)) return false;
    v.resize(static_cast<size_t>(n));
    if (n) std::memcpy(v.data(), bytes_.data() + at_, static_cast<size_t>(n) * sizeof(T));
    at_ += static_cast<size_t>(n) * sizeof(T);
    return true;
  }
  bool done() const { return at_ == bytes_.size(); }

 private:
  std::vector<char> bytes_;
  size_t at_ = 0;
};

std::vector<float> flatten(const std::vector<cv::Vec3f>& v) {
  std::vector<float> out;
  out.reserve(3 * v.size());
  for (const cv::Vec3f& x : v) out.insert(out.end(), {x[0], x[1], x[2]});
  return out;
}

bool unflatten(const std::vector<float>& f, std::vector<cv::Vec3f>& v) {
  if (f.size() % 3) return false;
  v.resize(f.size() / 3);
  for (size_t i = 0; i < v.size(); ++i) v[i] = {f[3 * i], f[3 * i + 1], f[3 * i + 2]};
  return true;
}

void writeVec3s(Writer& w, const std::vector<cv::Vec3f>& v) { w.array(flatten(v)); }
bool readVec3s(Reader& r, std::vector<cv::Vec3f>& v) {
  std::vector<float> f;
  return r.array(f) && unflatten(f, v);
}

void writeLinks(Writer& w, const CacheLinks& l) {
  w.value(static_cast<int32_t>(l.bands));
  w.value(static_cast<int32_t>(l.links));
  writeVec3s(w, l.positions);
  w.array(l.node), w.array(l.factor), w.array(l.transfer), w.array(l.backFraction);
}

bool readLinks(Reader& r, CacheLinks& l) {
  int32_t bands = 0, links = 0;
  if (!r.value(bands) || !r.value(links) || bands < 1 || bands > sh::kMaxBands || links < 1) return false;
  l.bands = bands, l.links = links;
  if (!readVec3s(r, l.positions) || !r.array(l.node) || !r.array(l.factor) || !r.array(l.transfer) ||
      !r.array(l.backFraction))
    return false;
  const size_t C = l.positions.size(), L = static_cast<size_t>(links), B2 = static_cast<size_t>(bands * bands);
  return l.node.size() == C * L && l.factor.size() == C * L * B2 && l.transfer.size() == C * B2 * 9 &&
         l.backFraction.size() == C;
}

// Surfels: 12 floats (position, normal, albedo, area, barycentric) and their triangles.
void writeSurfels(Writer& w, const std::vector<Surfel>& s) {
  std::vector<float> f;
  std::vector<uint32_t> t;
  for (const Surfel& x : s) {
    f.insert(f.end(), {x.position[0], x.position[1], x.position[2], x.normal[0], x.normal[1], x.normal[2], x.albedo[0],
                       x.albedo[1], x.albedo[2], x.area, x.barycentric[0], x.barycentric[1]});
    t.push_back(x.triangle);
  }
  w.array(f), w.array(t);
}

bool readSurfels(Reader& r, std::vector<Surfel>& s) {
  std::vector<float> f;
  std::vector<uint32_t> t;
  if (!r.array(f) || !r.array(t) || f.size() != 12 * t.size()) return false;
  s.resize(t.size());
  for (size_t i = 0; i < t.size(); ++i) {
    const float* x = &f[12 * i];
    s[i].position = {x[0], x[1], x[2]};
    s[i].normal = {x[3], x[4], x[5]};
    s[i].albedo = {x[6], x[7], x[8]};
    s[i].area = x[9];
    s[i].barycentric = {x[10], x[11]};
    s[i].triangle = t[i];
  }
  return true;
}

// Nodes: 7 floats (position, normal, area) and 4 integers (children, parent, level).
void writeNodes(Writer& w, const std::vector<Node>& nodes) {
  std::vector<float> f;
  std::vector<int32_t> i;
  for (const Node& n : nodes) {
    f.insert(f.end(), {n.position[0], n.position[1], n.position[2], n.normal[0], n.normal[1], n.normal[2], n.area});
    i.insert(i.end(), {n.child[0], n.child[1], n.parent, n.level});
  }
  w.array(f), w.array(i);
}

bool readNodes(Reader& r, std::vector<Node>& nodes) {
  std::vector<float> f;
  std::vector<int32_t> i;
  if (!r.array(f) || !r.array(i) || f.size() % 7 || f.size() / 7 != i.size() / 4 || i.size() % 4) return false;
  nodes.resize(i.size() / 4);
  for (size_t k = 0; k < nodes.size(); ++k) {
    const float* x = &f[7 * k];
    nodes[k].position = {x[0], x[1], x[2]};
    nodes[k].normal = {x[3], x[4], x[5]};
    nodes[k].area = x[6];
    nodes[k].child[0] = i[4 * k], nodes[k].child[1] = i[4 * k + 1], nodes[k].parent = i[4 * k + 2],
    nodes[k].level = i[4 * k + 3];
  }
  return true;
}

template <class Body>
void saveFile(const std::string& path, uint64_t key, const Body& body) {
  namespace fs = std::filesystem;
  const fs::path target(path), temp = target.string() + ".tmp";
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) return;  // a cache that cannot be written is only not kept
    out.write(kMagic, sizeof kMagic);
    Writer w(out);
    w.value(key);
    body(w);
    if (!out) {
      out.close();
      std::error_code ec;
      fs::remove(temp, ec);
      return;
    }
  }
  std::error_code ec;
  fs::rename(temp, target, ec);
  if (ec) fs::remove(temp, ec);
}

std::optional<Reader> openFile(const std::string& path, uint64_t key) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < sizeof kMagic + sizeof(uint64_t) || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    return std::nullopt;
  Reader r(std::vector<char>(bytes.begin() + sizeof kMagic, bytes.end()));
  uint64_t k = 0;
  if (!r.value(k) || k != key) return std::nullopt;
  return r;
}

}  // namespace

void saveMeshPrecompute(const std::string& path, uint64_t key, const MeshPrecompute& p) {
  saveFile(path, key, [&](Writer& w) {
    writeSurfels(w, p.surfels);
    writeNodes(w, p.hierarchy.nodes);
    w.value(static_cast<uint64_t>(p.hierarchy.leaves));
    w.value(p.hierarchy.root);
    w.value(p.hierarchy.eMax);
    w.array(p.receivers.nodes), w.array(p.receivers.ofSurfel);
    writeVec3s(w, p.receivers.positions);
    writeLinks(w, p.receiverLinks);
  });
}

bool loadMeshPrecompute(const std::string& path, uint64_t key, MeshPrecompute& out) {
  auto r = openFile(path, key);
  if (!r) return false;
  MeshPrecompute p;
  uint64_t leaves = 0;
  if (!readSurfels(*r, p.surfels) || !readNodes(*r, p.hierarchy.nodes) || !r->value(leaves) ||
      !r->value(p.hierarchy.root) || !r->value(p.hierarchy.eMax) || !r->array(p.receivers.nodes) ||
      !r->array(p.receivers.ofSurfel) || !readVec3s(*r, p.receivers.positions) || !readLinks(*r, p.receiverLinks) ||
      !r->done())
    return false;
  // The structure the runtime walks: leaves first, children before parents, indices in range.
  const auto n = static_cast<int64_t>(p.hierarchy.nodes.size());
  p.hierarchy.leaves = static_cast<size_t>(leaves);
  if (leaves != p.surfels.size() || (n > 0 && (p.hierarchy.root < 0 || p.hierarchy.root >= n)) ||
      (n == 0 && p.hierarchy.root != -1))
    return false;
  for (int64_t k = static_cast<int64_t>(leaves); k < n; ++k)
    for (int32_t c : p.hierarchy.nodes[static_cast<size_t>(k)].child)
      if (c < 0 || c >= k) return false;
  for (int32_t k : p.receivers.ofSurfel)
    if (k < -1 || k >= static_cast<int64_t>(p.receivers.positions.size())) return false;
  for (int32_t k : p.receiverLinks.node)
    if (k < -1 || k >= n) return false;
  if (p.receiverLinks.positions.size() != p.receivers.positions.size() ||
      p.receivers.ofSurfel.size() != p.surfels.size())
    return false;
  out = std::move(p);
  return true;
}

void saveCacheLinks(const std::string& path, uint64_t key, const CacheLinks& links) {
  saveFile(path, key, [&](Writer& w) { writeLinks(w, links); });
}

bool loadCacheLinks(const std::string& path, uint64_t key, CacheLinks& out) {
  auto r = openFile(path, key);
  CacheLinks l;
  if (!r || !readLinks(*r, l) || !r->done()) return false;
  out = std::move(l);
  return true;
}

}  // namespace mrgi::lighting::pic
