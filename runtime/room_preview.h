#pragma once
/// A picture of a fused room for a person (mrgi room writes it as ROOM/preview.png): the room ray cast from
/// the recording's first fused camera and from high in the room looking down at the object's place, each as
/// its fused radiance beside its albedo under the room's own lights (parts never scanned dark blue); below,
/// the room's environment at the object's place with its lights circled, numbered and listed (kind,
/// irradiance, direction).
#include <opencv2/core.hpp>
#include <optional>

#include "capture/types.h"
#include "reconstruction/room_model.h"

namespace mrgi::runtime {

struct RoomPreviewOptions {
  cv::Vec3d at{0, 0, 0.06};  ///< where the virtual object will be (the lights' point), marker frame
  int width = 320;           ///< of each view (4:3)
  int lightCount = 4;
};

/// RGB8. `T_world_camera` / `k`: the first fused frame's camera (none: the high view only).
/// `coverage` (optional): the share of the directions around `at` the room covers.
cv::Mat roomPreview(const reconstruction::RoomMesh& room, const std::optional<capture::Pose>& T_world_camera,
                    const capture::Intrinsics& k, const RoomPreviewOptions& options = {}, double* coverage = nullptr);

}  // namespace mrgi::runtime
