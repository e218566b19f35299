#pragma once
// Measures of the bench: a lighting result against the path-traced truth of the same frame (relative errors
// of the real-pixel delta and the virtual radiance, SSIM of the composites, error images), the frame-to-frame
// flicker of the real-pixel delta, and stage timings of full pipeline runs.
#include <map>
#include <string>
#include <utility>

#include <opencv2/core.hpp>

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
std::map<std::string, double> bestStages(lighting::LightingPipeline& pipe, const lighting::CameraView& view, int repeats,
                                         std::map<std::string, int>* runs = nullptr);

/// The path-traced truth of one frame.
struct Truth {
  int frame = 0;
  groundtruth::DifferentialImages images;
  cv::Mat delta, composite;  ///< the compositor's delta input; the reference composite (RGB8)
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
  size_t mismatched = 0;  ///< pixels virtual in one image only (silhouette), left out
  double nearAbs = 0, nearRef = 0;  ///< the delta's sums over real pixels near the objects (NearObjects)
  void add(const ErrorSums& e) {
    sq += e.sq, abs += e.abs, absRef += e.absRef, real += e.real;
    virtAbs += e.virtAbs, virtRef += e.virtRef, mismatched += e.mismatched;
    nearAbs += e.nearAbs, nearRef += e.nearRef;
  }
  double rmse() const { return real ? std::sqrt(sq / (3.0 * static_cast<double>(real))) : 0.0; }
  double relDelta() const { return absRef > 0 ? abs / absRef : 0.0; }
  double relVirtual() const { return virtRef > 0 ? virtAbs / virtRef : 0.0; }
  double relDeltaNear() const { return nearRef > 0 ? nearAbs / nearRef : 0.0; }
};
/// Real pixels near the objects: their surface point (G-buffer positions, CV_32FC4, w = valid) within
/// `radii` x the objects' bounding radius of its centre (the contact shadow and the bounce next to them).
struct NearObjects {
  cv::Mat positions;
  cv::Vec3d centre{0, 0, 0};
  double radius = 0;
  double radii = 2.0;
};
ErrorSums errorSums(const cv::Mat& shade, const Truth& truth, const NearObjects* near = nullptr);

/// The error as an image (RGB8): real pixels |delta_rt - delta_ref| (black = 0, white = `scale`; red: too dark,
/// green: too bright), virtual pixels their radiance's relative error (white = 10 %; blue: too dark, yellow:
/// too bright), pixels virtual in one image only grey.
cv::Mat errorImage(const cv::Mat& shade, const Truth& truth, double scale);

/// Mean SSIM over the three channels of two RGB8 images.
double ssimOf(const cv::Mat& a, const cv::Mat& b);

}  // namespace mrgi::evaluation
