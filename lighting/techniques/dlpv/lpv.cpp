#include "lighting/techniques/dlpv/lpv.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "lighting/sh.h"

namespace mrgi::lighting {

namespace {
using sh::kY00;
using sh::kY1;
constexpr float kCos0 = sh::kCosineBand0;
constexpr float kCos1 = sh::kCosineBand1;

const cv::Vec3i kAxes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

float dot4(const std::array<float, 4>& a, const std::array<float, 4>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
}

bool sameTexel(const RsmTexels& a, const RsmTexels& b, int x, int y) {
  for (auto [ma, mb] :
       {std::pair{&a.position, &b.position}, {&a.normal, &b.normal}, {&a.flux, &b.flux}, {&a.direct, &b.direct}})
    if (std::memcmp(&ma->at<cv::Vec4f>(y, x), &mb->at<cv::Vec4f>(y, x), sizeof(cv::Vec4f)) != 0) return false;
  return true;
}

bool cellOf(const LpvGrid& g, const cv::Vec3f& p, cv::Vec3i& cell) {
  for (int k = 0; k < 3; ++k) {
    const float c = std::floor((p[k] - static_cast<float>(g.origin[k])) / static_cast<float>(g.cellSize));
    if (!(c >= 0 && c < g.resolution)) return false;
    cell[k] = static_cast<int>(c);
  }
  return true;
}
}  // namespace

LpvGrid fitGrid(const cv::Vec3d& lo, const cv::Vec3d& hi, double sizeFactor, int resolution) {
  const cv::Vec3d extent = hi - lo;
  const double edge = std::max({extent[0], extent[1], extent[2], 1e-3});
  LpvGrid g;
  g.resolution = resolution;
  g.cellSize = edge * sizeFactor / resolution;
  g.origin = 0.5 * (lo + hi) - cv::Vec3d::all(0.5 * g.side());
  return g;
}

LpvGrid gridIn(const Region& region, int resolution) {
  LpvGrid g;
  g.resolution = resolution;
  g.cellSize = region.side / resolution;
  g.origin = region.origin;
  return g;
}

std::array<float, 4> cosineLobe(const cv::Vec3f& n) { return {kCos0, kCos1 * n[1], kCos1 * n[2], kCos1 * n[0]}; }
std::array<float, 4> basis(const cv::Vec3f& d) { return {kY00, kY1 * d[1], kY1 * d[2], kY1 * d[0]}; }

void injectReference(const LpvGrid& grid, const RsmTexels& source, const RsmTexels* other, const InjectParams& params,
                     LpvVolumeCpu& volume) {
  CV_Assert(volume.resolution == grid.resolution);
  const float half = 0.5f * static_cast<float>(grid.cellSize);
  for (int y = 0; y < source.position.rows; ++y)
    for (int x = 0; x < source.position.cols; ++x) {
      const cv::Vec4f p = source.position.at<cv::Vec4f>(y, x);
      if (p[3] < 0.5f) continue;
      if (params.skipIdentical && other && sameTexel(source, *other, x, y)) continue;
      const cv::Vec3f pos(p[0], p[1], p[2]);
      auto add = [&](const cv::Vec3f& at, const cv::Vec3f& dir, const cv::Vec3f& flux) {
        cv::Vec3i c;
        if (!cellOf(grid, at, c)) return;
        const auto lobe = cosineLobe(dir);
        CellSh& cell = volume.at(c[0], c[1], c[2]);
        for (int ch = 0; ch < 3; ++ch)
          for (int i = 0; i < 4; ++i) cell[ch][i] += params.sign * flux[ch] / std::numbers::pi_v<float> * lobe[i];
      };
      if (params.mode & kInjectIndirect) {
        const cv::Vec4f n = source.normal.at<cv::Vec4f>(y, x);
        const cv::Vec4f f = source.flux.at<cv::Vec4f>(y, x);
        const cv::Vec3f nn(n[0], n[1], n[2]);
        add(pos + nn * half, nn, cv::Vec3f(f[0], f[1], f[2]));
      }
      if (params.mode & kInjectDirect) {
        cv::Vec3f l = params.lightType == LightType::Directional ? params.lightDirection : pos - params.lightPosition;
        const float len = static_cast<float>(cv::norm(l));
        if (len <= 0) continue;
        l /= len;
        const cv::Vec4f f = source.direct.at<cv::Vec4f>(y, x);
        const float s = static_cast<float>(kDirectLobeScale);
        add(pos - l * half, l, cv::Vec3f(f[0], f[1], f[2]) * s);
      }
    }
}

float dampingFactor(const std::array<float, 4>& c, const cv::Vec3f& d, float damping) {
  if (damping <= 0.0f) return 1.0f;
  const cv::Vec3f c1(c[3], c[1], c[2]);  // (x, y, z) from the (y, z, x) band-1 order
  const float len1 = static_cast<float>(cv::norm(c1));
  const float c0 = std::abs(c[0]);
  if (len1 <= 0.0f || c0 <= 0.0f) return 1.0f;
  const float r = std::min(1.0f, 0.8660254f * len1 / c0);
  const cv::Vec3f m = c1 * ((c[0] >= 0.0f ? 1.0f : -1.0f) / len1);
  return 1.0f - damping * r * (1.0f - std::max(0.0f, d.dot(m)));
}

LpvVolumeCpu propagateReference(const LpvGrid& grid, const LpvVolumeCpu& injected, int steps, float damping,
                                bool clampNegative, const LpvVolumeCpu* late, int lateSteps,
                                const std::function<void(int, const LpvVolumeCpu&)>& afterEachStep) {
  const int res = grid.resolution;
  LpvVolumeCpu accum = injected, current = injected, next(res);
  const float sideDen = 1.0f / std::sqrt(1.25f);
  const int lateAt = std::max(0, steps - lateSteps);
  auto addLate = [&] {
    for (size_t n = 0; n < accum.cells.size(); ++n)
      for (int ch = 0; ch < 3; ++ch)
        for (int c = 0; c < 4; ++c) {
          accum.cells[n][ch][c] += late->cells[n][ch][c];
          current.cells[n][ch][c] += late->cells[n][ch][c];
        }
  };
  for (int step = 0; step <= steps; ++step) {
    if (late && step == lateAt) addLate();
    if (step == steps) break;
    for (int k = 0; k < res; ++k)
      for (int j = 0; j < res; ++j)
        for (int i = 0; i < res; ++i) {
          CellSh out{};
          for (const cv::Vec3i& d : kAxes) {
            const int si = i - d[0], sj = j - d[1], sk = k - d[2];
            if (si < 0 || sj < 0 || sk < 0 || si >= res || sj >= res || sk >= res) continue;
            const CellSh& src = current.at(si, sj, sk);
            const cv::Vec3f dv(static_cast<float>(d[0]), static_cast<float>(d[1]), static_cast<float>(d[2]));
            std::array<float, 4> lum;
            for (int c = 0; c < 4; ++c) lum[c] = 0.2126f * src[0][c] + 0.7152f * src[1][c] + 0.0722f * src[2][c];
            const float w = dampingFactor(lum, dv, damping);
            for (const cv::Vec3i& f : kAxes) {
              if (f == -d) continue;  // the shared face
              const cv::Vec3f fv(static_cast<float>(f[0]), static_cast<float>(f[1]), static_cast<float>(f[2]));
              const bool front = f == d;
              const cv::Vec3f dir = front ? dv : (dv + 0.5f * fv) * sideDen;
              const float solid = static_cast<float>(front ? kFrontFaceSolidAngle : kSideFaceSolidAngle);
              const auto y = basis(dir);
              const auto lobe = cosineLobe(fv);
              for (int ch = 0; ch < 3; ++ch) {
                float flux = w * solid * dot4(src[ch], y);
                if (clampNegative) flux = std::max(flux, 0.0f);
                for (int c = 0; c < 4; ++c) out[ch][c] += flux / std::numbers::pi_v<float> * lobe[c];
              }
            }
          }
          next.at(i, j, k) = out;
        }
    for (size_t n = 0; n < accum.cells.size(); ++n)
      for (int ch = 0; ch < 3; ++ch)
        for (int c = 0; c < 4; ++c) accum.cells[n][ch][c] += next.cells[n][ch][c];
    std::swap(current, next);
    if (afterEachStep) afterEachStep(step + 1, accum);
  }
  return accum;
}

cv::Vec3f irradianceReference(const LpvGrid& grid, const LpvVolumeCpu& volume, const cv::Vec3f& position,
                              const cv::Vec3f& normal) {
  const int res = grid.resolution;
  const float cell = static_cast<float>(grid.cellSize);
  const cv::Vec3f p = position + normal * (0.5f * cell);
  float t[3];
  int i0[3];
  for (int k = 0; k < 3; ++k) {
    const float u = (p[k] - static_cast<float>(grid.origin[k])) / (cell * res);
    if (!(u >= 0.0f && u <= 1.0f)) return {0, 0, 0};
    const float x = u * res - 0.5f;  // texel space of GL_LINEAR sampling
    const float f = std::floor(x);
    i0[k] = static_cast<int>(f);
    t[k] = x - f;
  }
  CellSh c{};
  for (int corner = 0; corner < 8; ++corner) {
    int idx[3];
    float w = 1.0f;
    for (int k = 0; k < 3; ++k) {
      const int b = (corner >> k) & 1;
      idx[k] = std::clamp(i0[k] + b, 0, res - 1);  // clamp to edge
      w *= b ? t[k] : 1.0f - t[k];
    }
    const CellSh& s = volume.at(idx[0], idx[1], idx[2]);
    for (int ch = 0; ch < 3; ++ch)
      for (int n = 0; n < 4; ++n) c[ch][n] += w * s[ch][n];
  }
  const auto y = basis(-normal);
  const float inv = 1.0f / (cell * cell);
  cv::Vec3f e;
  for (int ch = 0; ch < 3; ++ch)
    e[ch] = inv * (std::numbers::pi_v<float> * c[ch][0] * y[0] +
                   (2.0f * std::numbers::pi_v<float> / 3.0f) * (c[ch][1] * y[1] + c[ch][2] * y[2] + c[ch][3] * y[3]));
  return e;
}

cv::Vec3d totalFlux(const LpvVolumeCpu& volume) {
  cv::Vec3d t(0, 0, 0);
  for (const auto& c : volume.cells)
    for (int ch = 0; ch < 3; ++ch) t[ch] += 2.0 * std::sqrt(CV_PI) * c[ch][0];
  return t;
}

}  // namespace mrgi::lighting
