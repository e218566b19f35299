#include "lighting/shadow_footprint.h"

#include <algorithm>
#include <cmath>

namespace mrgi::lighting {

namespace {

/// Grows `box` (x0, y0, x1, y1) by the image point of world point p; false when p lies at or behind the near plane.
bool addPoint(const CameraView& camera, const capture::Pose& T_camera_world, const cv::Vec3d& p, cv::Vec4d& box) {
  const cv::Vec4d q = T_camera_world * cv::Vec4d(p[0], p[1], p[2], 1.0);
  if (!(q[2] > camera.nearPlane)) return false;
  const capture::Intrinsics& k = camera.intrinsics;
  const double u = k.fx * q[0] / q[2] + k.cx, v = k.fy * q[1] / q[2] + k.cy;
  box = {std::min(box[0], u), std::min(box[1], v), std::max(box[2], u), std::max(box[3], v)};
  return true;
}

/// mayShadow for one light and sphere, what does not depend on the receiver worked out once: the footprint
/// asks it of every triangle of the camera's mesh (hundreds of thousands with a frame's own depth mesh), so
/// the test compares squared distances and takes a root only for a point light's extent.
class ShadowReach {
 public:
  ShadowReach(const SceneLight& light, const cv::Vec3d& centre, double radius)
      : directional_(light.type == LightType::Directional), centre_(centre), radius_(radius), extent_(light.extent) {
    if (directional_) {
      back_ = -light.direction;
      tanSpread_ = light.extent > 0 ? std::tan(std::min(light.extent, 1.5)) : 0;
    } else {
      position_ = light.position;
      toC_ = centre - light.position;
      near_ = cv::norm(toC_) - radius;
    }
  }

  bool reaches(const cv::Vec3d& x, double margin) const {
    if (directional_) {
      // Rays from x against the travel direction within the disc's half-angle: the one through the centre's
      // foot passes the centre at its perpendicular distance (the distance to x when the centre lies behind
      // x); the others lie within tan(half-angle) x their run.
      const cv::Vec3d toC = centre_ - x;
      const double along = toC.dot(back_), run = std::max(along, 0.0);
      const double reach = radius_ + margin + (run + radius_) * tanSpread_;
      const cv::Vec3d off = toC - run * back_;
      return off.dot(off) <= reach * reach;
    }
    // A light with extent: its soft shadow's blocker search at x looks over a disc of (|x - P| - near) a / near
    // (near: the sphere's front from the light), which moves the segment's points at the sphere by that times
    // their share of the segment; the penumbra a point of the light's sphere casts lies within the same.
    const cv::Vec3d toX = x - position_;
    const double len2 = toX.dot(toX);
    if (!(near_ > 1e-4) || !(len2 > 0)) return true;  // the light inside the sphere or at the receiver
    const double t = toC_.dot(toX) / len2;
    double reach = radius_ + margin;
    if (extent_ > 0) {
      const double len = std::sqrt(len2), share = std::clamp(t + radius_ / len, 0.0, 1.0);
      reach += 1.05 * extent_ * std::max(0.0, len - near_) / near_ * share;
    }
    const cv::Vec3d off = toC_ - std::clamp(t, 0.0, 1.0) * toX;  // the centre from the segment's nearest point
    return off.dot(off) <= reach * reach;
  }

 private:
  bool directional_;
  cv::Vec3d centre_;
  double radius_, extent_;
  cv::Vec3d back_, position_, toC_;
  double tanSpread_ = 0, near_ = 0;
};

}  // namespace

bool mayShadow(const SceneLight& light, const cv::Vec3d& centre, double radius, const cv::Vec3d& x, double margin) {
  return ShadowReach(light, centre, radius).reaches(x, margin);
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
  std::vector<ShadowReach> reach;
  reach.reserve(lights.size());
  for (const SceneLight& l : lights) reach.emplace_back(l, centre, radius);
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
    const cv::Vec3d a = v[0] - m, b = v[1] - m, c = v[2] - m;
    const double size = std::sqrt(std::max({a.dot(a), b.dot(b), c.dot(c)}));
    bool shadowed = false;
    for (const ShadowReach& r : reach) shadowed = shadowed || r.reaches(m, margin + size);
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

std::vector<cv::Rect> bandsAround(const cv::Rect& image, const cv::Rect& inner) {
  const cv::Rect in = inner & image;
  if (in.empty()) return image.empty() ? std::vector<cv::Rect>{} : std::vector<cv::Rect>{image};
  const std::vector<cv::Rect> all{{image.x, image.y, image.width, in.y - image.y},                     // above
                                  {image.x, in.y + in.height, image.width, image.br().y - in.br().y},  // below
                                  {image.x, in.y, in.x - image.x, in.height},                          // left
                                  {in.x + in.width, in.y, image.br().x - in.br().x, in.height}};       // right
  std::vector<cv::Rect> bands;
  for (const cv::Rect& r : all)
    if (r.width > 0 && r.height > 0) bands.push_back(r);
  return bands;
}

}  // namespace mrgi::lighting
