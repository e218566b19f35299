#include "groundtruth/path_tracer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>
#include <thread>
#include <vector>

#include "capture/colour.h"
#include "groundtruth/brdf.h"

namespace mrgi::groundtruth {
namespace {

float lum(const cv::Vec3f& c) { return static_cast<float>(capture::luminance(cv::Vec3d(c))); }

/// SplitMix64 finaliser: decorrelates the per-sample seeds.
uint64_t mix(uint64_t z) {
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

/// Unit vector with polar angle acos(cosTheta) and azimuth phi about axis a.
cv::Vec3f aroundAxis(cv::Vec3f a, float cosTheta, float phi) {
  // Orthonormal basis from a unit vector (branchless, Duff et al. 2017).
  const float sign = std::copysign(1.0f, a[2]);
  const float p = -1.0f / (sign + a[2]);
  const float q = a[0] * a[1] * p;
  const cv::Vec3f t(1.0f + sign * a[0] * a[0] * p, sign * q, -sign * a[0]);
  const cv::Vec3f b(q, sign + a[1] * a[1] * p, -a[1]);
  const float sinTheta = std::sqrt(std::max(0.f, 1.f - cosTheta * cosTheta));
  return sinTheta * std::cos(phi) * t + sinTheta * std::sin(phi) * b + cosTheta * a;
}

/// Runs rows [0, rows) on `threads` workers plus the calling thread, which reports progress.
template <typename RowFn>
void forEachRow(int rows, int threads, const std::function<void(double)>& progress, RowFn&& row) {
  std::atomic<int> next{0}, done{0};
  auto work = [&](bool report) {
    for (int y; (y = next.fetch_add(1)) < rows;) {
      row(y);
      const int d = done.fetch_add(1) + 1;
      if (report && progress) progress(static_cast<double>(d) / rows);
    }
  };
  const int n = threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (int i = 1; i < n; ++i) pool.emplace_back(work, false);
  work(true);
  for (auto& t : pool) t.join();
  if (progress) progress(1.0);
}
}  // namespace

void cameraRay(const PinholeCamera& c, double x, double y, cv::Vec3f& origin, cv::Vec3f& dir) {
  const capture::Intrinsics& k = c.intrinsics;
  const cv::Matx44d& T = c.T_world_camera;
  const cv::Vec3d d((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0);
  const cv::Vec3d w(T(0, 0) * d[0] + T(0, 1) * d[1] + T(0, 2) * d[2], T(1, 0) * d[0] + T(1, 1) * d[1] + T(1, 2) * d[2],
                    T(2, 0) * d[0] + T(2, 1) * d[1] + T(2, 2) * d[2]);
  origin = cv::Vec3f(static_cast<float>(T(0, 3)), static_cast<float>(T(1, 3)), static_cast<float>(T(2, 3)));
  dir = cv::normalize(cv::Vec3f(static_cast<float>(w[0]), static_cast<float>(w[1]), static_cast<float>(w[2])));
}

PathTracer::PathTracer(const RayCaster& caster, PathTraceOptions options)
    : caster_(caster), options_(std::move(options)) {}

cv::Vec3f PathTracer::trace(cv::Vec3f origin, cv::Vec3f dir, cv::RNG& rng, bool seeLights) const {
  const Scene& scene = caster_.scene();
  const EnvironmentMap* env = scene.environmentMap.get();
  cv::Vec3f L(0, 0, 0), beta(1, 1, 1);
  float lastPdf = 0;  // pdf of the BRDF-sampled direction that led here (0: a camera ray)
  auto mis = [](float a, float b) { return a * a / (a * a + b * b); };  // power heuristic
  for (int depth = 0;; ++depth) {
    const auto hit = caster_.intersect(origin, dir, 1e-4f, 1e30f, depth == 0 && seeLights);
    if (!hit) {
      L += beta.mul(scene.environment);
      if (env) {
        // Found by the BRDF: weighted against next-event estimation of the same direction.
        const float w = lastPdf > 0.f ? mis(lastPdf, env->pdf(dir)) : 1.f;
        L += beta.mul(env->radiance(dir)) * w;
      }
      break;
    }
    if (hit->light >= 0) {  // only camera rays see a light's sphere; paths find lights by next-event estimation
      L += beta.mul(caster_.shadeDirect(*hit));
      break;
    }
    const Material& m = scene.materials[hit->material];
    L += beta.mul(m.emission);
    const cv::Vec3f n = hit->shading, g = hit->normal, wo = -dir;
    const cv::Vec3f refl = 2.f * n.dot(wo) * n - wo;
    const float k = m.exponent, ck = phongNormalisation(k);
    const bool glossy = lum(m.specular) > 0.f;
    // f(wi) cos(theta_i) of the real-time material: the glossy term carries no cosine (see Material).
    auto fcos = [&](cv::Vec3f wi, float cosI) -> cv::Vec3f {
      cv::Vec3f f = hit->albedo * (cosI / std::numbers::pi_v<float>);
      if (glossy) f += m.specular * (ck * phongPower(refl.dot(wi), k));
      return f;
    };
    for (size_t i = 0; i < scene.lights.size(); ++i) {
      const RayCaster::Incident in = caster_.incident(i, hit->position, g);
      const float cosI = n.dot(in.direction);
      if (cosI > 0.f && lum(in.irradiance) > 0.f) L += beta.mul(fcos(in.direction, cosI).mul(in.irradiance));
    }
    // How the next direction is drawn: the diffuse lobe (cosine-weighted) or the glossy one, by their
    // reflectance; bsdfPdf is that mixture's pdf per steradian.
    const float wd = lum(hit->albedo), ws = glossy ? lum(m.specular) : 0.f;
    const float pd = wd + ws > 0.f ? wd / (wd + ws) : 1.f;
    auto bsdfPdf = [&](cv::Vec3f wi, float cosI) {
      float p = pd * cosI / std::numbers::pi_v<float>;
      if (ws > 0.f)
        p += (1.f - pd) * (k <= 0.f ? 1.f / (2.f * std::numbers::pi_v<float>) : ck * phongPower(refl.dot(wi), k));
      return p;
    };
    const bool continues = depth < options_.bounces && wd + ws > 0.f;
    if (env) {
      // Next-event estimation of the environment (the BRDF finds it too while the path continues: MIS).
      const float e0 = rng.uniform(0.f, 1.f), e1 = rng.uniform(0.f, 1.f), e2 = rng.uniform(0.f, 1.f);
      const EnvironmentMap::Sample es = env->sample(e0, e1, e2);
      const float cosI = n.dot(es.direction);
      if (es.pdf > 0.f && cosI > 0.f && g.dot(es.direction) > 0.f &&
          !caster_.occluded(hit->position + 1e-4f * g, es.direction, 0.f, 1e30f)) {
        const float w = continues ? mis(es.pdf, bsdfPdf(es.direction, cosI)) : 1.f;
        L += beta.mul(fcos(es.direction, cosI).mul(es.radiance)) * (w / es.pdf);
      }
    }
    if (!continues) break;
    const float u0 = rng.uniform(0.f, 1.f), u1 = rng.uniform(0.f, 1.f), u2 = rng.uniform(0.f, 1.f);
    const float phi = 2.f * std::numbers::pi_v<float> * u2;
    cv::Vec3f wi;
    if (u0 < pd)
      wi = aroundAxis(n, std::sqrt(1.f - u1), phi);
    else if (k <= 0.f)
      wi = aroundAxis(n, 1.f - u1, phi);  // k = 0: uniform over the hemisphere
    else
      wi = aroundAxis(refl, std::pow(u1, 1.f / (k + 1.f)), phi);
    const float cosI = n.dot(wi);
    if (!(cosI > 0.f) || g.dot(wi) <= 0.f) break;
    const float pdf = bsdfPdf(wi, cosI);
    if (!(pdf > 0.f)) break;
    beta = beta.mul(fcos(wi, cosI)) * (1.f / pdf);
    lastPdf = pdf;
    origin = hit->position + 1e-4f * g;
    dir = wi;
  }
  return L;
}

cv::Mat PathTracer::render(const PinholeCamera& camera) const {
  const int W = camera.intrinsics.width, H = camera.intrinsics.height;
  cv::Mat out(H, W, CV_32FC3, cv::Scalar::all(0));
  const int base = std::max(1, options_.spp), focused = std::max(base, options_.focusSpp);
  forEachRow(H, options_.threads, options_.progress, [&](int y) {
    for (int x = 0; x < W; ++x) {
      const int spp = options_.focus.contains(cv::Point(x, y)) ? focused : base;
      cv::Vec3f sum(0, 0, 0);
      const uint64_t pixel = mix(options_.seed ^ mix(static_cast<uint64_t>(y) * 65536u + static_cast<uint64_t>(x)));
      for (int s = 0; s < spp; ++s) {
        cv::RNG rng(mix(pixel + static_cast<uint64_t>(s)) | 1u);
        double px = x, py = y;
        if (options_.jitter) px += rng.uniform(-0.5, 0.5), py += rng.uniform(-0.5, 0.5);
        cv::Vec3f o, d;
        cameraRay(camera, px, py, o, d);
        sum += trace(o, d, rng);
      }
      out.at<cv::Vec3f>(y, x) = sum * (1.f / static_cast<float>(spp));
    }
  });
  return out;
}

cv::Mat DifferentialImages::delta() const {
  cv::Mat d = rho - mu;
  rho.copyTo(d, mask);
  return d;
}

cv::Mat virtualMask(const RayCaster& caster, const PinholeCamera& camera) {
  cv::Mat mask(camera.intrinsics.height, camera.intrinsics.width, CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      cv::Vec3f o, d;
      cameraRay(camera, x, y, o, d);
      const auto hit = caster.intersect(o, d, 1e-4f, 1e30f, false);
      if (hit && caster.scene().materials[hit->material].isVirtual) mask.at<uchar>(y, x) = 255;
    }
  return mask;
}

cv::Mat partlyVirtualMask(const RayCaster& caster, const PinholeCamera& camera, int n, cv::Rect region) {
  const int W = camera.intrinsics.width, H = camera.intrinsics.height;
  cv::Mat mask(H, W, CV_8UC1, cv::Scalar(0));
  n = std::clamp(n, 1, 16);
  region = (region.empty() ? cv::Rect(0, 0, W, H) : region) & cv::Rect(0, 0, W, H);
  for (int y = region.y; y < region.y + region.height; ++y)
    for (int x = region.x; x < region.x + region.width; ++x) {
      int hits = 0;
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          cv::Vec3f o, d;
          cameraRay(camera, x - 0.5 + (i + 0.5) / n, y - 0.5 + (j + 0.5) / n, o, d);
          const auto hit = caster.intersect(o, d, 1e-4f, 1e30f, false);
          hits += hit && caster.scene().materials[hit->material].isVirtual;
        }
      if (hits > 0 && hits < n * n) mask.at<uchar>(y, x) = 255;
    }
  return mask;
}

cv::Rect virtualFocus(const Scene& scene, const PinholeCamera& camera, double grow) {
  cv::Vec3d lo(1e30, 1e30, 1e30), hi(-1e30, -1e30, -1e30);
  bool any = false;
  for (size_t t = 0; t < scene.triangles.size(); ++t) {
    if (!scene.materials[static_cast<size_t>(scene.triangleMaterial[t])].isVirtual) continue;
    for (int k = 0; k < 3; ++k) {
      const cv::Vec3d p(scene.vertices[static_cast<size_t>(scene.triangles[t][k])]);
      for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], p[c]), hi[c] = std::max(hi[c], p[c]);
      any = true;
    }
  }
  if (!any) return {};
  const cv::Vec3d centre = 0.5 * (lo + hi);
  const double r = 0.5 * cv::norm(hi - lo) * (1.0 + grow);
  // The grown sphere's corners of its box, projected; a corner behind the camera makes the whole image the focus.
  const capture::Pose T = capture::inversePose(camera.T_world_camera);
  const capture::Intrinsics& k = camera.intrinsics;
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  for (int c = 0; c < 8; ++c) {
    const cv::Vec3d p = centre + cv::Vec3d(c & 1 ? r : -r, c & 2 ? r : -r, c & 4 ? r : -r);
    const cv::Vec4d q = T * cv::Vec4d(p[0], p[1], p[2], 1.0);
    if (q[2] <= 1e-3) return cv::Rect(0, 0, k.width, k.height);
    const double u = k.fx * q[0] / q[2] + k.cx, v = k.fy * q[1] / q[2] + k.cy;
    x0 = std::min(x0, u), x1 = std::max(x1, u), y0 = std::min(y0, v), y1 = std::max(y1, v);
  }
  const cv::Rect box(
      cv::Point(static_cast<int>(std::floor(std::max(x0, -1.0))), static_cast<int>(std::floor(std::max(y0, -1.0)))),
      cv::Point(static_cast<int>(std::ceil(std::min(x1, k.width + 1.0))) + 1,
                static_cast<int>(std::ceil(std::min(y1, k.height + 1.0))) + 1));
  return box & cv::Rect(0, 0, k.width, k.height);
}

DifferentialImages renderDifferential(const Scene& withObjects, const Scene& realOnly, const PinholeCamera& camera,
                                      const PathTraceOptions& options) {
  DifferentialImages out;
  const RayCaster rhoCaster(withObjects), muCaster(realOnly);
  auto half = [&](double offset) {
    PathTraceOptions o = options;
    if (options.progress) o.progress = [&options, offset](double f) { options.progress(offset + 0.5 * f); };
    return o;
  };
  out.rho = PathTracer(rhoCaster, half(0.0)).render(camera);
  out.mu = PathTracer(muCaster, half(0.5)).render(camera);
  out.mask = virtualMask(rhoCaster, camera);
  return out;
}

}  // namespace mrgi::groundtruth
