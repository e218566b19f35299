#include "reconstruction/mesh_rays.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mrgi::reconstruction {

struct MeshRays::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

MeshRays::MeshRays(const std::vector<cv::Vec3f>& positions, const std::vector<uint32_t>& indices)
    : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(nullptr);
  impl_->scene = rtcNewScene(impl_->device);
  if (!positions.empty() && indices.size() >= 3) {
    RTCGeometry g = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), positions.size()));
    for (size_t i = 0; i < positions.size(); ++i)
      for (int k = 0; k < 3; ++k) v[3 * i + k] = positions[i][k];
    auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                               3 * sizeof(unsigned), indices.size() / 3));
    std::copy(indices.begin(), indices.begin() + static_cast<std::ptrdiff_t>(indices.size() / 3 * 3), idx);
    rtcCommitGeometry(g);
    rtcAttachGeometry(impl_->scene, g);
    rtcReleaseGeometry(g);
  }
  rtcCommitScene(impl_->scene);
}

MeshRays::~MeshRays() = default;

namespace {
RTCRay makeRay(const cv::Vec3d& o, const cv::Vec3d& d, double far) {
  // Embree asserts (aborts) on a ray it cannot trace; such a ray is the caller's error, never a signal.
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(o[k]) || std::abs(o[k]) > 1e6 || !std::isfinite(d[k]))
      throw std::invalid_argument("MeshRays: a ray's origin or direction is not finite or lies beyond 1e6 m");
  if (d[0] == 0 && d[1] == 0 && d[2] == 0) throw std::invalid_argument("MeshRays: a ray without a direction");
  if (std::isnan(far)) throw std::invalid_argument("MeshRays: a ray's far distance is nan");
  RTCRay ray{};
  ray.org_x = static_cast<float>(o[0]), ray.org_y = static_cast<float>(o[1]), ray.org_z = static_cast<float>(o[2]);
  ray.dir_x = static_cast<float>(d[0]), ray.dir_y = static_cast<float>(d[1]), ray.dir_z = static_cast<float>(d[2]);
  ray.tnear = 0.f;
  ray.tfar = static_cast<float>(std::min(far, 1e30));
  ray.mask = 0xffffffffu;
  return ray;
}
}  // namespace

bool MeshRays::occluded(const cv::Vec3d& o, const cv::Vec3d& d, double far) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay ray = makeRay(o, d, far);
  rtcOccluded1(impl_->scene, &ctx, &ray);
  return ray.tfar < 0;  // Embree sets tfar = -inf on a hit
}

MeshRays::Hit MeshRays::intersect(const cv::Vec3d& o, const cv::Vec3d& d, double far) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh{};
  rh.ray = makeRay(o, d, far);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &ctx, &rh);
  Hit h;
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return h;
  h.hit = true;
  h.t = rh.ray.tfar;
  h.triangle = rh.hit.primID;
  h.u = rh.hit.u, h.v = rh.hit.v;
  return h;
}

}  // namespace mrgi::reconstruction
