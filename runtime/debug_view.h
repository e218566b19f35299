#pragma once
// Debug views of one processed frame, as RGB8 images: what `mrgi replay --debug` writes and what the live
// window shows next to the composite.
#include <array>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "runtime/frame_pipeline.h"

namespace mrgi::runtime {

/// A view by its file-name-friendly name: the shared ones below, and each technique's own (e.g. "dlpv_slices").
using DebugView = std::string;
struct Views {
  static inline const DebugView kComposite = "composite";
  static inline const DebugView kDelta = "delta";            ///< real pixels' delta (grey positive, red negative)
  static inline const DebugView kAlbedo = "gbuffer_albedo";  ///< G-buffer albedo
  static inline const DebugView kNormal = "gbuffer_normal";  ///< G-buffer normals
  static inline const DebugView kMask = "gbuffer_mask";      ///< G-buffer virtual mask
  static inline const DebugView kRsmFlux = "rsm_flux";       ///< the last light's RSM^rho flux
  static inline const DebugView kRsmNormal = "rsm_normal";   ///< the last light's RSM^rho normals
  static inline const DebugView kFisheye =
      "fisheye_lights";  ///< the last fisheye frame, tone-mapped, with the median-cut lights
  static inline const DebugView kRoomLights =
      "room_lights";  ///< the room's fused radiance seen from the object, with its lights
  static inline const DebugView kRoomRadiance =
      "room_radiance";  ///< the fused room seen from the camera: its radiance at the frame's exposure
  static inline const DebugView kRoomAlbedo =
      "room_albedo";  ///< the fused room seen from the camera: its albedo under the current lights
};

inline const char* debugViewName(const DebugView& v) { return v.c_str(); }
/// The views a frame pipeline can show (composite first, then the shared ones, each technique's, and the
/// fisheye with a fisheye setup).
std::vector<DebugView> debugViews(FramePipeline& frames);

/// Renders a view of the frame just processed (the pipeline's last run). `info` receives the scales the
/// image used (e.g. "debug_delta_scale"). Returns an empty image when the view has nothing to show (no
/// lighting ran on this frame, no fisheye frame yet).
cv::Mat renderDebugView(const DebugView& v, FramePipeline& frames, const FrameResult& r, const capture::Intrinsics& k,
                        const cv::Mat& fisheyeImage, nlohmann::json* info = nullptr);

/// The room's environment at the object (lat-long, row 0 = +z of the marker frame, column 0 = +x), tone-mapped
/// so that the 99th percentile reads 0.8, its lights circled (orange: mostly saturated surfaces).
cv::Mat roomLightsImage(const reconstruction::RoomLights& lights);
/// Where unit direction `d` (marker frame) falls on a lat-long image of `size` laid out as roomLightsImage's.
cv::Point latLongPixel(const cv::Vec3d& d, cv::Size size);

/// The room seen from a camera: per pixel the first room triangle its ray meets (rays: the room's), `values`
/// (one per room vertex) interpolated with the hit's barycentrics; CV_32FC3, (0, 0, 0) where the ray meets
/// nothing, and `hitMask` (CV_8U, optional) 255 where it meets the room.
cv::Mat roomSeenFrom(const reconstruction::MeshRays& rays, const reconstruction::RoomMesh& room,
                     const std::vector<cv::Vec3f>& values, const capture::Intrinsics& k,
                     const capture::Pose& T_world_camera, cv::Mat* hitMask = nullptr);

/// Draws the marker's axes (x red, y green, z blue, `length` metres) onto an RGB8 camera image.
void drawMarkerAxes(cv::Mat& rgb, const capture::Intrinsics& k, const capture::Pose& T_marker_camera, double length);
/// The same axes as pixel positions: the marker's origin, then the ends of its x, y and z axes (drawn red,
/// green, blue), for drawing them over an image that stays on the GPU.
std::array<cv::Point2f, 4> markerAxesPixels(const capture::Intrinsics& k, const capture::Pose& T_marker_camera,
                                            double length);

}  // namespace mrgi::runtime
