#pragma once
/// Rays against a triangle mesh (Embree): shadow rays for the room's albedo, and first hits for the room's
/// environment as seen from a virtual object.
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

namespace mrgi::reconstruction {

class MeshRays {
 public:
  MeshRays(const std::vector<cv::Vec3f>& positions, const std::vector<uint32_t>& indices);
  ~MeshRays();
  MeshRays(const MeshRays&) = delete;
  MeshRays& operator=(const MeshRays&) = delete;

  /// True if anything lies on the segment o + t d, t in (0, far) (d unit).
  bool occluded(const cv::Vec3d& o, const cv::Vec3d& d, double far) const;

  struct Hit {
    bool hit = false;
    double t = 0;
    uint32_t triangle = 0;
    double u = 0, v = 0;  ///< barycentrics of the triangle's 2nd and 3rd vertex
  };
  Hit intersect(const cv::Vec3d& o, const cv::Vec3d& d, double far = 1e30) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mrgi::reconstruction
