#pragma once
/// Hole-aware guided filtering of metric depth with the colour image as guide (He et al., "Guided Image
/// Filtering"), and the real-scene triangle mesh built from the depth grid.
///
/// Invalid samples (0, NaN, inf, outside [minDepth, maxDepth]) carry weight 0 in every window statistic
/// (normalised weighting): they are never averaged in as zeros. On hole-free input the filter reduces to
/// the classic colour-guided filter and matches cv::ximgproc::guidedFilter (tests/reconstruction).
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "capture/types.h"

namespace mrgi::reconstruction {

struct DepthFilterOptions {
  int radiusPx = 4;           ///< box window (2r+1)^2 pixels
  double radiusMetres = 0.0;  ///< > 0: window radius chosen to span this many metres at the median depth
  double eps = 1e-3;          ///< regulariser of the guide covariance (guide channels in [0, 1])
  float minDepth = 0.1f;      ///< valid range, metres
  float maxDepth = 10.f;
  /// Depth-edge cut: a filtered value that moved more than edgeCut * z from its input keeps the input
  /// (no surface bridges a depth discontinuity); hole filling needs the window's depth spread below it.
  float edgeCut = 0.03f;
  bool removeSpikes = true;  ///< drop isolated samples further than edgeCut * z from their 5x5 median
  bool fillHoles = false;    ///< fill invalid pixels whose window is mostly valid and planar
  float fillMinValidFraction = 0.6f;
};

/// Depth with every unusable sample (NaN, inf, <= 0, outside the range) set to 0.
cv::Mat sanitizeDepth(const cv::Mat& depth, float minDepth, float maxDepth);

/// The guide image: CV_32FC3 in [0, 1] from an 8-bit colour image (any channel order) or a grey image.
cv::Mat guideFromColour(const cv::Mat& colour);

/// Box radius in pixels for the options at a frame's median valid depth (radiusPx if radiusMetres <= 0).
int filterRadiusPixels(const cv::Mat& depth, const capture::Intrinsics& k, const DepthFilterOptions& o);

/// Hole-aware guided filter. depth CV_32FC1 metres, guide CV_32FC3 or CV_32FC1 (same size); radius in
/// pixels. Output CV_32FC1 with 0 where no valid estimate exists.
cv::Mat guidedFilterDepth(const cv::Mat& depth, const cv::Mat& guide, int radius, const DepthFilterOptions& o);

/// Triangle mesh of the depth grid in the frame's camera space (metres, OpenCV axes).
struct DepthMesh {
  std::vector<cv::Vec3f> positions;
  std::vector<cv::Vec3f> normals;  ///< (0, 0, 0) where the normal is unknown
  std::vector<cv::Vec2f> pixels;   ///< image coordinates of each vertex (texture lookup)
  std::vector<uint32_t> indices;   ///< triangles, counter-clockwise seen from the camera
  size_t triangleCount() const { return indices.size() / 3; }
};

/// The depth jump, relative to the nearer depth, across which buildDepthMesh joins no two pixels.
constexpr float kDepthMeshMaxRelativeJump = 0.05f;

/// Mesh over every stride-th pixel: two triangles per grid cell, a triangle only where its three corners
/// are valid and no edge spans a depth jump larger than maxRelativeJump * z (discontinuity cut).
DepthMesh buildDepthMesh(const cv::Mat& positions, const cv::Mat& normals, int stride = 1,
                         float maxRelativeJump = kDepthMeshMaxRelativeJump);

}  // namespace mrgi::reconstruction
