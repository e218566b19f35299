#include "reconstruction/depth_filter.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

namespace mrgi::reconstruction {
namespace {

// Border handling of every window statistic; the same as OpenCV's guided filter (parity test).
constexpr int kBorder = cv::BORDER_REFLECT;

void boxMean(const cv::Mat& m, int r, cv::Mat& out) {
  cv::boxFilter(m, out, CV_32F, cv::Size(2 * r + 1, 2 * r + 1), cv::Point(-1, -1), true, kBorder);
}

/// The guided filter's window statistics, kept from call to call by each thread that filters: a frame's filter
/// fills some fifty megabytes of them, and memory fresh from the system each frame costs a page fault per page
/// (as much time again as the arithmetic). create() reuses them while the frame's size stays.
struct GuidedScratch {
  cv::Mat sums[4], means[4], coef, weight, spread, meanP, meanCoef, meanWeight, median;
};
GuidedScratch& guidedScratch() {
  thread_local GuidedScratch scratch;
  return scratch;
}

/// Rows 0..h-1, split over OpenCV's workers; every row is independent and written by one worker only, so
/// the result is the same as one after the other.
template <typename F>
void forRows(int h, const F& row) {
  cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) row(y);
  });
}

}  // namespace

cv::Mat sanitizeDepth(const cv::Mat& depth, float minDepth, float maxDepth) {
  CV_Assert(depth.type() == CV_32FC1);
  cv::Mat out(depth.size(), CV_32FC1);
  for (int y = 0; y < depth.rows; ++y) {
    const float* d = depth.ptr<float>(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < depth.cols; ++x)
      o[x] = (std::isfinite(d[x]) && d[x] >= minDepth && d[x] <= maxDepth) ? d[x] : 0.f;
  }
  return out;
}

cv::Mat guideFromColour(const cv::Mat& colour) {
  cv::Mat c3 = colour;
  if (colour.channels() == 1) cv::cvtColor(colour, c3, cv::COLOR_GRAY2RGB);
  CV_Assert(c3.channels() == 3);
  cv::Mat out;
  const double scale = c3.depth() == CV_8U ? 1.0 / 255.0 : c3.depth() == CV_16U ? 1.0 / 65535.0 : 1.0;
  c3.convertTo(out, CV_32FC3, scale);
  return out;
}

int filterRadiusPixels(const cv::Mat& depth, const capture::Intrinsics& k, const DepthFilterOptions& o) {
  if (!(o.radiusMetres > 0.0)) return std::max(0, o.radiusPx);
  std::vector<float> z;
  z.reserve(depth.total() / 16 + 1);
  for (int y = 0; y < depth.rows; y += 4)
    for (int x = 0; x < depth.cols; x += 4) {
      const float v = depth.at<float>(y, x);
      if (std::isfinite(v) && v >= o.minDepth && v <= o.maxDepth) z.push_back(v);
    }
  if (z.empty()) return std::max(0, o.radiusPx);
  std::nth_element(z.begin(), z.begin() + z.size() / 2, z.end());
  const double px = o.radiusMetres * k.fx / z[z.size() / 2];
  return std::clamp(static_cast<int>(std::lround(px)), 1, std::max(1, std::min(depth.cols, depth.rows) / 4));
}

cv::Mat guidedFilterDepth(const cv::Mat& depthIn, const cv::Mat& guideIn, int r, const DepthFilterOptions& o) {
  CV_Assert(depthIn.type() == CV_32FC1 && guideIn.size() == depthIn.size());
  const cv::Mat guide = guideIn.channels() == 3 ? guideIn : guideFromColour(guideIn);
  CV_Assert(guide.type() == CV_32FC3);
  cv::Mat p = sanitizeDepth(depthIn, o.minDepth, o.maxDepth);
  const int w = p.cols, h = p.rows;

  GuidedScratch& sc = guidedScratch();
  if (o.removeSpikes) {
    cv::Mat& med = sc.median;
    cv::medianBlur(p, med, 5);
    for (int y = 0; y < h; ++y) {
      float* d = p.ptr<float>(y);
      const float* m = med.ptr<float>(y);
      for (int x = 0; x < w; ++x)
        if (d[x] > 0.f && m[x] > 0.f && std::abs(d[x] - m[x]) > o.edgeCut * m[x]) d[x] = 0.f;
    }
  }
  if (r <= 0) return p;

  // Weighted window statistics; weight = validity, so invalid samples contribute nothing.
  for (cv::Mat& m : sc.sums) m.create(h, w, CV_32FC4);
  cv::Mat &s0 = sc.sums[0], &s1 = sc.sums[1], &s2 = sc.sums[2], &s3 = sc.sums[3];
  forRows(h, [&](int y) {
    const float* d = p.ptr<float>(y);
    const auto* g = guide.ptr<cv::Vec3f>(y);
    auto *a0 = s0.ptr<cv::Vec4f>(y), *a1 = s1.ptr<cv::Vec4f>(y), *a2 = s2.ptr<cv::Vec4f>(y), *a3 = s3.ptr<cv::Vec4f>(y);
    for (int x = 0; x < w; ++x) {
      const float v = d[x] > 0.f ? 1.f : 0.f, z = d[x];
      const cv::Vec3f I = g[x] * v;
      a0[x] = {v, I[0], I[1], I[2]};
      a1[x] = {z, I[0] * z, I[1] * z, I[2] * z};
      a2[x] = {I[0] * g[x][0], I[0] * g[x][1], I[0] * g[x][2], I[1] * g[x][1]};
      a3[x] = {I[1] * g[x][2], I[2] * g[x][2], z * z, 0.f};
    }
  });
  for (int i = 0; i < 4; ++i) boxMean(sc.sums[i], r, sc.means[i]);  // parallel inside
  const cv::Mat &m0 = sc.means[0], &m1 = sc.means[1], &m2 = sc.means[2], &m3 = sc.means[3];

  // Per-window linear model q = a . I + b, solved with the regularised guide covariance.
  sc.coef.create(h, w, CV_32FC4);
  for (cv::Mat* m : {&sc.weight, &sc.spread, &sc.meanP}) m->create(h, w, CV_32FC1);
  cv::Mat &coef = sc.coef, &weight = sc.weight, &spread = sc.spread, &meanP = sc.meanP;
  const double eps = o.eps;
  forRows(h, [&](int y) {
    const auto *b0 = m0.ptr<cv::Vec4f>(y), *b1 = m1.ptr<cv::Vec4f>(y), *b2 = m2.ptr<cv::Vec4f>(y),
               *b3 = m3.ptr<cv::Vec4f>(y);
    auto* c = coef.ptr<cv::Vec4f>(y);
    float *wt = weight.ptr<float>(y), *sp = spread.ptr<float>(y), *mp = meanP.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      const double n = b0[x][0];
      if (!(n > 1e-6)) {
        c[x] = {0, 0, 0, 0};
        wt[x] = 0.f;
        sp[x] = 0.f;
        mp[x] = 0.f;
        continue;
      }
      const double inv = 1.0 / n;
      const double mI[3] = {b0[x][1] * inv, b0[x][2] * inv, b0[x][3] * inv};
      const double mz = b1[x][0] * inv;
      const double cov[3] = {b1[x][1] * inv - mI[0] * mz, b1[x][2] * inv - mI[1] * mz, b1[x][3] * inv - mI[2] * mz};
      const double s00 = b2[x][0] * inv - mI[0] * mI[0] + eps, s01 = b2[x][1] * inv - mI[0] * mI[1],
                   s02 = b2[x][2] * inv - mI[0] * mI[2], s11 = b2[x][3] * inv - mI[1] * mI[1] + eps,
                   s12 = b3[x][0] * inv - mI[1] * mI[2], s22 = b3[x][1] * inv - mI[2] * mI[2] + eps;
      // Symmetric 3x3 inverse through the adjugate.
      const double c00 = s11 * s22 - s12 * s12, c01 = s02 * s12 - s01 * s22, c02 = s01 * s12 - s02 * s11;
      const double c11 = s00 * s22 - s02 * s02, c12 = s01 * s02 - s00 * s12, c22 = s00 * s11 - s01 * s01;
      const double det = s00 * c00 + s01 * c01 + s02 * c02;
      double a[3] = {0, 0, 0};
      if (std::abs(det) > 1e-30) {
        a[0] = (c00 * cov[0] + c01 * cov[1] + c02 * cov[2]) / det;
        a[1] = (c01 * cov[0] + c11 * cov[1] + c12 * cov[2]) / det;
        a[2] = (c02 * cov[0] + c12 * cov[1] + c22 * cov[2]) / det;
      }
      const double b = mz - a[0] * mI[0] - a[1] * mI[1] - a[2] * mI[2];
      c[x] = cv::Vec4f(static_cast<float>(a[0] * n), static_cast<float>(a[1] * n), static_cast<float>(a[2] * n),
                       static_cast<float>(b * n));
      wt[x] = static_cast<float>(n);
      sp[x] = static_cast<float>(std::sqrt(std::max(0.0, b3[x][2] * inv - mz * mz)));
      mp[x] = static_cast<float>(mz);
    }
  });
  // Average the models of every window covering a pixel, each weighted by its share of valid samples.
  boxMean(coef, r, sc.meanCoef);
  boxMean(weight, r, sc.meanWeight);
  const cv::Mat &mc = sc.meanCoef, &mw = sc.meanWeight;

  cv::Mat out(h, w, CV_32FC1, cv::Scalar(0));
  forRows(h, [&](int y) {
    const float* d = p.ptr<float>(y);
    const auto* g = guide.ptr<cv::Vec3f>(y);
    const auto* c = mc.ptr<cv::Vec4f>(y);
    const float *n = mw.ptr<float>(y), *wt = weight.ptr<float>(y), *sp = spread.ptr<float>(y),
                *mp = meanP.ptr<float>(y);
    float* q = out.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      if (!(n[x] > 1e-6f)) continue;
      const float v = (c[x][0] * g[x][0] + c[x][1] * g[x][1] + c[x][2] * g[x][2] + c[x][3]) / n[x];
      if (d[x] > 0.f) {
        q[x] = (std::isfinite(v) && std::abs(v - d[x]) <= o.edgeCut * d[x]) ? v : d[x];
      } else if (o.fillHoles && wt[x] >= o.fillMinValidFraction && sp[x] <= o.edgeCut * mp[x] && std::isfinite(v) &&
                 std::abs(v - mp[x]) <= o.edgeCut * mp[x] && v >= o.minDepth && v <= o.maxDepth) {
        q[x] = v;
      }
    }
  });
  return out;
}

DepthMesh buildDepthMesh(const cv::Mat& positions, const cv::Mat& normals, int stride, float maxRelativeJump) {
  CV_Assert(positions.type() == CV_32FC3 && stride >= 1);
  CV_Assert(normals.empty() || (normals.type() == CV_32FC3 && normals.size() == positions.size()));
  const int gw = (positions.cols - 1) / stride + 1, gh = (positions.rows - 1) / stride + 1;
  std::vector<int32_t> vertexOf(static_cast<size_t>(gw) * gh, -1);
  DepthMesh mesh;
  mesh.positions.reserve(vertexOf.size());
  mesh.normals.reserve(vertexOf.size());
  mesh.pixels.reserve(vertexOf.size());
  mesh.indices.reserve(vertexOf.size() * 6);
  for (int gy = 0; gy < gh; ++gy)
    for (int gx = 0; gx < gw; ++gx) {
      const int x = gx * stride, y = gy * stride;
      const cv::Vec3f p = positions.at<cv::Vec3f>(y, x);
      if (!(p[2] > 0.f) || !std::isfinite(p[2])) continue;
      vertexOf[static_cast<size_t>(gy) * gw + gx] = static_cast<int32_t>(mesh.positions.size());
      mesh.positions.push_back(p);
      mesh.normals.push_back(normals.empty() ? cv::Vec3f(0, 0, 0) : normals.at<cv::Vec3f>(y, x));
      mesh.pixels.emplace_back(static_cast<float>(x), static_cast<float>(y));
    }
  auto joined = [&](int32_t a, int32_t b) {
    const float za = mesh.positions[a][2], zb = mesh.positions[b][2];
    return std::abs(za - zb) <= maxRelativeJump * std::min(za, zb);
  };
  auto triangle = [&](int32_t a, int32_t b, int32_t c) {
    if (a < 0 || b < 0 || c < 0 || !joined(a, b) || !joined(b, c) || !joined(a, c)) return;
    mesh.indices.insert(mesh.indices.end(), {uint32_t(a), uint32_t(b), uint32_t(c)});
  };
  for (int gy = 0; gy + 1 < gh; ++gy)
    for (int gx = 0; gx + 1 < gw; ++gx) {
      const int32_t i00 = vertexOf[size_t(gy) * gw + gx], i10 = vertexOf[size_t(gy) * gw + gx + 1];
      const int32_t i01 = vertexOf[size_t(gy + 1) * gw + gx], i11 = vertexOf[size_t(gy + 1) * gw + gx + 1];
      // Image y runs down, so (00, 01, 10) winds counter-clockwise as seen from the camera.
      triangle(i00, i01, i10);
      triangle(i10, i01, i11);
    }
  return mesh;
}

}  // namespace mrgi::reconstruction
