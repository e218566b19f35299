#pragma once
/// Debug images of the lighting pipeline, RGB8 ready for PNG: signed quantities show positive values in
/// grey/white and negative ones in red, each with its scale printed by the caller.
#include <opencv2/core.hpp>
#include <vector>

namespace mrgi::lighting {

/// Signed luminance of a CV_32FC3/CV_32FC4 image (rgb used): grey = positive, red = negative, scaled so
/// `scale` (<= 0: the 99th percentile of |value|) maps to full intensity. Returns the scale used.
cv::Mat signedImage(const cv::Mat& image, double& scale);
/// A CV_32FC4 G-buffer normal (xyz in [-1, 1]) as RGB = n * 0.5 + 0.5; black where w = 0.
cv::Mat normalImage(const cv::Mat& normals);
/// Linear RGB (CV_32FC3/4) -> sRGB RGB8, optionally multiplied first.
cv::Mat linearImage(const cv::Mat& image, double multiply = 1.0);
/// The colour signedImage gives value v at `scale`: grey = positive, red = negative (sqrt-scaled).
cv::Vec3b signedColour(double v, double scale);
/// 99th percentile of v (reordered); 1 when v is empty or the percentile is not positive.
double percentile99(std::vector<double>& v);

}  // namespace mrgi::lighting
