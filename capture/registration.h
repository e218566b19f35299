#pragma once
/// Depth -> colour registration: resamples a depth image from the depth camera into the colour camera.
#include <opencv2/core.hpp>

#include "capture/types.h"

namespace mrgi::capture {

/// Forward-warps every valid depth pixel into the colour camera (T_colour_depth, both pinhole models) and
/// keeps the nearest surface per colour pixel (z-buffer), so foreground never shows through background.
/// Returns CV_32FC1 metres at the colour resolution, 0 where no depth sample landed; depth values are the
/// z in the colour camera. Each sample covers the colour pixels of its footprint's four corners' bounding
/// box (at most maxSplat wide) so no cracks open when the colour image is larger.
cv::Mat registerDepthToColour(const cv::Mat& depth, const Intrinsics& depthK, const Intrinsics& colourK,
                              const Pose& T_colour_depth, int maxSplat = 3);

/// Registers the frame's depth in place when it is not registered yet (no-op otherwise).
void ensureRegistered(RgbdFrame& frame);

}  // namespace mrgi::capture
