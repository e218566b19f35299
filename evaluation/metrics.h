#pragma once
// Measures of the bench: a lighting result against the path-traced truth of the same frame (relative errors
// of the real-pixel delta and the virtual radiance, SSIM of the composites, error images), the frame-to-frame
// flicker of the real-pixel delta, and stage timings of full pipeline runs.
#include <array>
#include <map>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "capture/types.h"
#include "gl/profiler.h"
#include "groundtruth/path_tracer.h"
#include "lighting/pipeline.h"

namespace mrgi::evaluation {

/// Stage times of one pipeline run (ms, the larger of CPU wall and GPU time per stage).
std::map<std::string, double> stageMs(gl::Profiler& profiler);

/// Best (per stage) over `repeats` full runs of the pipeline with no lights: each repeat starts from an
/// invalidated pipeline, so no stage is skipped because its inputs did not change. `runs` (optional) counts
/// per stage the repeats that timed it.
std::map<std::string, double> bestStages(lighting::LightingPipeline& pipe, const lighting::CameraView& view,
                                         int repeats, std::map<std::string, int>* runs = nullptr);

/// The path-traced truth of one frame.
struct Truth {
  int frame = 0;
  groundtruth::DifferentialImages images;
  cv::Mat delta, composite;  ///< the compositor's delta input; the reference composite (RGB8)
  cv::Mat second;            ///< where rendered: the delta of a second, independent render (another seed)
  /// CV_8UC1, 255 where the objects cover part of the pixel (groundtruth::partlyVirtualMask): the jittered
  /// reference mixes the object with what lies beside it there, which no binary mask can; left out of the
  /// per-pixel errors. Empty: none known.
  cv::Mat partial;
  bool partlyVirtual(int y, int x) const { return !partial.empty() && partial.at<uchar>(y, x) != 0; }
};

/// What one frame of a configuration left behind for the flicker of the next.
struct FrameState {
  cv::Mat shade, positions;  ///< RGBA32F: delta or virtual radiance (a = virtual); G-buffer positions (w = valid)
  cv::Mat smooth;            ///< CV_32F: luminance of the real pixels' delta, averaged over a 5x5 window of real pixels
  capture::Pose T_marker_camera;
};

/// The frame's state; the delta's luminance is box-averaged over real, valid pixels (normalised convolution),
/// so that a shadow edge landing one pixel over after reprojection does not count as flicker.
FrameState frameState(cv::Mat shade, cv::Mat positions, const capture::Pose& T_marker_camera);

/// Frame-to-frame change of the real pixels' smoothed delta at the same marker-frame points (reprojected with
/// the camera poses), relative to its magnitude: sums of |lum d_t - lum d_t-1| and |lum d_t-1| over matched pixels.
std::pair<double, double> flickerSums(const FrameState& prev, const FrameState& cur, const capture::Intrinsics& k);

/// Error sums of one frame against its truth.
struct ErrorSums {
  double sq = 0, abs = 0, absRef = 0;
  size_t real = 0;
  double virtAbs = 0, virtRef = 0;
  size_t mismatched = 0;            ///< pixels virtual in one image only (silhouette), left out
  size_t partial = 0;               ///< pixels the objects cover in part (Truth::partial), left out
  double nearAbs = 0, nearRef = 0;  ///< the delta's sums over real pixels near the objects (NearObjects)
  /// Per 16 x 16-pixel block with real pixels (over every frame added): the real-pixel delta's sums
  /// {|delta - reference|, |reference|}, for the relative L1's interval.
  std::vector<std::array<double, 2>> blocks;
  void add(const ErrorSums& e) {
    sq += e.sq, abs += e.abs, absRef += e.absRef, real += e.real;
    virtAbs += e.virtAbs, virtRef += e.virtRef, mismatched += e.mismatched, partial += e.partial;
    nearAbs += e.nearAbs, nearRef += e.nearRef;
    blocks.insert(blocks.end(), e.blocks.begin(), e.blocks.end());
  }
  double rmse() const { return real ? std::sqrt(sq / (3.0 * static_cast<double>(real))) : 0.0; }
  double relDelta() const { return absRef > 0 ? abs / absRef : 0.0; }
  double relVirtual() const { return virtRef > 0 ? virtAbs / virtRef : 0.0; }
  double relDeltaNear() const { return nearRef > 0 ? nearAbs / nearRef : 0.0; }
  /// The 95 % interval of relDelta() over the blocks (a ratio estimator's standard error: the blocks'
  /// residuals |e|_b - R |r|_b), clamped at 0; {relDelta, relDelta} with fewer than two blocks.
  std::array<double, 2> relDeltaInterval() const;
};
/// Real pixels near the objects: their surface point (G-buffer positions, CV_32FC4, w = valid) within
/// `radii` x the objects' bounding radius of its centre (the contact shadow and the bounce next to them).
struct NearObjects {
  cv::Mat positions;
  cv::Vec3d centre{0, 0, 0};
  double radius = 0;
  double radii = 2.0;
  /// Whether the G-buffer position p (w = valid) lies within radii x radius of the centre.
  bool contains(const cv::Vec4f& p) const {
    return radius > 0 && p[3] > 0.5f && cv::norm(cv::Vec3d(p[0], p[1], p[2]) - centre) <= radii * radius;
  }
};
ErrorSums errorSums(const cv::Mat& shade, const Truth& truth, const NearObjects* near = nullptr);

/// The object's shadow on the real pixels near it (within near.radii object radii; 3 is the measure),
/// luminance of the delta: `energy` = the darkening's sum (negative parts) over the reference's, and
/// `nearL1` = sum |G(delta) - G(reference)| / sum |G(reference)| with G a Gaussian of sigma 2 px over the
/// near real pixels only (normalised convolution), which takes most of the reference's per-pixel noise out.
/// Sums add over frames (ratio() of the totals).
struct ShadowSums {
  double dark = 0, darkRef = 0, l1 = 0, l1Ref = 0;
  size_t pixels = 0;
  void add(const ShadowSums& o) {
    dark += o.dark, darkRef += o.darkRef, l1 += o.l1, l1Ref += o.l1Ref, pixels += o.pixels;
  }
  double energy() const { return darkRef < 0 ? dark / darkRef : 0.0; }
  double nearL1() const { return l1Ref > 0 ? l1 / l1Ref : 0.0; }
};
ShadowSums shadowSums(const cv::Mat& shade, const Truth& truth, const NearObjects& near);

/// The squared error of an image against a truth known only through two independent noisy renders of it
/// (r1, r2: the truth plus zero-mean noise of any variance, as path-traced references with two seeds are).
/// Against either render alone the squared error carries that render's noise variance; the product
/// (x - r1)(x - r2) has the expectation (x - t)^2 itself, so its mean over pixels is unbiased for the squared
/// error, and r1 r2 for t^2 (the scale of a relative error). The pixels of a `tile` x `tile` block are
/// summed into one sample (neighbouring pixels' noise and errors correlate, blocks much less); the 95 %
/// interval is the normal one over the blocks (1.96 standard errors of their mean).
struct UnbiasedError {
  double meanSq = 0, meanSqLo = 0, meanSqHi = 0;  ///< per pixel and channel; may dip below 0 within the noise
  double refSq = 0;                               ///< mean r1 r2 per pixel and channel (unbiased for mean t^2)
  size_t pixels = 0, blocks = 0;
  /// The relative RMS error sqrt(meanSq / refSq) and its interval (clamped at 0).
  double rel() const;
  double relLo() const;
  double relHi() const;
};
/// x, r1, r2: CV_32FC3 (or CV_32FC4, alpha ignored) of one size; mask CV_8UC1, non-zero where a pixel counts
/// (empty: every pixel).
UnbiasedError unbiasedSquaredError(const cv::Mat& x, const cv::Mat& r1, const cv::Mat& r2, const cv::Mat& mask,
                                   int tile = 16);
/// The real-pixel delta's error against a truth rendered twice (unbiasedSquaredError over the pixels real in
/// both the result and the reference); nullopt without a second render.
std::optional<UnbiasedError> unbiasedDeltaError(const cv::Mat& shade, const Truth& truth);

/// The error as an image (RGB8): real pixels |delta_rt - delta_ref| (black = 0, white = `scale`; red: too dark,
/// green: too bright), virtual pixels their radiance's relative error (white = 10 %; blue: too dark, yellow:
/// too bright), pixels virtual in one image only grey.
cv::Mat errorImage(const cv::Mat& shade, const Truth& truth, double scale);

/// Mean SSIM over the three channels of two RGB8 images.
double ssimOf(const cv::Mat& a, const cv::Mat& b);

}  // namespace mrgi::evaluation
