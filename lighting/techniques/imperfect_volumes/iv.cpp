#include "lighting/techniques/imperfect_volumes/iv.h"

#include <algorithm>
#include <cmath>

#include "lighting/sh.h"
#include "reconstruction/light_estimation.h"

namespace mrgi::lighting::iv {

bool Grid::voxelOf(const cv::Vec3d& p, cv::Vec3i& v) const {
  // In float, as the GLSL twin does: a surface lying on a voxel boundary falls on the same side in both.
  for (int a = 0; a < 3; ++a) {
    const float u = (static_cast<float>(p[a]) - static_cast<float>(origin[a])) / static_cast<float>(voxel);
    if (!(u >= 0.0f) || u >= static_cast<float>(resolution)) return false;  // NaN-safe
    v[a] = std::min(static_cast<int>(u), resolution - 1);
  }
  return true;
}

cv::Vec3f trianglePoint(const cv::Vec3f& a, const cv::Vec3f& b, const cv::Vec3f& c, float r1, float r2) {
  const float s = std::sqrt(std::clamp(r1, 0.0f, 1.0f));
  return (1.0f - s) * a + (1.0f - r2) * s * b + r2 * s * c;
}

namespace {

float radicalInverse(uint32_t i, uint32_t base) {
  float f = 1.0f, r = 0.0f;
  while (i > 0) {
    f /= static_cast<float>(base);
    r += f * static_cast<float>(i % base);
    i /= base;
  }
  return r;
}

/// An integer hash (the GLSL twin uses the same constants).
uint32_t hash(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

}  // namespace

cv::Vec2f sampleOf(uint32_t triangle, int j) {
  const uint32_t h = hash(triangle);
  const float o1 = static_cast<float>(h & 0xffffu) / 65536.0f, o2 = static_cast<float>(h >> 16) / 65536.0f;
  const float r1 = radicalInverse(static_cast<uint32_t>(j) + 1u, 2) + o1,
              r2 = radicalInverse(static_cast<uint32_t>(j) + 1u, 3) + o2;
  return {r1 - std::floor(r1), r2 - std::floor(r2)};
}

std::vector<cv::Vec3f> rayDirections(int n) {
  n = std::max(n, 1);
  std::vector<cv::Vec3f> out(static_cast<size_t>(n));
  const double golden = CV_PI * (3.0 - std::sqrt(5.0));
  for (int j = 0; j < n; ++j) {
    const double z = 1.0 - (2.0 * j + 1.0) / n, r = std::sqrt(std::max(0.0, 1.0 - z * z)), phi = golden * j;
    out[static_cast<size_t>(j)] =
        cv::Vec3f(static_cast<float>(r * std::cos(phi)), static_cast<float>(r * std::sin(phi)), static_cast<float>(z));
  }
  return out;
}

Volume::Volume(const Grid& g)
    : grid(g),
      occupancy(g.count(), kEmpty),
      exitantRho(g.count(), cv::Vec4f::all(0)),
      exitantMu(g.count(), cv::Vec4f::all(0)),
      normalRho(g.count(), cv::Vec4f::all(0)),
      normalMu(g.count(), cv::Vec4f::all(0)),
      albedoRho(g.count(), cv::Vec3f::all(0)),
      albedoMu(g.count(), cv::Vec3f::all(0)),
      exitantMuLit(g.count(), cv::Vec4f::all(0)),
      exitantVirtual(g.count(), cv::Vec4f::all(0)) {}

Volume voxelise(const Grid& grid, const std::vector<Point>& points) {
  Volume v(grid);
  for (const Point& p : points) {
    cv::Vec3i c;
    if (!grid.voxelOf(cv::Vec3d(p.position), c)) continue;
    const size_t i = grid.index(c[0], c[1], c[2]);
    v.occupancy[i] |= p.isVirtual ? kVirtual : kReal;
    const auto add = [&](std::vector<cv::Vec4f>& ex, std::vector<cv::Vec4f>& nr, std::vector<cv::Vec3f>& al,
                         const cv::Vec3f& L) {
      ex[i] += cv::Vec4f(L[0], L[1], L[2], 1.0f);
      nr[i] += cv::Vec4f(p.normal[0], p.normal[1], p.normal[2], 0.0f);
      al[i] += p.albedo;
    };
    add(v.exitantRho, v.normalRho, v.albedoRho, p.radianceRho);
    if (p.isVirtual)
      v.exitantVirtual[i] += cv::Vec4f(p.radianceLights[0], p.radianceLights[1], p.radianceLights[2], 1.0f);
    if (!p.isVirtual) {
      add(v.exitantMu, v.normalMu, v.albedoMu, p.radianceMu);
      v.exitantMuLit[i] += cv::Vec4f(p.radianceRho[0], p.radianceRho[1], p.radianceRho[2], 1.0f);
    }
  }
  const auto mean = [](std::vector<cv::Vec4f>& ex, std::vector<cv::Vec3f>& al) {
    for (size_t i = 0; i < ex.size(); ++i)
      if (ex[i][3] > 0) {
        const float inv = 1.0f / ex[i][3];
        for (int k = 0; k < 3; ++k) ex[i][k] *= inv;
        al[i] *= inv;
      }
  };
  mean(v.exitantRho, v.albedoRho);
  mean(v.exitantMu, v.albedoMu);
  for (auto* list : {&v.exitantMuLit, &v.exitantVirtual})
    for (cv::Vec4f& e : *list)
      if (e[3] > 0)
        for (int k = 0; k < 3; ++k) e[k] /= e[3];
  return v;
}

cv::Vec3f unoccludedAmbient(const Ambient& ambient, const cv::Vec3f& n) {
  // As the shading pass: pi * uniform + the SH part's clamped-cosine irradiance.
  std::array<cv::Vec3d, 9> sh;
  for (size_t k = 0; k < sh.size(); ++k) sh[k] = cv::Vec3d(ambient.sh[k]);
  return static_cast<float>(CV_PI) * ambient.uniform + cv::Vec3f(reconstruction::ambientShIrradiance(sh, cv::Vec3d(n)));
}

std::vector<uint8_t> neededVoxels(const Grid& g, const std::vector<uint8_t>& occupied) {
  const int R = g.resolution;
  std::vector<uint8_t> need(g.count(), 0);
  for (int k = 0; k < R; ++k)
    for (int j = 0; j < R; ++j)
      for (int i = 0; i < R; ++i) {
        if (!occupied[g.index(i, j, k)]) continue;
        for (int dk = -1; dk <= 1; ++dk)
          for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
              const int a = i + di, b = j + dj, c = k + dk;
              if (a >= 0 && b >= 0 && c >= 0 && a < R && b < R && c < R) need[g.index(a, b, c)] = 1;
            }
      }
  return need;
}

SurfaceHits marchSurfaces(const Volume& volume, const cv::Vec3i& from, const cv::Vec3f& direction) {
  const Grid& g = volume.grid;
  const float s = static_cast<float>(g.voxel);
  const cv::Vec3f o = cv::Vec3f(g.centre(from[0], from[1], from[2]));
  const float start = 0.5f * std::sqrt(3.0f) * s;
  const int maxSteps = static_cast<int>(std::ceil(std::sqrt(3.0f) * g.resolution)) + 1;
  SurfaceHits hit;
  for (int step = 0; step <= maxSteps; ++step) {
    const float t = start + static_cast<float>(step) * s;
    cv::Vec3i c;
    if (!g.voxelOf(cv::Vec3d(o + t * direction), c)) break;
    const size_t v = g.index(c[0], c[1], c[2]);
    if ((volume.occupancy[v] & kVirtual) && hit.object < 0)
      hit.object = static_cast<int64_t>(v), hit.objectDistance = t;
    if (volume.occupancy[v] & kReal) {
      hit.real = static_cast<int64_t>(v), hit.realDistance = t;
      break;
    }
  }
  return hit;
}

namespace {

/// Radiance the voxel's surface sends towards direction `towards` (unit): its exitant radiance where that
/// direction lies in front of its mean normal, else 0 (its back).
cv::Vec3f exitantTowards(const cv::Vec4f& exitant, const cv::Vec4f& normalSum, const cv::Vec3f& towards) {
  const cv::Vec3f n(normalSum[0], normalSum[1], normalSum[2]);
  if (n.dot(towards) <= 0.0f) return {0, 0, 0};
  return {exitant[0], exitant[1], exitant[2]};
}

/// What one ray from voxel `from` brings: the hit voxel's `exitant` towards the origin within range (nothing
/// when null: ambient occlusion only), else the ambient (when given); the hit is the first voxel with real points
/// (marchSurfaces). In rho `glow` (when given) adds what the first object voxel within range sends towards the
/// origin. `hit`: a surface within range (either kind) was met.
cv::Vec3f rayRadiance(const Volume& volume, bool rho, const Options& o, const Ambient* ambient,
                      const std::vector<cv::Vec4f>* exitant, const std::vector<cv::Vec4f>* glow, const cv::Vec3i& from,
                      const cv::Vec3f& d, bool& hit) {
  const SurfaceHits r = marchSurfaces(volume, from, d);
  cv::Vec3f L(0, 0, 0);
  hit = rho && r.object >= 0 && r.objectDistance <= o.range;
  if (hit && glow) {
    const auto v = static_cast<size_t>(r.object);
    L += exitantTowards((*glow)[v], volume.normalRho[v] - volume.normalMu[v], -d);
  }
  if (r.real >= 0 && r.realDistance <= o.range) {
    hit = true;
    const auto v = static_cast<size_t>(r.real);
    return exitant ? L + exitantTowards((*exitant)[v], volume.normalMu[v], -d) : L;
  }
  return ambient ? L + ambient->radiance(d) : L;
}

/// One gather: per needed voxel, rayRadiance over the directions, projected to SH; adds into `out`.
void gatherPass(const Volume& volume, bool rho, const Options& o, const Ambient* ambient,
                const std::vector<cv::Vec4f>* exitant, const std::vector<cv::Vec4f>* glow,
                const std::vector<cv::Vec3f>& dirs, Incident& out, bool countOcclusion) {
  const Grid& g = volume.grid;
  const int B = out.bands, C = B * B, R = g.resolution;
  std::vector<std::vector<double>> basis(dirs.size());
  for (size_t j = 0; j < dirs.size(); ++j) basis[j] = sh::evaluate(cv::Vec3d(dirs[j]), B);
  const double w = 4.0 * CV_PI / static_cast<double>(dirs.size());
  for (int k = 0; k < R; ++k)
    for (int jj = 0; jj < R; ++jj)
      for (int i = 0; i < R; ++i) {
        const size_t v = g.index(i, jj, k);
        if (!out.computed[v]) continue;
        std::vector<double> acc(static_cast<size_t>(3 * C), 0.0);
        int hits = 0;
        for (size_t j = 0; j < dirs.size(); ++j) {
          bool hit = false;
          const cv::Vec3f L = rayRadiance(volume, rho, o, ambient, exitant, glow, {i, jj, k}, dirs[j], hit);
          hits += hit;
          for (int c = 0; c < 3; ++c)
            if (L[c] != 0.0f)
              for (int q = 0; q < C; ++q)
                acc[static_cast<size_t>(c * C + q)] += L[c] * basis[j][static_cast<size_t>(q)];
        }
        float* dst = out.sh.data() + v * static_cast<size_t>(3 * C);
        for (int q = 0; q < 3 * C; ++q) dst[q] += static_cast<float>(w * acc[static_cast<size_t>(q)]);
        if (countOcclusion) out.occlusion[v] = static_cast<float>(hits) / static_cast<float>(dirs.size());
      }
}

/// The exitant radiance and the objects' light of the first gather (none with no bounces): real surfaces as
/// the objects leave them lit in rho.
const std::vector<cv::Vec4f>* firstExitant(const Volume& volume, bool rho, const Options& o) {
  if (o.bounces <= 0) return nullptr;
  return rho ? &volume.exitantMuLit : &volume.exitantMu;
}
const std::vector<cv::Vec4f>* firstGlow(const Volume& volume, bool rho, const Options& o) {
  return rho && o.bounces > 0 ? &volume.exitantVirtual : nullptr;
}

/// What one ray of the first gather brings (gatherPass with the ambient).
cv::Vec3f firstGatherRadiance(const Volume& volume, bool rho, const Options& o, const Ambient& ambient,
                              const cv::Vec3i& from, const cv::Vec3f& d) {
  bool hit = false;
  return rayRadiance(volume, rho, o, &ambient, firstExitant(volume, rho, o), firstGlow(volume, rho, o), from, d, hit);
}

/// Irradiance about unit n of incident SH c (3 x B^2): sum_l pi s_l(1) c_lm y_lm(n).
cv::Vec3f shIrradiance(const float* c, int B, const cv::Vec3f& n) {
  const std::vector<double> s = sh::phongLobeFactors(1.0, B);
  std::vector<double> y(static_cast<size_t>(B * B));
  sh::evaluate(cv::Vec3d(n), B, y.data());
  cv::Vec3f e(0, 0, 0);
  for (int l = 0; l < B; ++l)
    for (int m = -l; m <= l; ++m) {
      const int q = sh::index(l, m);
      const double f = CV_PI * s[static_cast<size_t>(l)] * y[static_cast<size_t>(q)];
      for (int ch = 0; ch < 3; ++ch) e[ch] += static_cast<float>(f * c[ch * B * B + q]);
    }
  return e;
}

}  // namespace

std::vector<cv::Vec3f> capDirections(const cv::Vec3f& axis, float cosAlpha, int k) {
  std::vector<cv::Vec3f> out;
  if (k <= 0) return out;
  const cv::Vec3f z = cv::normalize(axis);
  const cv::Vec3f a = std::abs(z[0]) < 0.9f ? cv::Vec3f(1, 0, 0) : cv::Vec3f(0, 1, 0);
  const cv::Vec3f x = cv::normalize(a.cross(z)), y = z.cross(x);
  const double golden = CV_PI * (3.0 - std::sqrt(5.0)), c0 = std::clamp(static_cast<double>(cosAlpha), -1.0, 1.0);
  for (int j = 0; j < k; ++j) {
    const double c = 1.0 - (1.0 - c0) * (j + 0.5) / k, s = std::sqrt(std::max(0.0, 1.0 - c * c)), phi = golden * j;
    out.push_back(cv::normalize(static_cast<float>(s * std::cos(phi)) * x + static_cast<float>(s * std::sin(phi)) * y +
                                static_cast<float>(c) * z));
  }
  return out;
}

/// A voxel this far out (times the radius) is outside the bound: kept off the exact radius, where float
/// and double would disagree on voxels whose centres lie on it (the GPU twin uses the same factor).
constexpr double kConeOutside = 1.0001;

std::vector<float> coneCorrection(const Volume& volume, const std::vector<uint8_t>& computed, const Options& options,
                                  const Ambient& ambient, const std::vector<cv::Vec3f>& dirs, const Bound& bound,
                                  int coneRays) {
  const Grid& g = volume.grid;
  const int B = std::clamp(options.bands, 1, sh::kMaxBands), C = B * B, R = g.resolution;
  std::vector<float> out(g.count() * static_cast<size_t>(3 * C), 0.0f);
  if (!(bound.radius > 0) || coneRays <= 0 || dirs.empty()) return out;
  const double wUniform = 4.0 * CV_PI / static_cast<double>(dirs.size());
  for (int k = 0; k < R; ++k)
    for (int j = 0; j < R; ++j)
      for (int i = 0; i < R; ++i) {
        const size_t v = g.index(i, j, k);
        if (!computed[v]) continue;
        const cv::Vec3f c(g.centre(i, j, k));
        const cv::Vec3f axis = bound.centre - c;
        const double d = cv::norm(axis);
        if (!(d > kConeOutside * bound.radius)) continue;
        const double sinA = bound.radius / d, cosA = std::sqrt(std::max(0.0, 1.0 - sinA * sinA));
        const cv::Vec3f u = axis * static_cast<float>(1.0 / d);
        std::vector<double> acc(static_cast<size_t>(3 * C), 0.0);
        const auto add = [&](const cv::Vec3f& w, double weight) {
          const cv::Vec3f diff = firstGatherRadiance(volume, true, options, ambient, {i, j, k}, w) -
                                 firstGatherRadiance(volume, false, options, ambient, {i, j, k}, w);
          if (diff == cv::Vec3f(0, 0, 0)) return;
          const std::vector<double> y = sh::evaluate(cv::Vec3d(w), B);
          for (int ch = 0; ch < 3; ++ch)
            for (int q = 0; q < C; ++q)
              acc[static_cast<size_t>(ch * C + q)] += weight * diff[ch] * y[static_cast<size_t>(q)];
        };
        for (const cv::Vec3f& w : dirs)
          if (w.dot(u) >= cosA) add(w, -wUniform);
        const double omega = 2.0 * CV_PI * (1.0 - cosA);
        for (const cv::Vec3f& w : capDirections(u, static_cast<float>(cosA), coneRays)) add(w, omega / coneRays);
        float* dst = out.data() + v * static_cast<size_t>(3 * C);
        for (int q = 0; q < 3 * C; ++q) dst[q] = static_cast<float>(acc[static_cast<size_t>(q)]);
      }
  return out;
}

Incident gather(const Volume& volume, bool rho, const Options& options, const Ambient& ambient) {
  Options o = options;
  o.rays = std::clamp(o.rays, 1, 1024);
  o.bands = std::clamp(o.bands, 1, sh::kMaxBands);
  o.bounces = std::clamp(o.bounces, 0, 3);
  const Grid& g = volume.grid;
  Incident out;
  out.bands = o.bands;
  const int C = o.bands * o.bands;
  out.computed = o.everyVoxel ? std::vector<uint8_t>(g.count(), 1) : neededVoxels(g, volume.occupancy);
  out.sh.assign(g.count() * static_cast<size_t>(3 * C), 0.0f);
  out.occlusion.assign(g.count(), 0.0f);
  const std::vector<cv::Vec3f> dirs = rayDirections(o.rays);
  // Bounce 0: the ambient where no surface is hit within range (and ambient occlusion).
  gatherPass(volume, rho, o, &ambient, firstExitant(volume, rho, o), firstGlow(volume, rho, o), dirs, out, true);
  out.reflectedSum.assign(g.count(), cv::Vec3f(0, 0, 0));
  // Further bounces: occupied voxels reflect what the previous bounce brought them (no ambient: the
  // ambient stands for light from beyond the volume, already counted).
  if (o.bounces > 1) {
    // The first pass mixed ambient into the incident light; the bounce light alone is the pass without it.
    Incident bounce;
    bounce.bands = o.bands;
    bounce.computed = out.computed;
    bounce.sh.assign(out.sh.size(), 0.0f);
    bounce.occlusion.assign(g.count(), 0.0f);
    gatherPass(volume, rho, o, nullptr, firstExitant(volume, rho, o), firstGlow(volume, rho, o), dirs, bounce, false);
    // The real surfaces reflect the next bounce (in rho too: the objects' own further bounces are the
    // shading pass's reflection of the light they hide).
    const auto& normals = volume.normalMu;
    const auto& albedo = volume.albedoMu;
    for (int b = 1; b < o.bounces; ++b) {
      std::vector<cv::Vec4f> reflected(g.count(), cv::Vec4f::all(0));
      for (size_t v = 0; v < g.count(); ++v) {
        if (!volume.occupied(v, false) || !bounce.computed[v]) continue;
        const cv::Vec3f n(normals[v][0], normals[v][1], normals[v][2]);
        const double len = cv::norm(n);
        if (len <= 0) continue;
        const cv::Vec3f E = shIrradiance(bounce.at(v), o.bands, n * static_cast<float>(1.0 / len));
        for (int c = 0; c < 3; ++c) reflected[v][c] = std::max(0.0f, albedo[v][c] / static_cast<float>(CV_PI) * E[c]);
        reflected[v][3] = 1.0f;
        out.reflectedSum[v] += cv::Vec3f(reflected[v][0], reflected[v][1], reflected[v][2]);
      }
      Incident next;
      next.bands = o.bands;
      next.computed = out.computed;
      next.sh.assign(out.sh.size(), 0.0f);
      next.occlusion.assign(g.count(), 0.0f);
      gatherPass(volume, rho, o, nullptr, &reflected, nullptr, dirs, next, false);
      for (size_t q = 0; q < out.sh.size(); ++q) out.sh[q] += next.sh[q];
      bounce = std::move(next);
    }
  }
  return out;
}

namespace {

/// The first occupied voxel along a ray from x, sampled at t = (k + offset) voxel + from (k = 0, 1, ...), x's
/// own voxel skipped; -1 when a sample leaves the grid (`exit` gets its t). marchFromPoint and marchOuter.
int64_t marchSamples(const Volume& volume, bool rho, const cv::Vec3f& x, const cv::Vec3f& direction, float offset,
                     float from, float* distance, float* exit) {
  const Grid& g = volume.grid;
  const float s = static_cast<float>(g.voxel);
  cv::Vec3i own(-1, -1, -1);
  g.voxelOf(cv::Vec3d(x), own);
  const int maxSteps = static_cast<int>(std::ceil(std::sqrt(3.0f) * g.resolution)) + 1;
  for (int step = 0; step <= maxSteps; ++step) {
    const float t = (static_cast<float>(step) + offset) * s + from;
    cv::Vec3i c;
    if (!g.voxelOf(cv::Vec3d(x + t * direction), c)) {
      if (exit) *exit = t;
      return -1;
    }
    if (c == own) continue;
    const size_t v = g.index(c[0], c[1], c[2]);
    if (volume.occupied(v, rho)) {
      if (distance) *distance = t;
      return static_cast<int64_t>(v);
    }
  }
  return -1;
}

}  // namespace

int64_t marchFromPoint(const Volume& volume, bool rho, const cv::Vec3f& x, const cv::Vec3f& direction, float* distance,
                       float* exit) {
  return marchSamples(volume, rho, x, direction, 0.5f, 0.0f, distance, exit);
}

Grid outerGrid(const Grid& inner, double range, int resolution) {
  Grid g;
  g.resolution = std::max(resolution, 1);
  const double side = inner.voxel * inner.resolution + 2.0 * std::max(range, 0.0);
  g.voxel = side / g.resolution;
  g.origin = inner.origin - cv::Vec3d::all(std::max(range, 0.0));
  return g;
}

int64_t marchOuter(const Volume& outer, const cv::Vec3f& x, const cv::Vec3f& direction, float from, float* distance) {
  return marchSamples(outer, false, x, direction, 0.0f, from, distance, nullptr);
}

std::vector<cv::Vec3f> ambientHiddenByObjects(const Volume& volume, const Options& options, const Ambient& ambient,
                                              const std::vector<cv::Vec3f>& dirs) {
  const Grid& g = volume.grid;
  std::vector<cv::Vec3f> hidden(g.count(), cv::Vec3f(0, 0, 0));
  if (dirs.empty()) return hidden;
  const float w = static_cast<float>(4.0 * CV_PI / static_cast<double>(dirs.size()));
  for (int k = 0; k < g.resolution; ++k)
    for (int j = 0; j < g.resolution; ++j)
      for (int i = 0; i < g.resolution; ++i) {
        const size_t v = g.index(i, j, k);
        if (!(volume.exitantMu[v][3] > 0)) continue;
        const cv::Vec3f nSum(volume.normalMu[v][0], volume.normalMu[v][1], volume.normalMu[v][2]);
        const float len = static_cast<float>(cv::norm(nSum));
        if (!(len > 0)) continue;
        const cv::Vec3f n = nSum / len;
        for (const cv::Vec3f& d : dirs) {
          const float c = n.dot(d);
          if (!(c > 0)) continue;
          // The first voxel the ray meets holds virtual points: an object voxel up to the first real one.
          const SurfaceHits r = marchSurfaces(volume, {i, j, k}, d);
          if (r.object >= 0 && r.objectDistance <= options.range) hidden[v] += ambient.radiance(d) * (c * w);
        }
      }
  return hidden;
}

cv::Vec3f pointGather(const Volume& volume, bool rho, const Incident& incident, const Options& options,
                      const Ambient& ambient, const std::vector<cv::Vec3f>& dirs, const cv::Vec3f& x,
                      const cv::Vec3f& n, const std::vector<cv::Vec3f>* hidden, const Volume* outer) {
  cv::Vec3f change(0, 0, 0);
  if (dirs.empty() || incident.reflectedSum.size() != volume.grid.count()) return change;
  const auto& normals = rho ? volume.normalRho : volume.normalMu;
  const auto& direct = rho ? volume.exitantRho : volume.exitantMuLit;
  const Grid& g = volume.grid;
  // What voxel v's surface sends towards -d; false where it does not face the ray.
  const auto sends = [&](size_t v, const cv::Vec3f& d, cv::Vec3f& L) {
    const cv::Vec3f nSum(normals[v][0], normals[v][1], normals[v][2]);
    if (!(nSum.dot(-d) > 0)) return false;
    L = {0, 0, 0};
    if (options.bounces > 0) {
      L = cv::Vec3f(direct[v][0], direct[v][1], direct[v][2]);
      if (!rho && hidden && hidden->size() == g.count())
        for (int ch = 0; ch < 3; ++ch)
          L[ch] = std::max(0.0f, L[ch] - volume.albedoMu[v][ch] / static_cast<float>(CV_PI) * (*hidden)[v][ch]);
    }
    L += incident.reflectedSum[v];
    return true;
  };
  for (const cv::Vec3f& d : dirs) {
    const float c = n.dot(d);
    if (!(c > 0)) continue;
    float t = 0, exit = 0;
    const int64_t h = marchFromPoint(volume, rho, x, d, &t, &exit);
    if (h < 0 && outer && exit <= options.range) {
      // Past the grid: the outer volume's real surfaces.
      const int64_t o = marchOuter(*outer, x, d, exit, &t);
      if (o < 0 || t > options.range) continue;
      const auto v = static_cast<size_t>(o);
      const cv::Vec3f nSum(outer->normalMu[v][0], outer->normalMu[v][1], outer->normalMu[v][2]);
      cv::Vec3f L(0, 0, 0);
      if (nSum.dot(-d) > 0 && options.bounces > 0)
        L = cv::Vec3f(outer->exitantMuLit[v][0], outer->exitantMuLit[v][1], outer->exitantMuLit[v][2]);
      change += (L - ambient.radiance(d)) * c;
      continue;
    }
    if (h < 0 || t > options.range) continue;
    // The surface's light at the hit, interpolated trilinearly between the centres of the occupied voxels
    // around it that face the ray (the hit voxel's alone would jump from pixel to pixel as neighbouring rays
    // cross voxel boundaries: a texture finer than the voxels, a tag's cells, mottles the object).
    const cv::Vec3f p = x + t * d;
    const cv::Vec3f q = (p - cv::Vec3f(g.origin)) * static_cast<float>(1.0 / g.voxel) - cv::Vec3f(0.5f, 0.5f, 0.5f);
    const cv::Vec3i base(static_cast<int>(std::floor(q[0])), static_cast<int>(std::floor(q[1])),
                         static_cast<int>(std::floor(q[2])));
    const cv::Vec3f f =
        q - cv::Vec3f(static_cast<float>(base[0]), static_cast<float>(base[1]), static_cast<float>(base[2]));
    cv::Vec3f sum(0, 0, 0), L(0, 0, 0);
    float wSum = 0;
    for (int corner = 0; corner < 8; ++corner) {
      const cv::Vec3i k = base + cv::Vec3i(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
      if (k[0] < 0 || k[1] < 0 || k[2] < 0 || k[0] >= g.resolution || k[1] >= g.resolution || k[2] >= g.resolution)
        continue;
      const size_t v = g.index(k[0], k[1], k[2]);
      cv::Vec3f Lv;
      if (!volume.occupied(v, rho) || !sends(v, d, Lv)) continue;
      float w = 1;
      for (int a = 0; a < 3; ++a) w *= ((corner >> a) & 1) ? f[a] : 1 - f[a];
      sum += w * Lv, wSum += w;
    }
    if (wSum > 1e-6f)
      L = sum / wSum;
    else if (!sends(static_cast<size_t>(h), d, L))
      L = {0, 0, 0};
    change += (L - ambient.radiance(d)) * c;
  }
  return change * static_cast<float>(4.0 * CV_PI / static_cast<double>(dirs.size()));
}

std::vector<std::pair<size_t, float>> readVoxels(const Volume& volume, const std::vector<uint8_t>& computed,
                                                 const cv::Vec3f& x, const cv::Vec3f& n) {
  const Grid& g = volume.grid;
  const float s = static_cast<float>(g.voxel);
  const cv::Vec3f p = x + 0.5f * s * n;
  cv::Vec3i own(-1, -1, -1), centre;
  g.voxelOf(cv::Vec3d(x), own);
  if (computed.size() != g.count() || !g.voxelOf(cv::Vec3d(p), centre)) return {};
  struct Candidate {
    float d2, w;
    size_t v;
    bool occupied;
  };
  std::vector<Candidate> cands;
  for (int dk = -1; dk <= 1; ++dk)
    for (int dj = -1; dj <= 1; ++dj)
      for (int di = -1; di <= 1; ++di) {
        const cv::Vec3i c = centre + cv::Vec3i(di, dj, dk);
        if (c == own) continue;
        if (c[0] < 0 || c[1] < 0 || c[2] < 0 || c[0] >= g.resolution || c[1] >= g.resolution || c[2] >= g.resolution)
          continue;
        const size_t v = g.index(c[0], c[1], c[2]);
        if (!computed[v]) continue;
        const cv::Vec3f q = cv::Vec3f(g.centre(c[0], c[1], c[2]));
        const cv::Vec3f to = q - x;
        const float len = static_cast<float>(cv::norm(to));
        const float cosT = len > 0 ? n.dot(to) / len : 0.0f;
        if (!(cosT > 0.0f)) continue;
        const cv::Vec3f dp = q - p;
        cands.push_back({dp.dot(dp), cosT, v, volume.occupancy[v] != kEmpty});
      }
  if (std::any_of(cands.begin(), cands.end(), [](const Candidate& c) { return !c.occupied; }))
    cands.erase(std::remove_if(cands.begin(), cands.end(), [](const Candidate& c) { return c.occupied; }), cands.end());
  const size_t keep = std::min<size_t>(6, cands.size());
  std::partial_sort(cands.begin(), cands.begin() + static_cast<std::ptrdiff_t>(keep), cands.end(),
                    [](const Candidate& a, const Candidate& b) { return a.d2 < b.d2 || (a.d2 == b.d2 && a.v < b.v); });
  std::vector<std::pair<size_t, float>> out;
  for (size_t k = 0; k < keep; ++k) out.emplace_back(cands[k].v, cands[k].w);
  return out;
}

cv::Vec3f irradiance(const Volume& volume, const Incident& incident, const cv::Vec3f& x, const cv::Vec3f& n) {
  if (incident.bands <= 0 || incident.sh.empty()) return {0, 0, 0};
  const auto chosen = readVoxels(volume, incident.computed, x, n);
  if (chosen.empty()) return {0, 0, 0};
  const int B = incident.bands, C = B * B;
  std::vector<float> c(static_cast<size_t>(3 * C), 0.0f);
  float wsum = 0;
  for (const auto& [v, w] : chosen) {
    const float* src = incident.at(v);
    for (int q = 0; q < 3 * C; ++q) c[static_cast<size_t>(q)] += w * src[q];
    wsum += w;
  }
  for (float& v : c) v /= wsum;
  return shIrradiance(c.data(), B, n);
}

float occlusion(const Volume& volume, const Incident& incident, const cv::Vec3f& x, const cv::Vec3f& n) {
  if (incident.occlusion.empty()) return -1.0f;
  const auto chosen = readVoxels(volume, incident.computed, x, n);
  float sum = 0, wsum = 0;
  for (const auto& [v, w] : chosen) sum += w * incident.occlusion[v], wsum += w;
  return wsum > 0 ? sum / wsum : -1.0f;
}

}  // namespace mrgi::lighting::iv
