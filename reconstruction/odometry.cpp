#include "reconstruction/odometry.h"

#include <open3d/core/Tensor.h>
#include <open3d/t/pipelines/odometry/RGBDOdometry.h>

#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <set>
#include <stdexcept>

#include "capture/colour.h"
#include "reconstruction/depth.h"
#include "reconstruction/open3d_pose.h"

namespace mrgi::reconstruction {

namespace o3c = open3d::core;
namespace o3o = open3d::t::pipelines::odometry;

const char* toString(OdometryMethod m) {
  switch (m) {
    case OdometryMethod::PointToPlane:
      return "point-to-plane";
    case OdometryMethod::Intensity:
      return "intensity";
    case OdometryMethod::Hybrid:
      return "hybrid";
  }
  return "?";
}

namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

/// Intrinsics of an image halved by 2 x 2 blocks (pixel centres: u' = (u + 0.5) / 2 - 0.5).
capture::Intrinsics halved(const capture::Intrinsics& k) {
  return {k.width / 2, k.height / 2, k.fx / 2, k.fy / 2, (k.cx + 0.5) / 2 - 0.5, (k.cy + 0.5) / 2 - 0.5};
}

/// Depth halved by 2 x 2 blocks: the mean of a block whose four samples exist and lie within 4 % (+ 1 cm) of
/// each other, NaN across a depth edge or a hole (no point floats between a foreground and a background).
cv::Mat halveDepth(const cv::Mat& d) {
  cv::Mat out(d.rows / 2, d.cols / 2, CV_32F);
  for (int y = 0; y < out.rows; ++y) {
    const float* a = d.ptr<float>(2 * y);
    const float* b = d.ptr<float>(2 * y + 1);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < out.cols; ++x) {
      const float s[4] = {a[2 * x], a[2 * x + 1], b[2 * x], b[2 * x + 1]};
      float lo = s[0], hi = s[0], sum = 0;
      bool ok = true;
      for (float v : s) {
        ok &= std::isfinite(v);
        lo = std::min(lo, v), hi = std::max(hi, v), sum += v;
      }
      o[x] = ok && hi - lo <= 0.04f * lo + 0.01f ? 0.25f * sum : kNaN;
    }
  }
  return out;
}

cv::Mat halveIntensity(const cv::Mat& i) {
  cv::Mat out;
  cv::resize(i, out, {i.cols / 2, i.rows / 2}, 0, 0, cv::INTER_AREA);
  return out;
}

/// Depth in metres with NaN where there is none or it is out of [minM, maxM].
cv::Mat metresWithNaN(const cv::Mat& depth, double minM, double maxM) {
  cv::Mat d;
  if (depth.type() == CV_16U)
    depth.convertTo(d, CV_32F, 1e-3);
  else if (depth.type() == CV_32F)
    d = depth.clone();
  else
    throw std::invalid_argument("odometry: depth must be CV_32F metres or CV_16U millimetres");
  d.forEach<float>([&](float& z, const int*) {
    if (!(z >= minM && z <= maxM)) z = kNaN;
  });
  return d;
}
}  // namespace

struct OdometryFrame::Impl {
  struct Level {
    capture::Intrinsics k;
    cv::Mat depth, intensity, vertices, normals;
    /// What a step samples where a source pixel lands, interleaved so that one bilinear lookup reads it all
    /// (CV_32FC(6)): intensity, its x and y derivatives per pixel, depth (NaN = none), its x and y derivatives
    /// (NaN within a pixel of a hole). Only with colour, for the sub-pixel steps (OdometryOptions::subpixel).
    cv::Mat samples;
    o3c::Tensor tDepth, tIntensity, tDepthDx, tDepthDy, tIntensityDx, tIntensityDy, tVertices, tNormals, tK;
  };
  std::vector<Level> levels;
  size_t valid = 0;
  bool intensity = false;
};

OdometryFrame::OdometryFrame() : impl_(std::make_shared<Impl>()) {}
OdometryFrame::~OdometryFrame() = default;
OdometryFrame::OdometryFrame(const OdometryFrame&) = default;
OdometryFrame& OdometryFrame::operator=(const OdometryFrame&) = default;

OdometryFrame::OdometryFrame(const cv::Mat& depthIn, const cv::Mat& colour, const capture::Intrinsics& kIn,
                             const OdometryOptions& o, double exposure) {
  if (depthIn.empty() || depthIn.cols != kIn.width || depthIn.rows != kIn.height)
    throw std::invalid_argument("odometry: depth is not on the intrinsics' pixel grid");
  if (!colour.empty() && colour.size() != depthIn.size())
    throw std::invalid_argument("odometry: colour and depth differ in size");
  if (o.iterations.empty()) throw std::invalid_argument("odometry: no pyramid level");
  auto impl = std::make_shared<Impl>();
  cv::Mat depth = metresWithNaN(depthIn, o.minDepthM, o.maxDepthM);
  cv::Mat grey;
  if (!colour.empty()) {
    // The intensity is the frame's radiance (its exposure divided out: auto exposure does not read as motion),
    // as luminance, then gamma-encoded so that dark and bright texture weigh alike.
    cv::Mat linear;
    if (colour.type() == CV_8UC3) {
      cv::transform(capture::radianceOf(colour, exposure), linear, cv::Matx13f(0.2126f, 0.7152f, 0.0722f));
    } else if (colour.type() == CV_32FC1) {
      linear = colour;  // already linear luminance at exposure 1 (a model's rendering)
    } else if (colour.type() == CV_8UC1) {
      cv::Mat rgb;
      cv::cvtColor(colour, rgb, cv::COLOR_GRAY2RGB);
      cv::extractChannel(capture::radianceOf(rgb, exposure), linear, 0);
    } else {
      throw std::invalid_argument("odometry: colour must be 8-bit RGB or grey, or float linear luminance");
    }
    cv::pow(cv::max(linear, 0.0), 1.0 / 2.2, grey);
    grey *= o.intensityWeight;
    if (o.normaliseIntensity) {
      cv::Scalar mean, sd;
      cv::meanStdDev(grey, mean, sd, depthIn > 0);
      if (sd[0] > 1e-4) grey.convertTo(grey, CV_32F, 0.2 / sd[0], 0.5 - 0.2 * mean[0] / sd[0]);
    }
    impl->intensity = true;
  }
  capture::Intrinsics k = kIn;
  while (depth.cols > std::max(o.maxWidth, 16)) {
    depth = halveDepth(depth);
    if (!grey.empty()) grey = halveIntensity(grey);
    k = halved(k);
  }
  const int levels = static_cast<int>(o.iterations.size());
  for (int l = 0; l < levels; ++l) {
    if (l > 0) {
      depth = halveDepth(depth);
      if (!grey.empty()) grey = halveIntensity(grey);
      k = halved(k);
    }
    if (depth.cols < 8 || depth.rows < 8)
      throw std::invalid_argument("odometry: too many pyramid levels for the image");
    Impl::Level L;
    L.k = k;
    L.depth = depth;
    // Vertices (NaN without depth) and normals (NaN where they cannot be formed).
    L.vertices.create(depth.size(), CV_32FC3);
    cv::Mat zeroed(depth.size(), CV_32FC3);
    for (int y = 0; y < depth.rows; ++y)
      for (int x = 0; x < depth.cols; ++x) {
        const float z = depth.at<float>(y, x);
        if (std::isfinite(z)) {
          const cv::Vec3f v(static_cast<float>((x - k.cx) / k.fx * z), static_cast<float>((y - k.cy) / k.fy * z), z);
          L.vertices.at<cv::Vec3f>(y, x) = v;
          zeroed.at<cv::Vec3f>(y, x) = v;
        } else {
          L.vertices.at<cv::Vec3f>(y, x) = cv::Vec3f(kNaN, kNaN, kNaN);
          zeroed.at<cv::Vec3f>(y, x) = cv::Vec3f(0, 0, 0);
        }
      }
    L.normals = computeNormals(zeroed);
    L.normals.forEach<cv::Vec3f>([](cv::Vec3f& n, const int*) {
      if (n == cv::Vec3f(0, 0, 0)) n = cv::Vec3f(kNaN, kNaN, kNaN);
    });
    if (l == 0) impl->valid = static_cast<size_t>(cv::countNonZero(depth == depth));
    // The tensors share the images' pixels (imageTensor): nothing writes an image after this.
    L.tDepth = imageTensor(depth);
    L.tVertices = imageTensor(L.vertices);
    L.tNormals = imageTensor(L.normals);
    L.tK = intrinsicsTensor(k);
    cv::Mat depthDx, depthDy, greyDx, greyDy;
    cv::Sobel(depth, depthDx, CV_32F, 1, 0, 3);  // unscaled (8 times the derivative); NaN spreads to the 3 x 3
    cv::Sobel(depth, depthDy, CV_32F, 0, 1, 3);
    if (!grey.empty()) {
      L.intensity = grey;
      L.tIntensity = imageTensor(grey);
      cv::Sobel(grey, greyDx, CV_32F, 1, 0, 3);
      cv::Sobel(grey, greyDy, CV_32F, 0, 1, 3);
    }
    if (!o.subpixel) {
      // Open3D's steps read each gradient from an image of its own (the tensors share their pixels) and scale it.
      L.tDepthDx = imageTensor(depthDx);
      L.tDepthDy = imageTensor(depthDy);
      if (!grey.empty()) L.tIntensityDx = imageTensor(greyDx), L.tIntensityDy = imageTensor(greyDy);
    } else if (!grey.empty()) {
      // The sub-pixel steps read them interleaved, as derivatives per pixel.
      const auto per = [](const cv::Mat& sobel) { return cv::Mat(sobel * 0.125); };
      const cv::Mat channels[6] = {grey, per(greyDx), per(greyDy), depth, per(depthDx), per(depthDy)};
      cv::merge(channels, 6, L.samples);
    }
    impl->levels.push_back(std::move(L));
  }
  impl_ = std::move(impl);
}

int OdometryFrame::levels() const { return static_cast<int>(impl_->levels.size()); }
const capture::Intrinsics& OdometryFrame::intrinsics(int l) const { return impl_->levels.at(l).k; }
const cv::Mat& OdometryFrame::depth(int l) const { return impl_->levels.at(l).depth; }
const cv::Mat& OdometryFrame::intensity(int l) const { return impl_->levels.at(l).intensity; }
const cv::Mat& OdometryFrame::vertices(int l) const { return impl_->levels.at(l).vertices; }
const cv::Mat& OdometryFrame::normals(int l) const { return impl_->levels.at(l).normals; }
size_t OdometryFrame::validPixels() const { return impl_->valid; }
bool OdometryFrame::hasIntensity() const { return impl_->intensity; }
size_t OdometryFrame::bytes() const {
  std::set<const void*> seen;
  size_t sum = 0;
  const auto add = [&](const void* data, size_t n) {
    if (data && seen.insert(data).second) sum += n;
  };
  for (const auto& L : impl_->levels) {
    for (const cv::Mat* m : {&L.depth, &L.intensity, &L.vertices, &L.normals, &L.samples})
      add(m->data, m->total() * m->elemSize());
    for (const o3c::Tensor* t : {&L.tDepth, &L.tIntensity, &L.tDepthDx, &L.tDepthDy, &L.tIntensityDx, &L.tIntensityDy,
                                 &L.tVertices, &L.tNormals})
      if (t->NumElements() > 0) add(t->GetDataPtr(), static_cast<size_t>(t->NumElements()) * t->GetDtype().ByteSize());
  }
  return sum;
}

struct OdometrySolver {
  /// The source level without the pixels whose intensity, at pose T (target from source), differs from the
  /// target's where they land by more than options.intensityOutlier (the intensities' own scale, before
  /// intensityWeight): their depth and vertex made NaN, which every step skips. Nullopt when none is, or when more
  /// than half the associated pixels would be (a change of the whole view's brightness: not outliers), or fewer
  /// than options.intensityOutlierMinShare of them (the sensor's noise and the edges of an unchanged view: the
  /// second solve would cost as much as the first for nothing).
  static std::optional<OdometryFrame::Impl::Level> withoutIntensityOutliers(const OdometryFrame::Impl::Level& s,
                                                                            const OdometryFrame::Impl::Level& t,
                                                                            const capture::Pose& T,
                                                                            const OdometryOptions& o) {
    if (s.intensity.empty() || t.intensity.empty()) return std::nullopt;
    const cv::Matx33d R = capture::rotationOf(T);
    const cv::Vec3d tr = capture::translationOf(T);
    const float limit = static_cast<float>(o.intensityOutlier * o.intensityWeight);
    cv::Mat out(s.vertices.size(), CV_8UC1, cv::Scalar(0));
    size_t associated = 0, outliers = 0;
    for (int y = 0; y < s.vertices.rows; ++y)
      for (int x = 0; x < s.vertices.cols; ++x) {
        const cv::Vec3f v = s.vertices.at<cv::Vec3f>(y, x);
        if (!std::isfinite(v[0])) continue;
        const cv::Vec3d p = R * cv::Vec3d(v) + tr;
        if (!(p[2] > 0)) continue;
        const double u = t.k.fx * p[0] / p[2] + t.k.cx, w = t.k.fy * p[1] / p[2] + t.k.cy;
        if (!(u >= 0 && w >= 0 && u <= t.intensity.cols - 1 && w <= t.intensity.rows - 1)) continue;
        const int u0 = std::min(static_cast<int>(u), t.intensity.cols - 2),
                  w0 = std::min(static_cast<int>(w), t.intensity.rows - 2);
        const float a = static_cast<float>(u - u0), b = static_cast<float>(w - w0);
        const float it =
            (1 - a) * (1 - b) * t.intensity.at<float>(w0, u0) + a * (1 - b) * t.intensity.at<float>(w0, u0 + 1) +
            (1 - a) * b * t.intensity.at<float>(w0 + 1, u0) + a * b * t.intensity.at<float>(w0 + 1, u0 + 1);
        ++associated;
        if (std::abs(it - s.intensity.at<float>(y, x)) > limit) out.at<uchar>(y, x) = 1, ++outliers;
      }
    if (static_cast<double>(outliers) < o.intensityOutlierMinShare * static_cast<double>(associated) || outliers == 0 ||
        2 * outliers > associated)
      return std::nullopt;
    OdometryFrame::Impl::Level m = s;
    m.depth = s.depth.clone();
    m.vertices = s.vertices.clone();
    for (int y = 0; y < out.rows; ++y)
      for (int x = 0; x < out.cols; ++x)
        if (out.at<uchar>(y, x)) {
          m.depth.at<float>(y, x) = kNaN;
          m.vertices.at<cv::Vec3f>(y, x) = cv::Vec3f(kNaN, kNaN, kNaN);
        }
    m.tDepth = imageTensor(m.depth);
    m.tVertices = imageTensor(m.vertices);
    return m;
  }

  /// One Gauss-Newton step of the intensity or hybrid term, its target sampled where each source pixel lands
  /// (bilinear: intensity, depth and their derivatives), not at the nearest pixel as Open3D's kernels do: a
  /// nearest-pixel residual is flat within a pixel and steps at its edges, so the steps cannot settle closer than
  /// about half a pixel of the level and wander by that much from one step to the next; sampled between pixels
  /// they converge. The residuals and their Jacobians are those of Steinbrücker et al. (intensity) and Park et al.
  /// (depth along the ray) for a motion exp(xi) T applied on the left, xi = (omega, v), each weighed by Huber
  /// (iteratively reweighted). Returns the step's motion exp(xi), or nullopt when no pixel associates or the normal
  /// equations are singular.
  /// `rotationOnly`: the step turns about the target camera's centre and does not translate. `cost` (optional)
  /// receives the robust cost at T (before the step): the Huber losses of the residuals, and for each source pixel
  /// with depth that associates with none a loss as large as an outlier's.
  static std::optional<capture::Pose> subpixelStep(const OdometryFrame::Impl::Level& s,
                                                   const OdometryFrame::Impl::Level& t, const capture::Pose& T,
                                                   bool hybrid, const OdometryOptions& o, bool rotationOnly = false,
                                                   double* cost = nullptr) {
    const cv::Matx33f R = capture::rotationOf(T);
    const cv::Vec3f tr = capture::translationOf(T);
    const float fx = static_cast<float>(t.k.fx), fy = static_cast<float>(t.k.fy), cx = static_cast<float>(t.k.cx),
                cy = static_cast<float>(t.k.cy);
    const float outlier = o.depthOutlierM, huberD = o.depthHuberM, huberI = o.intensityHuber * o.intensityWeight;
    const int W = t.samples.cols, H = t.samples.rows;
    // The normal equations' upper triangle (21) and right-hand side (6), summed per row in float and per stripe in
    // double.
    constexpr int kTerms = 27;
    constexpr int kStripes = 8;
    std::array<std::array<double, kTerms>, kStripes> stripes{};
    std::array<size_t, kStripes> counts{};
    std::array<double, kStripes> losses{};
    const auto add = [](float* S, const float J[6], float r, float w) {
      int k = 0;
      for (int i = 0; i < 6; ++i) {
        const float wj = w * J[i];
        for (int j = i; j < 6; ++j) S[k++] += wj * J[j];
        S[21 + i] += wj * r;
      }
    };
    const auto huber = [](float r, float delta) { return std::abs(r) <= delta ? 1.0f : delta / std::abs(r); };
    const auto loss = [](float r, float delta) {
      const float a = std::abs(r);
      return a <= delta ? 0.5f * a * a : delta * (a - 0.5f * delta);
    };
    // A pixel that associates with nothing costs what an intensity residual of the whole range and a depth
    // residual at the outlier distance cost.
    const float unassociated = loss(o.intensityWeight, huberI) + (hybrid ? loss(outlier, huberD) : 0.0f);
    cv::parallel_for_(cv::Range(0, kStripes), [&](const cv::Range& range) {
      for (int stripe = range.start; stripe < range.end; ++stripe) {
        std::array<double, kTerms>& S = stripes[static_cast<size_t>(stripe)];
        size_t& n = counts[static_cast<size_t>(stripe)];
        double& lost = losses[static_cast<size_t>(stripe)];
        const int y0 = s.vertices.rows * stripe / kStripes, y1 = s.vertices.rows * (stripe + 1) / kStripes;
        for (int y = y0; y < y1; ++y) {
          float row[kTerms] = {};
          const cv::Vec3f* vrow = s.vertices.ptr<cv::Vec3f>(y);
          const float* irow = s.intensity.empty() ? nullptr : s.intensity.ptr<float>(y);
          for (int x = 0; x < s.vertices.cols; ++x) {
            const cv::Vec3f v = vrow[x];
            if (!std::isfinite(v[0])) continue;
            const cv::Vec3f p = R * v + tr;
            if (!(p[2] > 0)) {
              lost += unassociated;
              continue;
            }
            const float iz = 1.0f / p[2];
            const float u = fx * p[0] * iz + cx, w = fy * p[1] * iz + cy;
            if (!(u >= 0 && w >= 0 && u < W - 1 && w < H - 1)) {
              lost += unassociated;
              continue;
            }
            const int u0 = static_cast<int>(u), w0 = static_cast<int>(w);
            const float a = u - u0, c = w - w0;
            const float* q00 = t.samples.ptr<float>(w0) + 6 * u0;
            const float* q10 = q00 + 6;
            const float* q01 = t.samples.ptr<float>(w0 + 1) + 6 * u0;
            const float* q11 = q01 + 6;
            float m[6];
            for (int k = 0; k < 6; ++k)
              m[k] = (1 - c) * ((1 - a) * q00[k] + a * q10[k]) + c * ((1 - a) * q01[k] + a * q11[k]);
            const float rD = m[3] - p[2];  // NaN where a tap has no depth
            if (!(std::abs(rD) <= outlier)) {
              lost += unassociated;
              continue;
            }
            // The Jacobian of a quantity sampled at p's projection whose gradient with respect to p is g, under the
            // motion dp = -[p]x omega + v.
            const auto jacobian = [&](float gx, float gy, float gz, float J[6]) {
              J[0] = p[1] * gz - p[2] * gy;
              J[1] = p[2] * gx - p[0] * gz;
              J[2] = p[0] * gy - p[1] * gx;
              J[3] = gx, J[4] = gy, J[5] = gz;
            };
            float J[6];
            if (irow) {
              const float c0 = m[1] * fx * iz, c1 = m[2] * fy * iz, c2 = -(c0 * p[0] + c1 * p[1]) * iz;
              const float rI = m[0] - irow[x];
              jacobian(c0, c1, c2, J);
              add(row, J, rI, huber(rI, huberI));
              lost += loss(rI, huberI);
            }
            if (hybrid && std::isfinite(m[4]) && std::isfinite(m[5])) {
              const float d0 = m[4] * fx * iz, d1 = m[5] * fy * iz, d2 = -(d0 * p[0] + d1 * p[1]) * iz - 1.0f;
              jacobian(d0, d1, d2, J);
              add(row, J, rD, huber(rD, huberD));
              lost += loss(rD, huberD);
            }
            ++n;
          }
          for (int k = 0; k < kTerms; ++k) S[static_cast<size_t>(k)] += row[k];
        }
      }
    });
    cv::Matx66d A = cv::Matx66d::zeros();
    cv::Vec6d b(0, 0, 0, 0, 0, 0);
    size_t n = 0;
    for (int stripe = 0; stripe < kStripes; ++stripe) {
      const std::array<double, kTerms>& S = stripes[static_cast<size_t>(stripe)];
      int k = 0;
      for (int i = 0; i < 6; ++i) {
        for (int j = i; j < 6; ++j) A(i, j) += S[static_cast<size_t>(k++)];
        b[i] += S[static_cast<size_t>(21 + i)];
      }
      n += counts[static_cast<size_t>(stripe)];
    }
    if (cost) {
      *cost = 0;
      for (double l : losses) *cost += l;
    }
    if (n < 6) return std::nullopt;
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < i; ++j) A(i, j) = A(j, i);
    cv::Vec6d xi(0, 0, 0, 0, 0, 0);
    if (rotationOnly) {
      const cv::Matx33d Ar = A.get_minor<3, 3>(0, 0);
      cv::Vec3d w;
      if (!cv::solve(Ar, -cv::Vec3d(b[0], b[1], b[2]), w, cv::DECOMP_CHOLESKY)) return std::nullopt;
      xi[0] = w[0], xi[1] = w[1], xi[2] = w[2];
    } else if (!cv::solve(A, -b, xi, cv::DECOMP_CHOLESKY)) {
      return std::nullopt;
    }
    for (int i = 0; i < 6; ++i)
      if (!std::isfinite(xi[i])) return std::nullopt;
    cv::Matx33d Rd;
    cv::Rodrigues(cv::Vec3d(xi[0], xi[1], xi[2]), Rd);
    return capture::makePose(Rd, cv::Vec3d(xi[3], xi[4], xi[5]));
  }

  /// One Gauss-Newton step of options.method from T (target from source): the motion to apply on the left, or
  /// nullopt when no pixel associates (the frames do not overlap at T) or the step is not finite.
  static std::optional<capture::Pose> step(const OdometryFrame::Impl::Level& s, const OdometryFrame::Impl::Level& t,
                                           const capture::Pose& T, const OdometryOptions& o) {
    const OdometryMethod method = o.method;
    capture::Pose delta;
    if (o.subpixel && method != OdometryMethod::PointToPlane) {
      const std::optional<capture::Pose> d = subpixelStep(s, t, T, method == OdometryMethod::Hybrid, o);
      if (!d) return std::nullopt;
      delta = *d;
    } else {
      const o3c::Tensor pose = poseTensor(T);
      o3o::OdometryResult r;
      try {
        switch (method) {
          case OdometryMethod::PointToPlane:
            r = o3o::ComputeOdometryResultPointToPlane(s.tVertices, t.tVertices, t.tNormals, t.tK, pose,
                                                       o.depthOutlierM, o.depthHuberM);
            break;
          case OdometryMethod::Intensity:
            r = o3o::ComputeOdometryResultIntensity(s.tDepth, t.tDepth, s.tIntensity, t.tIntensity, t.tIntensityDx,
                                                    t.tIntensityDy, s.tVertices, t.tK, pose, o.depthOutlierM,
                                                    o.intensityHuber * o.intensityWeight);
            break;
          case OdometryMethod::Hybrid:
            r = o3o::ComputeOdometryResultHybrid(s.tDepth, t.tDepth, s.tIntensity, t.tIntensity, t.tDepthDx, t.tDepthDy,
                                                 t.tIntensityDx, t.tIntensityDy, s.tVertices, t.tK, pose,
                                                 o.depthOutlierM, o.depthHuberM, o.intensityHuber * o.intensityWeight);
            break;
        }
      } catch (const std::exception&) {
        return std::nullopt;  // no inlier at all
      }
      delta = poseOf(r.transformation_);
    }
    for (double v : delta.val)
      if (!std::isfinite(v)) return std::nullopt;
    return delta;
  }

  /// At most `steps` steps at one pyramid level, from T (updated in place), until a step moves the view by less
  /// than OdometryOptions::convergedPixels of the level's pixel (radians, or metres at 1 m): the coarse levels
  /// stop where their pixels cannot tell more. `count` gains the steps taken. False when a step fails.
  static bool solveLevel(const OdometryFrame::Impl::Level& s, const OdometryFrame::Impl::Level& t, int steps,
                         const OdometryOptions& o, capture::Pose& T, int& count, bool rotationOnly = false) {
    const double converged = o.convergedPixels / std::max(t.k.fx, t.k.fy);
    for (int i = 0; i < steps; ++i) {
      const std::optional<capture::Pose> delta =
          rotationOnly ? subpixelStep(s, t, T, o.method == OdometryMethod::Hybrid, o, true) : step(s, t, T, o);
      if (!delta) return false;
      T = *delta * T;
      ++count;
      const capture::Pose& d = *delta;
      const double angle = std::acos(std::clamp((d(0, 0) + d(1, 1) + d(2, 2) - 1) / 2, -1.0, 1.0));
      if (angle + cv::norm(capture::translationOf(d)) < converged) break;
    }
    return true;
  }

  static OdometryResult solve(const OdometryFrame& source, const OdometryFrame& target, const capture::Pose& init,
                              const OdometryOptions& o) {
    const auto& S = *source.impl_;
    const auto& T = *target.impl_;
    if (S.levels.size() != T.levels.size() || S.levels.empty() || !(S.levels[0].k == T.levels[0].k))
      throw std::invalid_argument("odometry: source and target pyramids differ");
    OdometryMethod method = o.method;
    if (method != OdometryMethod::PointToPlane && !(S.intensity && T.intensity))
      throw std::invalid_argument(std::string("odometry: ") + toString(method) + " needs colour in both frames");
    if (method != OdometryMethod::PointToPlane &&
        (o.subpixel ? T.levels[0].samples.empty() : T.levels[0].tIntensityDx.NumElements() == 0))
      throw std::invalid_argument("odometry: the target was prepared for the other kind of step (subpixel)");
    OdometryResult out;
    out.T_target_source = init;
    const int levels = static_cast<int>(S.levels.size());
    capture::Pose pose = init;
    bool solved = true;
    const auto solveAt = [&](int l, capture::Pose& at) {
      const auto& s = S.levels[l];
      const auto& t = T.levels[l];
      const int steps = o.iterations[static_cast<size_t>(levels - 1 - l)];
      bool ok = solveLevel(s, t, steps, o, at, out.steps);
      // Where the source's appearance has changed since the target (a hand, a screen, a painted-out marker, a
      // highlight that moved) its intensity residual stays large however the pose moves: once the level has
      // converged, those pixels are left out and the level solved again (a redescending weight, where the
      // steps' own Huber weight would keep pulling the pose by them). Nothing (or too much) to leave out: the
      // level stands.
      if (ok && method != OdometryMethod::PointToPlane && o.intensityOutlier > 0)
        if (const auto masked = withoutIntensityOutliers(s, t, at, o))
          ok = solveLevel(*masked, t, steps, o, at, out.steps);
      return ok;
    };
    for (int l = levels - 1; l >= 0 && solved; --l) {
      if (l != levels - 1 || !o.turnInPlace || !o.subpixel || method == OdometryMethod::PointToPlane) {
        solved = solveAt(l, pose);
        continue;
      }
      // The coarsest level from init and from init turned in place; the turned one carries on where its robust
      // cost is clearly lower. Where both starts end in the same basin their costs differ by the steps' own noise
      // (within 2 % on the ViSP desk, whose camera never stops to turn) and the start's solve stands; the turn
      // tabletop-scan's camera makes at frame 13 costs 5.5 % less than the translation the start slides into.
      constexpr double kTurnedMargin = 0.97;
      const auto& s = S.levels[l];
      const auto& t = T.levels[l];
      const bool hybrid = method == OdometryMethod::Hybrid;
      capture::Pose turned = init;
      const bool turnedOk = solveLevel(s, t, o.iterations[0], o, turned, out.steps, true) && solveAt(l, turned);
      solved = solveAt(l, pose);
      if (!turnedOk) continue;
      double kept = 0, other = 0;
      if (solved) subpixelStep(s, t, pose, hybrid, o, false, &kept);
      subpixelStep(s, t, turned, hybrid, o, false, &other);
      if (!solved || other < kTurnedMargin * kept) {
        pose = turned;
        solved = true;
        out.turnedInPlace = true;
      }
    }
    if (!solved) return out;
    out.T_target_source = pose;
    out.solved = true;
    measure(S.levels[0], T.levels[0], out, o);
    if (o.weakDirection > 0 && out.fitness > 0 && method != OdometryMethod::PointToPlane) {
      const cv::Matx33d held = heldDirections(S.levels[levels - 1], T.levels[levels - 1], out.T_target_source, o);
      // The motion from init, D = T * init^-1 (target frame): its translation along the directions the view
      // does not hold is taken back to init's, its rotation kept.
      cv::Matx31d values;
      cv::Matx33d vectors;  // rows
      cv::eigen(held, values, vectors);
      const capture::Pose D = out.T_target_source * capture::inversePose(init);
      cv::Vec3d t = capture::translationOf(D);
      for (int i = 0; i < 3; ++i)
        if (values(i) < o.weakDirection) {
          const cv::Vec3d v(vectors(i, 0), vectors(i, 1), vectors(i, 2));
          t -= v * v.dot(t);
          ++out.weakDirections;
        }
      if (out.weakDirections > 0) {
        out.T_target_source = capture::makePose(capture::rotationOf(D), t) * init;
        measure(S.levels[0], T.levels[0], out, o);
      }
    }
    return out;
  }

  /// What one source pixel's vertex meets in the target at pose T (projective association).
  struct Association {
    cv::Vec3d p;       ///< the source vertex in the target's frame
    int u = 0, w = 0;  ///< the target pixel it lands on
    cv::Vec3d n;       ///< the target's normal there
    double r = 0;      ///< point-to-plane residual (metres)
    bool overlaps = false, inlier = false;
  };
  /// Calls visit(a) for each source pixel with depth: whether it lands on a target pixel with depth
  /// (overlaps) and, within the outlier distance of it, is an inlier.
  template <class Visit>
  static void associate(const OdometryFrame::Impl::Level& s, const OdometryFrame::Impl::Level& t,
                        const capture::Pose& T, const OdometryOptions& o, Visit&& visit) {
    const cv::Matx33d R = capture::rotationOf(T);
    const cv::Vec3d tr = capture::translationOf(T);
    for (int y = 0; y < s.vertices.rows; ++y)
      for (int x = 0; x < s.vertices.cols; ++x) {
        const cv::Vec3f v = s.vertices.at<cv::Vec3f>(y, x);
        if (!std::isfinite(v[0])) continue;
        Association a;
        a.p = R * cv::Vec3d(v) + tr;
        if (a.p[2] > 0) {
          a.u = static_cast<int>(std::lround(t.k.fx * a.p[0] / a.p[2] + t.k.cx));
          a.w = static_cast<int>(std::lround(t.k.fy * a.p[1] / a.p[2] + t.k.cy));
          if (a.u >= 0 && a.w >= 0 && a.u < t.vertices.cols && a.w < t.vertices.rows) {
            const cv::Vec3f q = t.vertices.at<cv::Vec3f>(a.w, a.u);
            const cv::Vec3f n = t.normals.at<cv::Vec3f>(a.w, a.u);
            a.overlaps = std::isfinite(q[0]) && std::isfinite(n[0]);
            if (a.overlaps) {
              a.n = cv::Vec3d(n);
              a.r = (a.p - cv::Vec3d(q)).dot(a.n);
              a.inlier = std::abs(a.r) <= o.depthOutlierM && std::abs(a.p[2] - q[2]) <= o.depthOutlierM;
            }
          }
        }
        visit(a);
      }
  }

  /// How well the inliers hold each direction of translation: the mean over them of n n^T (their target
  /// normals) plus g g^T for the pixels whose intensity gradient is an edge (g: how the intensity there
  /// changes per metre the camera moves). Taken at the coarsest level: there a normal averages the depth's
  /// noise away (the finest level's normals, 2-3 m away, scatter enough to make a bare wall look as if it
  /// held every direction) and noise makes no edge.
  static cv::Matx33d heldDirections(const OdometryFrame::Impl::Level& s, const OdometryFrame::Impl::Level& t,
                                    const capture::Pose& T, const OdometryOptions& o) {
    constexpr float kEdge = 0.03f;  // intensity per coarse pixel (the sensor's noise there: about 0.002)
    cv::Matx33d held = cv::Matx33d::zeros();
    size_t inliers = 0;
    const cv::Mat& I = t.intensity;
    associate(s, t, T, o, [&](const Association& a) {
      if (!a.inlier) return;
      ++inliers;
      held += a.n * a.n.t();
      if (I.empty() || a.u < 1 || a.w < 1 || a.u + 1 >= I.cols || a.w + 1 >= I.rows) return;
      const float gx = 0.5f * (I.at<float>(a.w, a.u + 1) - I.at<float>(a.w, a.u - 1));
      const float gy = 0.5f * (I.at<float>(a.w + 1, a.u) - I.at<float>(a.w - 1, a.u));
      if (!(std::hypot(gx, gy) > kEdge)) return;  // also NaN
      const double ax = gx * t.k.fx / a.p[2], ay = gy * t.k.fy / a.p[2];
      const cv::Vec3d g(ax, ay, -(ax * a.p[0] + ay * a.p[1]) / a.p[2]);
      held += g * g.t();
    });
    return inliers ? held * (1.0 / static_cast<double>(inliers)) : held;
  }

  /// Quality at the finest level: of the source's pixels with depth, those that overlap the target and the
  /// inliers among them, with the inliers' point-to-plane RMSE, plain and scaled to 1 m range.
  static void measure(const OdometryFrame::Impl::Level& s, const OdometryFrame::Impl::Level& t, OdometryResult& out,
                      const OdometryOptions& o) {
    size_t valid = 0, overlapping = 0, inliers = 0;
    double sum2 = 0, range2 = 0;
    associate(s, t, out.T_target_source, o, [&](const Association& a) {
      ++valid;
      overlapping += a.overlaps;
      if (!a.inlier) return;
      ++inliers;
      sum2 += a.r * a.r;
      const double z2 = std::max(1.0, a.p[2] * a.p[2]);
      range2 += a.r * a.r / (z2 * z2);
    });
    const auto ratio = [](size_t a, size_t b) { return b ? static_cast<double>(a) / static_cast<double>(b) : 0.0; };
    out.fitness = ratio(inliers, valid);
    out.overlap = ratio(overlapping, valid);
    out.inlierRmse = inliers ? std::sqrt(sum2 / static_cast<double>(inliers)) : 0.0;
    out.rangeRmse = inliers ? std::sqrt(range2 / static_cast<double>(inliers)) : 0.0;
  }
};

OdometryResult estimateOdometry(const OdometryFrame& source, const OdometryFrame& target, const capture::Pose& init,
                                const OdometryOptions& options) {
  return OdometrySolver::solve(source, target, init, options);
}

}  // namespace mrgi::reconstruction
