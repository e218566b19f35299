#include "reconstruction/plane.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/rgbd.hpp>

namespace mrgi::reconstruction {

Plane transformPlane(const Plane& plane, const capture::Pose& T_new_old) {
  Plane out = plane;
  const cv::Matx33d R = capture::rotationOf(T_new_old);
  out.normal = R * plane.normal;
  out.centroid = capture::transformPoint(T_new_old, plane.centroid);
  // n'·x' + d' = 0 for x' = R x + t: d' = d - n'·t.
  out.d = plane.d - out.normal.dot(capture::translationOf(T_new_old));
  return out;
}

std::vector<Plane> findPlanes(const cv::Mat& positions, const cv::Mat& normals, const PlaneOptions& options,
                              cv::Mat* labels) {
  CV_Assert(positions.type() == CV_32FC3 && normals.type() == CV_32FC3 && positions.size() == normals.size());
  // The segmentation marks missing samples with NaN.
  cv::Mat points = positions.clone(), norms = normals.clone();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  int valid = 0;
  for (int y = 0; y < points.rows; ++y)
    for (int x = 0; x < points.cols; ++x) {
      cv::Vec3f& p = points.at<cv::Vec3f>(y, x);
      cv::Vec3f& n = norms.at<cv::Vec3f>(y, x);
      if (!(p[2] > 0.f) || !std::isfinite(p[2]) || n == cv::Vec3f(0, 0, 0)) {
        p = cv::Vec3f(nan, nan, nan);
        n = cv::Vec3f(nan, nan, nan);
      } else {
        ++valid;
      }
    }
  std::vector<Plane> planes;
  cv::Mat mask(points.size(), CV_8UC1, cv::Scalar(255));
  if (valid > 0) {
    const int block = std::max(8, points.cols / 16);
    const int minSize = std::max(block * block, static_cast<int>(options.minFraction * valid));
    // Sensor error model: threshold grows with z² (axial noise of structured light / ToF sensors).
    cv::rgbd::RgbdPlane segment(cv::rgbd::RgbdPlane::RGBD_PLANE_METHOD_DEFAULT, block, minSize, options.thresholdMetres,
                                0, 0, options.thresholdMetres);
    std::vector<cv::Vec4f> coefficients;
    segment(points, norms, mask, coefficients);
    planes.resize(coefficients.size());
    std::vector<cv::Vec3d> sums(coefficients.size(), cv::Vec3d(0, 0, 0));
    for (int y = 0; y < mask.rows; ++y)
      for (int x = 0; x < mask.cols; ++x) {
        const int i = mask.at<uchar>(y, x);
        if (i >= static_cast<int>(planes.size())) continue;
        ++planes[i].inliers;
        sums[i] += cv::Vec3d(points.at<cv::Vec3f>(y, x));
      }
    for (size_t i = 0; i < planes.size(); ++i) {
      cv::Vec3d n(coefficients[i][0], coefficients[i][1], coefficients[i][2]);
      double d = coefficients[i][3];
      const double len = cv::norm(n);
      n /= len, d /= len;
      if (d < 0) n = -n, d = -d;  // facing the camera (origin on the positive side)
      planes[i].normal = n;
      planes[i].d = d;
      planes[i].centroid = planes[i].inliers ? sums[i] / planes[i].inliers : cv::Vec3d(0, 0, 0);
    }
  }
  // Largest first, labels renumbered to match.
  std::vector<int> order(planes.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return planes[a].inliers > planes[b].inliers; });
  std::vector<Plane> sorted;
  std::vector<uchar> relabel(256, 255);
  for (size_t i = 0; i < order.size() && i < 255; ++i) {
    sorted.push_back(planes[order[i]]);
    relabel[order[i]] = static_cast<uchar>(i);
  }
  if (labels) {
    *labels = cv::Mat(mask.size(), CV_8UC1);
    for (int y = 0; y < mask.rows; ++y)
      for (int x = 0; x < mask.cols; ++x) labels->at<uchar>(y, x) = relabel[mask.at<uchar>(y, x)];
  }
  return sorted;
}

std::optional<Plane> supportPlane(const std::vector<Plane>& planes, const cv::Vec3d& point, const cv::Vec3d& up,
                                  const cv::Mat& labels, const capture::Pose& T_camera_frame,
                                  const capture::Intrinsics& k, double maxTiltDeg) {
  const double upLen = cv::norm(up);
  if (!(upLen > 0)) return std::nullopt;
  const cv::Vec3d u = up / upLen;
  const double cosTilt = std::cos(maxTiltDeg * CV_PI / 180.0);
  std::optional<Plane> under, nearest;
  double underDist = std::numeric_limits<double>::infinity(), nearestDist = underDist;
  for (size_t i = 0; i < planes.size(); ++i) {
    Plane p = planes[i];
    if (p.normal.dot(u) < 0) p.normal = -p.normal, p.d = -p.d;  // orient along up
    if (p.normal.dot(u) < cosTilt) continue;
    const double h = p.signedDistance(point);
    if (h < -0.02) continue;  // the point is below this plane (tolerance for an object resting on it)
    const double dist = std::abs(h);
    if (dist < nearestDist) nearestDist = dist, nearest = p;
    // Is the foot point on this plane's pixels (3x3 window)?
    const cv::Vec3d foot = capture::transformPoint(T_camera_frame, point - h * p.normal);
    if (!labels.empty() && foot[2] > 0) {
      const int px = static_cast<int>(std::lround(k.fx * foot[0] / foot[2] + k.cx));
      const int py = static_cast<int>(std::lround(k.fy * foot[1] / foot[2] + k.cy));
      bool hit = false;
      for (int dy = -1; dy <= 1 && !hit; ++dy)
        for (int dx = -1; dx <= 1 && !hit; ++dx) {
          const int x = px + dx * 2, y = py + dy * 2;
          hit = x >= 0 && y >= 0 && x < labels.cols && y < labels.rows && labels.at<uchar>(y, x) == i;
        }
      if (hit && dist < underDist) underDist = dist, under = p;
    }
  }
  return under ? under : nearest;
}

std::optional<capture::Pose> worldOnDominantPlane(const cv::Mat& positions, const cv::Mat& normals,
                                                  const capture::Intrinsics& k) {
  cv::Mat labels;
  const std::vector<Plane> planes = findPlanes(positions, normals, {}, &labels);
  if (planes.empty()) return std::nullopt;
  // Image up is the camera's -y: a floor or table seen from above faces it.
  const auto facesUp = [](const Plane& p) { return p.normal[1] < -0.3; };
  const Plane* chosen = nullptr;
  const int cx = std::clamp(static_cast<int>(std::lround(k.cx)), 0, labels.cols - 1);
  const int cy = std::clamp(static_cast<int>(std::lround(k.cy)), 0, labels.rows - 1);
  const uchar centre = labels.at<uchar>(cy, cx);
  if (centre < planes.size() && facesUp(planes[centre])) chosen = &planes[centre];
  for (size_t i = 0; i < planes.size() && !chosen; ++i)
    if (facesUp(planes[i])) chosen = &planes[i];
  if (!chosen) return std::nullopt;
  const cv::Vec3d n = chosen->normal;  // faces the camera: up
  // The centre's viewing ray meets the plane at t: n . (t r) + d = 0.
  const cv::Vec3d ray((cx - k.cx) / k.fx, (cy - k.cy) / k.fy, 1.0);
  const double denom = n.dot(ray);
  // A view along the floor meets it far beyond what it saw (20 m for a camera held level): there the origin is
  // the plane's seen centroid instead.
  const bool meets = std::abs(denom) > 1e-6 && -chosen->d / denom > 0 &&
                     cv::norm(ray * (-chosen->d / denom)) <= 2 * cv::norm(chosen->centroid);
  const cv::Vec3d origin = meets ? ray * (-chosen->d / denom) : chosen->centroid;
  cv::Vec3d x = cv::Vec3d(1, 0, 0) - n * n[0];
  if (cv::norm(x) < 1e-6) x = cv::Vec3d(0, 0, 1) - n * n[2];
  x /= cv::norm(x);
  const cv::Vec3d y = n.cross(x);
  const cv::Matx33d R(x[0], y[0], n[0], x[1], y[1], n[1], x[2], y[2], n[2]);  // columns: the world's axes in the camera
  return capture::makePose(R, origin);
}

capture::Pose restOnPlane(const capture::Pose& T_frame_object, const std::vector<cv::Vec3f>& points,
                          const Plane& plane) {
  const cv::Matx33d R = capture::rotationOf(T_frame_object);
  const cv::Vec3d z = R * cv::Vec3d(0, 0, 1), n = plane.normal;
  // Smallest rotation taking z onto n.
  const cv::Vec3d axis = z.cross(n);
  const double s = cv::norm(axis), c = z.dot(n);
  cv::Matx33d align = cv::Matx33d::eye();
  if (s > 1e-12) {
    cv::Rodrigues(axis * (std::atan2(s, c) / s), align);
  } else if (c < 0) {  // opposite: half turn about any axis perpendicular to n
    const cv::Vec3d perp =
        std::abs(n[0]) < 0.9 ? cv::normalize(n.cross(cv::Vec3d(1, 0, 0))) : cv::normalize(n.cross(cv::Vec3d(0, 1, 0)));
    cv::Rodrigues(perp * CV_PI, align);
  }
  const cv::Matx33d Rn = align * R;
  cv::Vec3d t = capture::translationOf(T_frame_object);
  t -= plane.signedDistance(t) * n;  // origin onto the plane
  double lowest = 0;
  bool any = false;
  for (const auto& p : points) {
    const double h = n.dot(Rn * cv::Vec3d(p));
    lowest = any ? std::min(lowest, h) : h;
    any = true;
  }
  t -= lowest * n;
  return capture::makePose(Rn, t);
}

}  // namespace mrgi::reconstruction
