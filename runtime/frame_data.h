#pragma once
// What a frame carries through the frame pipeline (runtime/frame_pipeline.h): its measurement and result,
// the real surface the lighting sees, and the CPU half prepared ahead of the GL half.
#include <array>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "gl/profiler.h"
#include "lighting/frame/mesh.h"
#include "lighting/frame/technique_input.h"
#include "lighting/scene.h"
#include "runtime/pose_source.h"

namespace mrgi::runtime {

struct FrameResult {
  cv::Mat composite;                             ///< 8-bit RGB, same order as the camera image
  std::optional<capture::Pose> T_marker_camera;  ///< nullopt when the frame is lost (CameraPose)
  CameraPose pose;                               ///< how the frame was posed
  cv::Mat positions, normals;                    ///< camera frame, from the filtered depth (empty without a scene)
  bool lit = false;                              ///< the lighting pipeline ran (a scene and a marker pose)
  bool reusedSurface = false;  ///< static camera: the last frame's real surface was kept (FrameOptions::reuse)
  double exposure = 1.0;       ///< the colour image's exposure (capture::RgbdFrame::exposure)
  nlohmann::json info = nlohmann::json::object();  ///< per-frame facts for the stats (marker status, lights)
};

/// A measured frame's filtered depth (metres, the z of its positions; 0 where none), as the room model
/// fuses it.
cv::Mat measuredDepth(const FrameResult& r);

/// The real scene as the lighting sees it: the filtered depth's mesh in the marker frame, each vertex
/// with the albedo estimated at its pixel under the setup's lights.
struct RealSurface {
  std::vector<lighting::MeshVertex> vertices;
  std::vector<uint32_t> indices;
  cv::Mat pixelAlbedo;  ///< CV_32FC3 per colour pixel (the vertices sample it every meshStride pixels)
};

/// What fusing a frame into the room being built gave (FrameOptions::fuse), from the fusion thread: the
/// facts for FrameResult::info["room_fusion"], the room's surface when this frame refreshed it, and the stages it
/// timed (room_fusion, room_mesh).
struct FusedFrame {
  nlohmann::json info = nlohmann::json::object();
  std::shared_ptr<const reconstruction::RoomMesh> refreshedRoom;
  std::shared_ptr<gl::Profiler> stages;
};

/// The CPU half of a frame (FramePipeline::prepare): its measurement and, lit from its own depth, its real
/// surface and the techniques' own inputs, with the lights and ambient it is to be lit under. It touches no GL, so the
/// next frame's may be made on another thread while the GL half of this one runs.
struct PreparedFrame {
  FrameResult result;
  std::optional<RealSurface> surface;  ///< the real scene from this frame's depth, when built
  /// The techniques' own inputs from this frame (technique name, input), when built.
  std::vector<std::pair<std::string, std::shared_ptr<const lighting::TechniqueInput>>> inputs;
  /// FrameOptions::fuse: the frame's fusion, running on the pipeline's fusion thread (render() takes it up).
  std::shared_future<FusedFrame> fused;
  /// FrameOptions::fuse: the room's surface refreshed after this frame was fused (render() takes it up).
  std::shared_ptr<const reconstruction::RoomMesh> refreshedRoom;
  std::vector<lighting::SceneLight> lights;  ///< marker frame, as they were for this frame
  cv::Vec3d ambient{0, 0, 0};
  std::array<cv::Vec3d, 9> ambientSh{};
  std::shared_ptr<const lighting::RadianceMap> ambientMap;  ///< LightingSetup::ambientMap, as it was for this frame
};

}  // namespace mrgi::runtime
