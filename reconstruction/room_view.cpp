#include "reconstruction/room_view.h"

#include <opencv2/core/utility.hpp>

namespace mrgi::reconstruction {

RoomView renderRoomView(const RoomMesh& room, const MeshRays& rays, const capture::Pose& T_world_camera,
                        const capture::Intrinsics& k, double maxDepthM) {
  RoomView v{cv::Mat::zeros(k.height, k.width, CV_32F), cv::Mat::zeros(k.height, k.width, CV_32F)};
  const cv::Matx33d R = capture::rotationOf(T_world_camera);
  const cv::Vec3d o = capture::translationOf(T_world_camera);
  cv::parallel_for_(cv::Range(0, k.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* depth = v.depth.ptr<float>(y);
      float* lum = v.luminance.ptr<float>(y);
      for (int x = 0; x < k.width; ++x) {
        const cv::Vec3d camera((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0);
        const double length = cv::norm(camera);
        const MeshRays::Hit hit = rays.intersect(o, R * (camera / length), maxDepthM * length);
        if (!hit.hit || hit.triangle * 3 + 2 >= room.indices.size()) continue;
        depth[x] = static_cast<float>(hit.t / length);  // along the ray -> along the optical axis
        const uint32_t* tri = &room.indices[hit.triangle * 3];
        if (room.radiance.size() == room.positions.size()) {
          const cv::Vec3f c = static_cast<float>(1 - hit.u - hit.v) * room.radiance[tri[0]] +
                              static_cast<float>(hit.u) * room.radiance[tri[1]] +
                              static_cast<float>(hit.v) * room.radiance[tri[2]];
          lum[x] = std::max(0.f, 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]);
        }
      }
    }
  });
  return v;
}

}  // namespace mrgi::reconstruction
