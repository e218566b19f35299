#include "evaluation/metrics.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/quality.hpp>
#include <vector>

#include "capture/colour.h"

namespace mrgi::evaluation {
namespace {
double lum3(const cv::Vec4f& v) { return capture::luminance({v[0], v[1], v[2]}); }
}  // namespace

/// Stage times of one pipeline run (ms, the larger of CPU wall and GPU time per stage).
std::map<std::string, double> stageMs(gl::Profiler& profiler) {
  std::map<std::string, double> out;
  for (const auto& [name, t] : profiler.resolve()) out[name] = std::max(t.cpuMs, t.gpuMs);
  return out;
}

/// Best (per stage) over `repeats` full runs of the pipeline: each repeat starts from an invalidated pipeline,
/// so no stage is skipped because its inputs did not change.
std::map<std::string, double> bestStages(lighting::LightingPipeline& pipe, const lighting::CameraView& view,
                                         int repeats, std::map<std::string, int>* runs) {
  gl::Profiler profiler;
  std::map<std::string, double> best;
  for (int i = 0; i < repeats; ++i) {
    pipe.invalidate();
    pipe.run(view, {}, {0, 0, 0}, &profiler);
    for (const auto& [name, ms] : stageMs(profiler)) {
      best[name] = best.count(name) ? std::min(best[name], ms) : ms;
      if (runs) ++(*runs)[name];
    }
  }
  return best;
}

/// The frame's state; the delta's luminance is box-averaged over real, valid pixels (normalised convolution),
/// so that a shadow edge landing one pixel over after reprojection does not count as flicker.
FrameState frameState(cv::Mat shade, cv::Mat positions, const capture::Pose& T_marker_camera) {
  cv::Mat lum(shade.size(), CV_32F, cv::Scalar(0)), weight(shade.size(), CV_32F, cv::Scalar(0));
  for (int i = 0; i < static_cast<int>(shade.total()); ++i) {
    const cv::Vec4f s = shade.at<cv::Vec4f>(i);
    if (positions.at<cv::Vec4f>(i)[3] < 0.5f || s[3] > 0.5f) continue;
    lum.at<float>(i) = static_cast<float>(lum3(s));
    weight.at<float>(i) = 1.f;
  }
  cv::Mat num, den;
  cv::boxFilter(lum, num, CV_32F, {5, 5}, {-1, -1}, false);
  cv::boxFilter(weight, den, CV_32F, {5, 5}, {-1, -1}, false);
  cv::Mat smooth = num / cv::max(den, 1.f);
  return {std::move(shade), std::move(positions), std::move(smooth), T_marker_camera};
}

/// Frame-to-frame change of the real pixels' smoothed delta at the same marker-frame points (reprojected with
/// the camera poses), relative to its magnitude: Σ|lum δ_t − lum δ_{t−1}| / Σ|lum δ_{t−1}| over matched pixels.
std::pair<double, double> flickerSums(const FrameState& prev, const FrameState& cur, const capture::Intrinsics& k) {
  const capture::Pose T_camera_marker = capture::inversePose(prev.T_marker_camera);
  double num = 0, den = 0;
  for (int y = 0; y < cur.positions.rows; ++y)
    for (int x = 0; x < cur.positions.cols; ++x) {
      const cv::Vec4f p = cur.positions.at<cv::Vec4f>(y, x);
      const cv::Vec4f s = cur.shade.at<cv::Vec4f>(y, x);
      if (p[3] < 0.5f || s[3] > 0.5f) continue;
      const cv::Vec3d c = capture::transformPoint(T_camera_marker, {p[0], p[1], p[2]});
      if (c[2] <= 0) continue;
      const int u = static_cast<int>(std::lround(k.fx * c[0] / c[2] + k.cx)),
                v = static_cast<int>(std::lround(k.fy * c[1] / c[2] + k.cy));
      if (u < 0 || v < 0 || u >= prev.positions.cols || v >= prev.positions.rows) continue;
      const cv::Vec4f q = prev.positions.at<cv::Vec4f>(v, u);
      const cv::Vec4f t = prev.shade.at<cv::Vec4f>(v, u);
      if (q[3] < 0.5f || t[3] > 0.5f) continue;
      if (cv::norm(cv::Vec3f(q[0] - p[0], q[1] - p[1], q[2] - p[2])) > 0.01) continue;  // not the same surface point
      const double a = cur.smooth.at<float>(y, x), b = prev.smooth.at<float>(v, u);
      num += std::abs(a - b);
      den += std::abs(b);
    }
  return {num, den};
}

std::array<double, 2> ErrorSums::relDeltaInterval() const {
  const double R = relDelta();
  const size_t B = blocks.size();
  if (B < 2 || !(absRef > 0)) return {R, R};
  double ss = 0;
  for (const auto& b : blocks) ss += (b[0] - R * b[1]) * (b[0] - R * b[1]);
  const double se = std::sqrt(ss * static_cast<double>(B) / static_cast<double>(B - 1)) / absRef;
  return {std::max(0.0, R - 1.96 * se), R + 1.96 * se};
}

ErrorSums errorSums(const cv::Mat& shade, const Truth& truth, const NearObjects* near) {
  ErrorSums e;
  constexpr int kTile = 16;
  const int tilesX = (shade.cols + kTile - 1) / kTile, tilesY = (shade.rows + kTile - 1) / kTile;
  std::vector<std::array<double, 2>> tiles(static_cast<size_t>(tilesX * tilesY), {0.0, 0.0});
  std::vector<char> hasReal(tiles.size(), 0);
  for (int y = 0; y < shade.rows; ++y)
    for (int x = 0; x < shade.cols; ++x) {
      const cv::Vec4f s = shade.at<cv::Vec4f>(y, x);
      const cv::Vec3f r = truth.delta.at<cv::Vec3f>(y, x);
      const bool virtRt = s[3] > 0.5f, virtRef = truth.images.mask.at<uchar>(y, x) != 0;
      if (virtRt != virtRef) {
        ++e.mismatched;
        continue;
      }
      if (truth.partlyVirtual(y, x)) {
        ++e.partial;
        continue;
      }
      const bool isNear = near && !virtRt && near->contains(near->positions.at<cv::Vec4f>(y, x));
      for (int c = 0; c < 3; ++c) {
        const double d = s[c] - r[c];
        if (isNear) e.nearAbs += std::abs(d), e.nearRef += std::abs(r[c]);
        if (virtRt) {
          e.virtAbs += std::abs(d);
          e.virtRef += std::abs(r[c]);
        } else {
          e.sq += d * d;
          e.abs += std::abs(d);
          e.absRef += std::abs(r[c]);
          auto& t = tiles[static_cast<size_t>((y / kTile) * tilesX + x / kTile)];
          t[0] += std::abs(d), t[1] += std::abs(r[c]);
        }
      }
      if (!virtRt) ++e.real, hasReal[static_cast<size_t>((y / kTile) * tilesX + x / kTile)] = 1;
    }
  for (size_t i = 0; i < tiles.size(); ++i)
    if (hasReal[i]) e.blocks.push_back(tiles[i]);
  return e;
}

// (metrics.h)
ShadowSums shadowSums(const cv::Mat& shade, const Truth& truth, const NearObjects& near) {
  ShadowSums out;
  if (!(near.radius > 0)) return out;
  cv::Mat lum(shade.size(), CV_32F, cv::Scalar(0)), lumRef(shade.size(), CV_32F, cv::Scalar(0)),
      m(shade.size(), CV_32F, cv::Scalar(0));
  for (int y = 0; y < shade.rows; ++y)
    for (int x = 0; x < shade.cols; ++x) {
      const cv::Vec4f s = shade.at<cv::Vec4f>(y, x);
      const bool real = s[3] <= 0.5f && !truth.images.mask.at<uchar>(y, x) && !truth.partlyVirtual(y, x);
      if (!real || !near.contains(near.positions.at<cv::Vec4f>(y, x))) continue;
      const double a = capture::luminance(cv::Vec3d(s[0], s[1], s[2]));
      const double b = capture::luminance(cv::Vec3d(truth.delta.at<cv::Vec3f>(y, x)));
      lum.at<float>(y, x) = static_cast<float>(a);
      lumRef.at<float>(y, x) = static_cast<float>(b);
      m.at<float>(y, x) = 1.f;
      out.dark += std::min(a, 0.0);
      out.darkRef += std::min(b, 0.0);
      ++out.pixels;
    }
  if (out.pixels == 0) return out;
  cv::Mat gl, gr, gm;
  cv::GaussianBlur(lum, gl, {0, 0}, 2.0);
  cv::GaussianBlur(lumRef, gr, {0, 0}, 2.0);
  cv::GaussianBlur(m, gm, {0, 0}, 2.0);
  for (int y = 0; y < shade.rows; ++y)
    for (int x = 0; x < shade.cols; ++x) {
      if (m.at<float>(y, x) < 0.5f || gm.at<float>(y, x) <= 1e-6f) continue;
      const double a = gl.at<float>(y, x) / gm.at<float>(y, x), b = gr.at<float>(y, x) / gm.at<float>(y, x);
      out.l1 += std::abs(a - b);
      out.l1Ref += std::abs(b);
    }
  return out;
}

UnbiasedError unbiasedSquaredError(const cv::Mat& x, const cv::Mat& r1, const cv::Mat& r2, const cv::Mat& mask,
                                   int tile) {
  CV_Assert(x.size() == r1.size() && x.size() == r2.size() && tile >= 1);
  CV_Assert((x.type() == CV_32FC3 || x.type() == CV_32FC4) && r1.type() == CV_32FC3 && r2.type() == CV_32FC3);
  CV_Assert(mask.empty() || (mask.type() == CV_8UC1 && mask.size() == x.size()));
  const int xc = x.channels();
  UnbiasedError u;
  std::vector<double> blockMean;  // per block: mean product per pixel and channel
  std::vector<size_t> blockCount;
  double sumProd = 0, sumRef = 0;
  for (int by = 0; by < x.rows; by += tile)
    for (int bx = 0; bx < x.cols; bx += tile) {
      double prod = 0;
      size_t n = 0;
      for (int y = by; y < std::min(by + tile, x.rows); ++y) {
        const float* px = x.ptr<float>(y);
        const float* p1 = r1.ptr<float>(y);
        const float* p2 = r2.ptr<float>(y);
        for (int xx = bx; xx < std::min(bx + tile, x.cols); ++xx) {
          if (!mask.empty() && !mask.at<uchar>(y, xx)) continue;
          for (int c = 0; c < 3; ++c) {
            const double v = px[xc * xx + c], a = p1[3 * xx + c], b = p2[3 * xx + c];
            prod += (v - a) * (v - b);
            sumRef += a * b;
          }
          ++n;
        }
      }
      if (n == 0) continue;
      sumProd += prod;
      u.pixels += n;
      blockMean.push_back(prod / (3.0 * static_cast<double>(n)));
      blockCount.push_back(n);
    }
  u.blocks = blockMean.size();
  if (u.pixels == 0) return u;
  u.meanSq = sumProd / (3.0 * static_cast<double>(u.pixels));
  u.refSq = sumRef / (3.0 * static_cast<double>(u.pixels));
  // The pixel-weighted mean of the block means is meanSq; its standard error from the blocks' spread
  // (weights n_b / N: var = sum w_b^2 (m_b - mean)^2 * B / (B - 1)).
  if (u.blocks > 1) {
    double var = 0;
    for (size_t b = 0; b < u.blocks; ++b) {
      const double w = static_cast<double>(blockCount[b]) / static_cast<double>(u.pixels);
      var += w * w * (blockMean[b] - u.meanSq) * (blockMean[b] - u.meanSq);
    }
    var *= static_cast<double>(u.blocks) / static_cast<double>(u.blocks - 1);
    const double half = 1.96 * std::sqrt(var);
    u.meanSqLo = u.meanSq - half;
    u.meanSqHi = u.meanSq + half;
  } else {
    u.meanSqLo = u.meanSqHi = u.meanSq;
  }
  return u;
}

std::optional<UnbiasedError> unbiasedDeltaError(const cv::Mat& shade, const Truth& truth) {
  if (truth.second.empty()) return std::nullopt;
  cv::Mat real(shade.size(), CV_8UC1);
  for (int y = 0; y < shade.rows; ++y)
    for (int x = 0; x < shade.cols; ++x)
      real.at<uchar>(y, x) =
          shade.at<cv::Vec4f>(y, x)[3] <= 0.5f && !truth.images.mask.at<uchar>(y, x) && !truth.partlyVirtual(y, x) ? 255
                                                                                                                   : 0;
  return unbiasedSquaredError(shade, truth.delta, truth.second, real);
}

namespace {
double relOf(double sq, double ref) { return ref > 0 ? std::sqrt(std::max(sq, 0.0) / ref) : 0.0; }
}  // namespace
double UnbiasedError::rel() const { return relOf(meanSq, refSq); }
double UnbiasedError::relLo() const { return relOf(meanSqLo, refSq); }
double UnbiasedError::relHi() const { return relOf(meanSqHi, refSq); }

cv::Mat errorImage(const cv::Mat& shade, const Truth& truth, double scale) {
  cv::Mat out(shade.size(), CV_8UC3);
  for (int y = 0; y < shade.rows; ++y)
    for (int x = 0; x < shade.cols; ++x) {
      const cv::Vec4f s = shade.at<cv::Vec4f>(y, x);
      const cv::Vec3f r = truth.delta.at<cv::Vec3f>(y, x);
      const bool virtRt = s[3] > 0.5f, virtRef = truth.images.mask.at<uchar>(y, x) != 0;
      if (virtRt != virtRef) {  // silhouette mismatch
        out.at<cv::Vec3b>(y, x) = {90, 90, 90};
        continue;
      }
      if (virtRt) {  // relative error of the object's radiance: white = 10 %, blue: too dark, yellow: too bright
        const double ref = capture::luminance({r[0], r[1], r[2]});
        const double d = capture::luminance({s[0] - r[0], s[1] - r[1], s[2] - r[2]});
        const auto v = cv::saturate_cast<uchar>(255.0 * std::abs(d) / std::max(0.1 * ref, 1e-9));
        out.at<cv::Vec3b>(y, x) = d < 0 ? cv::Vec3b(v / 4, v / 4, v) : cv::Vec3b(v, v, v / 4);
        continue;
      }
      const double d = capture::luminance({s[0] - r[0], s[1] - r[1], s[2] - r[2]});
      const auto v = cv::saturate_cast<uchar>(255.0 * std::abs(d) / scale);
      out.at<cv::Vec3b>(y, x) = d < 0 ? cv::Vec3b(v, v / 4, v / 4) : cv::Vec3b(v / 4, v, v / 4);  // red: too dark
    }
  return out;
}

double ssimOf(const cv::Mat& a, const cv::Mat& b) {
  const cv::Scalar s = cv::quality::QualitySSIM::compute(a, b, cv::noArray());
  return (s[0] + s[1] + s[2]) / 3.0;
}

}  // namespace mrgi::evaluation
