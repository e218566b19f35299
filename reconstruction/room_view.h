#pragma once
/// The room model as a camera at a given pose would see it: per pixel the depth of the first surface along
/// its ray (Embree against the room's mesh) and the luminance of the fused radiance there (linear, exposure 1,
/// interpolated over the triangle). What frame-to-model tracking aligns a new frame with (KinectFusion's
/// prediction, from the mesh instead of the volume).
#include <opencv2/core.hpp>

#include "capture/types.h"
#include "reconstruction/mesh_rays.h"
#include "reconstruction/room_model.h"

namespace mrgi::reconstruction {

struct RoomView {
  cv::Mat depth;      ///< CV_32F metres along the optical axis, 0 where the ray meets nothing within maxDepthM
  cv::Mat luminance;  ///< CV_32F linear luminance of the fused radiance, 0 where no surface
};

/// `rays` must be built over `room`'s positions and indices.
RoomView renderRoomView(const RoomMesh& room, const MeshRays& rays, const capture::Pose& T_world_camera,
                        const capture::Intrinsics& k, double maxDepthM = 4.0);

}  // namespace mrgi::reconstruction
