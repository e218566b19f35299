#pragma once
// Debug views of one processed frame, as RGB8 images: what `mrgi replay --debug` writes and what the live
// window shows next to the composite.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "app/frame_pipeline.h"

namespace mrgi::app {

enum class DebugView {
  Composite,
  Delta,          ///< real pixels' delta (grey positive, red negative)
  Albedo,         ///< G-buffer albedo
  Normal,         ///< G-buffer normals
  Mask,           ///< G-buffer virtual mask
  RsmFlux,        ///< the last light's RSM^rho flux
  RsmNormal,      ///< the last light's RSM^rho normals
  Volume,         ///< DLPV (or lpv-diff rho) z-slices
  ValIrradiance,  ///< Kinect-VAL bounce irradiance on the virtual object
  SparsePoints,   ///< Kinect-VAL sparse points over the composite, coloured by their irradiance
  Fisheye,        ///< the last fisheye frame, tone-mapped, with the median-cut lights drawn
};

/// The file-name-friendly name ("delta", "gbuffer_albedo", "dlpv_slices", ...).
const char* debugViewName(DebugView v);
/// The views a pipeline of this technique can show (Composite first); fisheye only with a fisheye setup.
std::vector<DebugView> debugViews(const LightingSetup* setup);

/// Renders a view of the frame just processed (the pipeline's last run). `info` receives the scales the
/// image used (e.g. "debug_delta_scale"). Returns an empty image when the view has nothing to show (no
/// lighting ran on this frame, no fisheye frame yet).
cv::Mat renderDebugView(DebugView v, FramePipeline& frames, const FrameResult& r, const capture::Intrinsics& k,
                        const cv::Mat& fisheyeImage,
                        nlohmann::json* info = nullptr);

/// Draws the marker's axes (x red, y green, z blue, `length` metres) onto an RGB8 camera image.
void drawMarkerAxes(cv::Mat& rgb, const capture::Intrinsics& k, const capture::Pose& T_marker_camera, double length);

}  // namespace mrgi::app
