#pragma once
/// Monte-Carlo path tracer on the Embree ray caster: the ground truth the real-time techniques are
/// measured against. Materials are the real-time ones (Lambertian albedo plus the normalised Phong lobe of
/// the Kinect-VAL shading, see Material), lights are delta lights sampled at every vertex (next-event
/// estimation), emissive surfaces and the environment are found by the sampled paths.
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>

#include "capture/types.h"
#include "groundtruth/raycaster.h"

namespace mrgi::groundtruth {

struct PathTraceOptions {
  int spp = 64;         ///< samples (paths) per pixel
  int bounces = 3;      ///< indirect bounces after the first surface (0 = direct light only)
  uint64_t seed = 1;    ///< the image is a function of the seed alone (not of the thread count)
  bool jitter = false;  ///< spread samples over the pixel (anti-aliased) instead of through its centre
  int threads = 0;      ///< worker threads, 0 = all hardware threads
  /// Pixels inside `focus` take `focusSpp` samples instead of `spp` (where the objects' shadow and bounce
  /// fall: a reference's noise on the real-pixel delta gathers there); empty or focusSpp <= spp: none.
  cv::Rect focus;
  int focusSpp = 0;
  /// Called on the calling thread with the fraction of rows done (0..1), for a progress bar.
  std::function<void(double)> progress;
};

struct PinholeCamera {
  capture::Intrinsics intrinsics;
  capture::Pose T_world_camera;  ///< OpenCV camera frame (x right, y down, z forward) in the scene's world
};

/// World ray through image point (x, y) (pixel centres at integers); dir is unit length.
void cameraRay(const PinholeCamera& camera, double x, double y, cv::Vec3f& origin, cv::Vec3f& dir);

class PathTracer {
 public:
  PathTracer(const RayCaster& caster, PathTraceOptions options);

  /// One path's radiance estimate along the ray (camera rays see the lights' spheres; seeLights = false:
  /// the ray does not, for estimates whose direct light is counted apart).
  cv::Vec3f trace(cv::Vec3f origin, cv::Vec3f dir, cv::RNG& rng, bool seeLights = true) const;

  /// Mean radiance per pixel, CV_32FC3 linear RGB. Sample s of pixel (x, y) draws from its own random
  /// stream seeded by (seed, x, y, s): the image does not depend on the thread count, and two scenes
  /// rendered with one seed share their random numbers, so the difference ρ − μ is far less noisy than
  /// either image.
  cv::Mat render(const PinholeCamera& camera) const;

  const PathTraceOptions& options() const { return options_; }

 private:
  const RayCaster& caster_;
  PathTraceOptions options_;
};

/// The reference the compositor's inputs are judged by: ρ (the scene with the virtual objects), μ (the
/// real scene alone), both path traced with the same random numbers, and the virtual mask (pixels whose
/// centre ray first meets a virtual object's material).
struct DifferentialImages {
  cv::Mat rho, mu;  ///< CV_32FC3 linear radiance
  cv::Mat mask;     ///< CV_8UC1, 255 on virtual pixels
  /// The compositor's delta input: ρ − μ on real pixels, ρ on virtual pixels.
  cv::Mat delta() const;
};

/// 255 where the pixel's centre ray first meets a material marked virtual, else 0 (CV_8UC1).
cv::Mat virtualMask(const RayCaster& caster, const PinholeCamera& camera);

/// 255 where a virtual object covers part of the pixel but not all of it, 0 elsewhere (CV_8UC1): of n x n rays
/// through the centres of the pixel's n x n cells (the square a jittered render samples), some first meet a
/// virtual object's material and some do not — a render's value there mixes the object with what lies
/// beside it. Tested within `region` only (the whole image when empty; virtualFocus bounds the objects).
cv::Mat partlyVirtualMask(const RayCaster& caster, const PinholeCamera& camera, int n = 4, cv::Rect region = {});

/// The image box around the virtual objects (materials marked virtual) grown by `grow` times their bounding
/// sphere's radius on every side in the world, clipped to the image; empty when none is in front of the camera.
cv::Rect virtualFocus(const Scene& scene, const PinholeCamera& camera, double grow = 3.0);

/// Renders ρ from `withObjects` and μ from `realOnly` (progress reported over both, 0..1).
DifferentialImages renderDifferential(const Scene& withObjects, const Scene& realOnly, const PinholeCamera& camera,
                                      const PathTraceOptions& options);

}  // namespace mrgi::groundtruth
