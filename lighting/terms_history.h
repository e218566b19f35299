#pragma once
/// The shading pass's object terms carried from frame to frame (frame knob `object_terms_history`):
/// lighting/terms_history.glsl is the GPU twin, run by lighting/object_terms.frag over the reduced grid.
///
/// Each texel's world point x is projected into the previous frame's camera; the previous grid's texel whose
/// source pixel (lighting/upsample.h reducedSource) lies nearest holds the point the terms were computed at
/// there, its normal and its terms. The history counts only where that surface is x's: a real surface both
/// times, within 2 % of x's distance from the camera (+ 2 mm) of x, its normal within about 25 degrees of x's
/// (n . n' >= 0.9). There the texel takes (1 - w) fresh + w history, an exponential average over frames that
/// takes the depth map's per-frame noise out of the terms; elsewhere (what the previous frame did not see:
/// a disocclusion, the image's edge, another surface) the fresh terms alone. The pipeline drops the history
/// whenever anything the terms depend on besides the camera changes (the objects, the lights, the ambient).
#include <opencv2/core.hpp>
#include <optional>

#include "lighting/frame/mesh.h"

namespace mrgi::lighting {

/// The previous frame's camera and reduced grid, as the history pass reads them.
struct HistoryCamera {
  cv::Matx44f cameraFromWorld = cv::Matx44f::eye();  ///< the previous camera's pose, inverted
  float fx = 1, fy = 1, cx = 0, cy = 0;              ///< its intrinsics, frame pixels
  int factor = 1;                                    ///< frame pixels per reduced texel
  cv::Size grid;                                     ///< the reduced grid's size
};

/// Camera `camera`'s view of its frame reduced to 1/factor (lighting/upsample.h reducedSize).
HistoryCamera historyCamera(const CameraView& camera, int factor);

/// Relative and absolute distance, and the normals' cosine, within which the history's surface is x's.
constexpr float kHistoryRelativeDistance = 0.02f;
constexpr float kHistoryAbsoluteDistance = 0.002f;
constexpr float kHistoryNormalCosine = 0.9f;

/// The previous grid's texel whose source pixel lies nearest x's image point; nullopt when x lies behind that
/// camera or its point falls outside the image by more than half a texel.
std::optional<cv::Point> historyTexel(const HistoryCamera& previous, const cv::Vec3f& x);

/// Whether the previous frame's surface at a texel (its position: xyz, w = 1 where real terms were computed;
/// its unit normal) is x's (normal n), seen from `eye`.
bool historyAgrees(const cv::Vec3f& x, const cv::Vec3f& n, const cv::Vec3f& eye, const cv::Vec4f& previousPosition,
                   const cv::Vec4f& previousNormal);

/// The terms a texel keeps: (1 - weight) fresh + weight history where `agrees`, else fresh; a non-finite
/// history counts as none.
cv::Vec4f blendHistory(const cv::Vec4f& fresh, const cv::Vec4f& history, float weight, bool agrees);

}  // namespace mrgi::lighting
