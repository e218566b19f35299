#pragma once
/// What a technique builds for itself from each frame on the CPU, beside the shared resources (G-buffer, RSMs,
/// shadow maps): e.g. real surfaces as light sources of its own kind. Shared code carries it without knowing
/// what it is: the technique hands out a builder (Technique::inputBuilder), the application runs it on each
/// frame (on its prepare worker, frames in order) or once on a room, and the frame holds the result for the
/// technique to read back (FrameResources::techniqueInput), counted as the kInputOwn input.
#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <vector>

#include "capture/types.h"
#include "reconstruction/room_model.h"

namespace mrgi::lighting {

/// A technique's own input; it knows its concrete type.
struct TechniqueInput {
  virtual ~TechniqueInput() = default;
  /// What the frame's summary says about it (counts: {"points": n}).
  virtual nlohmann::json facts() const { return nlohmann::json::object(); }
};

/// One camera frame as an input builder sees it.
struct InputFrame {
  cv::Mat positions, normals;  ///< CV_32FC3 camera space, of the filtered depth (no depth: z <= 0 or not finite)
  cv::Mat radiance;            ///< CV_32FC3 linear RGB, the camera's exposure divided out
  capture::Intrinsics intrinsics;
  capture::Pose T_world_camera = capture::identityPose();  ///< into the lighting world
};

class TechniqueInputBuilder {
 public:
  virtual ~TechniqueInputBuilder() = default;
  /// The input from this frame (may carry state over frames: fusion).
  virtual std::shared_ptr<const TechniqueInput> fromFrame(const InputFrame& frame) = 0;
  /// The input from a room model (lighting world), its triangles `indices` only (those the lighting sees).
  virtual std::shared_ptr<const TechniqueInput> fromRoom(const reconstruction::RoomMesh& room,
                                                         const std::vector<uint32_t>& indices) = 0;
};

}  // namespace mrgi::lighting
