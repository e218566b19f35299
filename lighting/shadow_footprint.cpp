#include "lighting/shadow_footprint.h"

#include <algorithm>
#include <cmath>

namespace mrgi::lighting {

namespace {

/// Distance from c to the segment a-b.
double segmentDistance(const cv::Vec3d& c, const cv::Vec3d& a, const cv::Vec3d& b) {
  const cv::Vec3d ab = b - a;
  const double len2 = ab.dot(ab);
  const double t = len2 > 0 ? std::clamp((c - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return cv::norm(c - (a + t * ab));
}

/// Grows `box` (x0, y0, x1, y1) by the image point of world point p; false when p lies at or behind the near plane.
bool addPoint(const CameraView& camera, const capture::Pose& T_camera_world, const cv::Vec3d& p, cv::Vec4d& box) {
  const cv::Vec4d q = T_camera_world * cv::Vec4d(p[0], p[1], p[2], 1.0);
  if (!(q[2] > camera.nearPlane)) return false;
  const capture::Intrinsics& k = camera.intrinsics;
  const double u = k.fx * q[0] / q[2] + k.cx, v = k.fy * q[1] / q[2] + k.cy;
  box = {std::min(box[0], u), std::min(box[1], v), std::max(box[2], u), std::max(box[3], v)};
  return true;
}

}  // namespace

bool mayShadow(const SceneLight& light, const cv::Vec3d& centre, double radius, const cv::Vec3d& x, double margin) {
  if (light.type == LightType::Directional) {
    // Rays from x against the travel direction within the disc's half-angle: the one through the centre's
    // foot passes the centre at its perpendicular distance; the others lie within tan(half-angle) x their run.
    const cv::Vec3d back = -light.direction;
    const double along = (centre - x).dot(back);
    const double spread =
        light.extent > 0 ? (std::max(along, 0.0) + radius) * std::tan(std::min(light.extent, 1.5)) : 0;
    return segmentDistance(centre, x, x + std::max(along, 0.0) * back) <= radius + margin + spread;
  }
  // A light with extent: its soft shadow's blocker search at x looks over a disc of (|x - P| - near) a / near
  // (near: the sphere's front from the light), which moves the segment's points at the sphere by that times
  // their share of the segment; the penumbra a point of the light's sphere casts lies within the same.
  const cv::Vec3d toX = x - light.position, toC = centre - light.position;
  const double len = cv::norm(toX), d = cv::norm(toC), near = d - radius;
  if (!(near > 1e-4) || !(len > 0)) return true;  // the light inside the sphere or at the receiver
  double spread = 0;
  if (light.extent > 0) {
    const double share = std::clamp(toC.dot(toX) / (len * len) + radius / len, 0.0, 1.0);
    spread = 1.05 * light.extent * std::max(0.0, len - near) / near * share;
  }
  return segmentDistance(centre, light.position, x) <= radius + margin + spread;
}

cv::Rect objectsFootprint(const CameraView& camera, const cv::Vec3d& centre, double radius,
                          const std::vector<SceneLight>& lights, double margin, const std::vector<MeshVertex>& vertices,
                          const std::vector<uint32_t>& indices) {
  const capture::Intrinsics& k = camera.intrinsics;
  const cv::Rect image(0, 0, k.width, k.height);
  const capture::Pose T = capture::inversePose(camera.T_world_camera);
  cv::Vec4d box(1e30, 1e30, -1e30, -1e30);
  // The objects: the corners of the sphere's box; one behind the camera sees them from inside it.
  for (int c = 0; c < 8; ++c) {
    const cv::Vec3d p =
        centre + cv::Vec3d(c & 1 ? radius : -radius, c & 2 ? radius : -radius, c & 4 ? radius : -radius);
    const cv::Vec4d q = T * cv::Vec4d(p[0], p[1], p[2], 1.0);
    if (q[2] > camera.nearPlane) {
      addPoint(camera, T, p, box);
    } else if ((T * cv::Vec4d(centre[0], centre[1], centre[2], 1.0))[2] + radius > camera.nearPlane) {
      return image;
    }
  }
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    cv::Vec3d v[3];
    bool valid = true;
    for (int j = 0; j < 3; ++j) {
      const uint32_t i = indices[t + static_cast<size_t>(j)];
      if (i >= vertices.size()) {
        valid = false;
        break;
      }
      v[j] = cv::Vec3d(vertices[i].position);
    }
    if (!valid) continue;
    const cv::Vec3d m = (v[0] + v[1] + v[2]) / 3.0;
    const double size = std::max({cv::norm(v[0] - m), cv::norm(v[1] - m), cv::norm(v[2] - m)});
    bool shadowed = false;
    for (const SceneLight& l : lights) shadowed = shadowed || mayShadow(l, centre, radius, m, margin + size);
    if (!shadowed) continue;
    for (const cv::Vec3d& p : v)
      if (!addPoint(camera, T, p, box)) {
        // A vertex at or behind the near plane: the triangle may cover any part of the image.
        if ((T * cv::Vec4d(m[0], m[1], m[2], 1.0))[2] + size > camera.nearPlane) return image;
      }
  }
  if (box[0] > box[2]) return {};
  const auto lo = [](double a) { return static_cast<int>(std::floor(std::max(a, -1e6))) - 2; };
  const auto hi = [](double a) { return static_cast<int>(std::ceil(std::min(a, 1e6))) + 3; };
  const int x0 = lo(box[0]), y0 = lo(box[1]), x1 = hi(box[2]), y1 = hi(box[3]);
  return cv::Rect(cv::Point(x0, y0), cv::Point(x1, y1)) & image;
}

}  // namespace mrgi::lighting
