#include "reconstruction/marker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "reconstruction/apriltag_family.h"
#include "reconstruction/depth.h"

extern "C" {
#include <apriltag/common/zarray.h>
}

namespace mrgi::reconstruction {

// ---------------------------------------------------------------------------------------------- detector

struct TagDetector::Impl {
  detail::FamilyHandle family;
  apriltag_detector_t* detector = nullptr;
  ~Impl() {
    if (detector) apriltag_detector_destroy(detector);
  }
};

TagDetector::TagDetector(const DetectorOptions& options) : impl_(std::make_unique<Impl>()), options_(options) {
  impl_->family = detail::createFamily(options.family);
  impl_->detector = apriltag_detector_create();
  apriltag_detector_add_family_bits(impl_->detector, impl_->family.family, std::max(0, options.maxHamming));
  impl_->detector->quad_decimate = std::max(1.0f, options.decimate);
  impl_->detector->quad_sigma = options.blurSigma;
  impl_->detector->nthreads = std::max(1, options.threads);
  impl_->detector->refine_edges = true;
}

TagDetector::~TagDetector() = default;

std::vector<TagDetection> TagDetector::detect(const cv::Mat& image, cv::Rect roi) const {
  // Whole 4-pixel tiles of the image (libapriltag thresholds per tile of 4 x 4 pixels from the image's origin).
  constexpr int kTile = 4;
  roi &= cv::Rect(0, 0, image.cols, image.rows);
  const int x0 = roi.x / kTile * kTile, y0 = roi.y / kTile * kTile;
  const int x1 = std::min((roi.x + roi.width + kTile - 1) / kTile * kTile, image.cols / kTile * kTile);
  const int y1 = std::min((roi.y + roi.height + kTile - 1) / kTile * kTile, image.rows / kTile * kTile);
  if (x1 - x0 < 2 * kTile || y1 - y0 < 2 * kTile) return {};
  const cv::Rect region(x0, y0, x1 - x0, y1 - y0);
  std::vector<TagDetection> out = detect(image(region));
  for (TagDetection& d : out) {
    for (cv::Point2d& c : d.corners) c += cv::Point2d(region.x, region.y);
    d.centre += cv::Point2d(region.x, region.y);
  }
  return out;
}

cv::Rect tagSearchRegion(const std::array<cv::Point2d, 4>& corners, double grow) {
  double lx = corners[0].x, hx = lx, ly = corners[0].y, hy = ly;
  for (const cv::Point2d& c : corners)
    lx = std::min(lx, c.x), hx = std::max(hx, c.x), ly = std::min(ly, c.y), hy = std::max(hy, c.y);
  const double g = grow * std::max(hx - lx, hy - ly);
  if (!std::isfinite(g)) return {};
  return cv::Rect(cv::Point(static_cast<int>(std::floor(lx - g)), static_cast<int>(std::floor(ly - g))),
                  cv::Point(static_cast<int>(std::ceil(hx + g)) + 1, static_cast<int>(std::ceil(hy + g)) + 1));
}

bool tagWellInside(const TagDetection& d, const cv::Rect& roi, double margin) {
  for (const cv::Point2d& c : d.corners)
    if (c.x < roi.x + margin || c.y < roi.y + margin || c.x > roi.x + roi.width - margin ||
        c.y > roi.y + roi.height - margin)
      return false;
  return true;
}

std::vector<TagDetection> TagDetector::detect(const cv::Mat& image) const {
  cv::Mat grey;
  if (image.type() == CV_8UC1)
    grey = image;
  else if (image.type() == CV_8UC3)
    cv::cvtColor(image, grey, cv::COLOR_RGB2GRAY);
  else if (image.type() == CV_8UC4)
    cv::cvtColor(image, grey, cv::COLOR_RGBA2GRAY);
  else
    throw std::invalid_argument("tag detection needs an 8-bit grey or colour image");
  std::vector<TagDetection> out;
  if (grey.empty()) return out;
  image_u8_t im{grey.cols, grey.rows, static_cast<int32_t>(grey.step[0]), grey.data};
  zarray_t* found = apriltag_detector_detect(impl_->detector, &im);
  for (int i = 0; i < zarray_size(found); ++i) {
    apriltag_detection_t* d = nullptr;
    zarray_get(found, i, &d);
    if (d->hamming > options_.maxHamming || d->decision_margin < options_.minDecisionMargin) continue;
    TagDetection t;
    t.id = d->id;
    t.hamming = d->hamming;
    t.decisionMargin = d->decision_margin;
    for (int c = 0; c < 4; ++c) t.corners[c] = {d->p[c][0], d->p[c][1]};
    t.centre = {d->c[0], d->c[1]};
    out.push_back(t);
  }
  apriltag_detections_destroy(found);
  std::sort(out.begin(), out.end(), [](const TagDetection& a, const TagDetection& b) { return a.id < b.id; });
  return out;
}

// -------------------------------------------------------------------------------------------------- pose

std::array<cv::Point3d, 4> tagCornersInTagFrame(double s) {
  const double h = s / 2;
  return {cv::Point3d(-h, -h, 0), cv::Point3d(h, -h, 0), cv::Point3d(h, h, 0), cv::Point3d(-h, h, 0)};
}

namespace {

capture::Pose poseFrom(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  return capture::makePose(R, cv::Vec3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
}

double rmsOf(const std::vector<cv::Point3d>& obj, const std::vector<cv::Point2d>& img, const cv::Mat& K,
             const cv::Mat& rvec, const cv::Mat& tvec) {
  std::vector<cv::Point2d> proj;
  cv::projectPoints(obj, rvec, tvec, K, cv::noArray(), proj);
  double s = 0;
  for (size_t i = 0; i < img.size(); ++i) s += std::pow(cv::norm(proj[i] - img[i]), 2);
  return std::sqrt(s / img.size());
}

cv::Vec3d zAxis(const capture::Pose& T) { return {T(0, 2), T(1, 2), T(2, 2)}; }

}  // namespace

std::optional<TagPose> estimateTagPose(const TagDetection& det, double size, const capture::Intrinsics& k,
                                       const PoseOptions& options, const capture::Pose* previous,
                                       const cv::Vec3d* planeNormal) {
  if (!(size > 0) || !k.valid()) return std::nullopt;
  const auto c = tagCornersInTagFrame(size);
  // IPPE square wants (-h, h), (h, h), (h, -h), (-h, -h): corners 3, 2, 1, 0.
  const std::vector<cv::Point3d> obj{c[3], c[2], c[1], c[0]};
  const std::vector<cv::Point2d> img{det.corners[3], det.corners[2], det.corners[1], det.corners[0]};
  for (const auto& p : img)
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) return std::nullopt;
  double area2 = 0;  // shoelace: twice the signed quad area
  for (int i = 0; i < 4; ++i) area2 += img[i].x * img[(i + 1) % 4].y - img[(i + 1) % 4].x * img[i].y;
  if (std::abs(area2) < 8.0) return std::nullopt;  // collapsed quad (< 4 px^2)
  const cv::Mat K = (cv::Mat_<double>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  std::vector<cv::Mat> rvecs, tvecs;
  int n = 0;
  try {
    n = cv::solvePnPGeneric(obj, img, K, cv::noArray(), rvecs, tvecs, false, cv::SOLVEPNP_IPPE_SQUARE);
  } catch (const cv::Exception&) {
    return std::nullopt;
  }
  if (n <= 0) return std::nullopt;
  struct Candidate {
    cv::Mat r, t;
    double rms;
  };
  std::vector<Candidate> cand;
  for (int i = 0; i < n; ++i) {
    cv::Mat r = rvecs[i].clone(), t = tvecs[i].clone();
    r.convertTo(r, CV_64F), t.convertTo(t, CV_64F);
    if (t.at<double>(2) <= 0) continue;  // behind the camera
    cv::solvePnPRefineLM(obj, img, K, cv::noArray(), r, t);
    cand.push_back({r, t, rmsOf(obj, img, K, r, t)});
  }
  if (cand.empty()) return std::nullopt;
  std::sort(cand.begin(), cand.end(), [](const Candidate& a, const Candidate& b) { return a.rms < b.rms; });
  TagPose out;
  size_t pick = 0;
  out.alternativeRms = cand.size() > 1 ? cand[1].rms : std::numeric_limits<double>::infinity();
  out.ambiguous = cand.size() > 1 && cand[0].rms >= options.ambiguityRatio * cand[1].rms;
  if (out.ambiguous) {
    const capture::Pose T0 = poseFrom(cand[0].r, cand[0].t), T1 = poseFrom(cand[1].r, cand[1].t);
    if (planeNormal) {
      pick = zAxis(T1).dot(*planeNormal) > zAxis(T0).dot(*planeNormal) ? 1 : 0;
    } else if (previous) {
      pick = rotationErrorDeg(T1, *previous) < rotationErrorDeg(T0, *previous) ? 1 : 0;
    }
  }
  out.T_camera_tag = poseFrom(cand[pick].r, cand[pick].t);
  out.reprojectionRms = cand[pick].rms;
  if (pick == 1) out.alternativeRms = cand[0].rms;
  return out;
}

std::optional<std::pair<cv::Vec3d, cv::Vec3d>> fitTagPlane(const TagDetection& det, const cv::Mat& depth,
                                                           const capture::Intrinsics& k, int minSamples) {
  if (depth.empty() || depth.type() != CV_32FC1 || !k.valid()) return std::nullopt;
  cv::Mat mask(depth.size(), CV_8UC1, cv::Scalar(0));
  std::vector<cv::Point> quad;
  for (const auto& p : det.corners) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) return std::nullopt;
    quad.emplace_back(cvRound(p.x), cvRound(p.y));
  }
  cv::fillConvexPoly(mask, quad, cv::Scalar(255));
  // Only the quad's bounding box can hold samples.
  const cv::Rect box = cv::boundingRect(quad) & cv::Rect(0, 0, depth.cols, depth.rows);
  std::vector<cv::Vec3d> pts;
  for (int y = box.y; y < box.y + box.height; ++y)
    for (int x = box.x; x < box.x + box.width; ++x) {
      const float z = depth.at<float>(y, x);
      if (mask.at<uchar>(y, x) && validDepth(z) && std::isfinite(z))
        pts.emplace_back((x - k.cx) * z / k.fx, (y - k.cy) * z / k.fy, z);
    }
  std::pair<cv::Vec3d, cv::Vec3d> plane;
  for (int round = 0; round < 2; ++round) {
    if (static_cast<int>(pts.size()) < minSamples) return std::nullopt;
    cv::Vec3d mean(0, 0, 0);
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    cv::Matx33d C = cv::Matx33d::zeros();
    for (const auto& p : pts) {
      const cv::Vec3d d = p - mean;
      C += d * d.t();
    }
    cv::Mat values, vectors;
    cv::eigen(cv::Mat(C), values, vectors);  // descending eigenvalues: the last vector is the normal
    cv::Vec3d n(vectors.at<double>(2, 0), vectors.at<double>(2, 1), vectors.at<double>(2, 2));
    if (n.dot(mean) > 0) n = -n;
    plane = {n, mean};
    const double rms = std::sqrt(std::max(0.0, values.at<double>(2)) / pts.size());
    const double cut = std::max(3.0 * rms, 0.002);
    std::vector<cv::Vec3d> kept;
    for (const auto& p : pts)
      if (std::abs((p - mean).dot(n)) <= cut) kept.push_back(p);
    if (kept.size() == pts.size()) break;
    pts.swap(kept);
  }
  return plane;
}

std::pair<double, double> depthGateLimits(const DepthGate& gate, const TagDetection& detection, double z) {
  double side = 0;
  for (int i = 0; i < 4; ++i)
    side += cv::norm(detection.corners[static_cast<size_t>(i)] - detection.corners[static_cast<size_t>((i + 1) % 4)]);
  side /= 4;
  const double dz = side > 0 && std::isfinite(z) ? z * std::sqrt(2.0) * gate.cornerNoisePx / side : 0.0;
  const double scale = std::max(1.0, 3.0 * dz / gate.maxShiftMetres);
  return {gate.maxAngleDeg * scale, gate.maxShiftMetres * scale};
}

std::optional<TagPose> measureTagPose(const TagDetection& detection, double tagSize, const capture::Intrinsics& k,
                                      const cv::Mat& depth, const capture::Pose* previous, const DepthGate& gate) {
  std::optional<std::pair<cv::Vec3d, cv::Vec3d>> plane;
  if (!depth.empty()) plane = fitTagPlane(detection, depth, k);
  auto pose = estimateTagPose(detection, tagSize, k, {}, previous, plane ? &plane->first : nullptr);
  if (pose && plane) {
    const auto [angle, shift] = depthGateLimits(gate, detection, pose->T_camera_tag(2, 3));
    *pose = refinePoseWithDepth(*pose, *plane, angle, shift);
  }
  return pose;
}

TagPose refinePoseWithDepth(const TagPose& pose, const std::pair<cv::Vec3d, cv::Vec3d>& plane, double maxAngleDeg,
                            double maxShiftMetres) {
  const auto& [n, p0] = plane;
  const cv::Vec3d z = zAxis(pose.T_camera_tag);
  const double cosA = std::clamp(z.dot(n), -1.0, 1.0);
  if (std::acos(cosA) * 180.0 / CV_PI > maxAngleDeg) return pose;
  const cv::Vec3d t = capture::translationOf(pose.T_camera_tag);
  const double tn = cv::norm(t);
  if (!(tn > 0)) return pose;
  const cv::Vec3d ray = t / tn;
  const double denom = n.dot(ray);
  if (std::abs(denom) < 1e-3) return pose;  // grazing: the intersection is ill-conditioned
  const double s = n.dot(p0) / denom;
  if (!(s > 0) || !std::isfinite(s)) return pose;
  if (std::abs(s - tn) > maxShiftMetres) return pose;  // the plane disagrees with the image on the distance
  // Smallest rotation taking z onto n, applied on the camera side.
  cv::Vec3d axis = z.cross(n);
  const double sinA = cv::norm(axis);
  cv::Matx33d Rmin = cv::Matx33d::eye();
  if (sinA > 1e-12) {
    axis *= std::atan2(sinA, cosA) / sinA;
    cv::Rodrigues(axis, Rmin);
  }
  TagPose out = pose;
  out.T_camera_tag = capture::makePose(Rmin * capture::rotationOf(pose.T_camera_tag), ray * s);
  out.depthRefined = true;
  return out;
}

// ------------------------------------------------------------------------------------------- smoothing

std::vector<double> OneEuroFilter::filter(double t, const std::vector<double>& x) {
  if (!initialised_ || x.size() != xPrev_.size()) {
    initialised_ = true;
    tPrev_ = t;
    xPrev_ = x;
    dxPrev_.assign(x.size(), 0.0);
    return x;
  }
  double dt = t - tPrev_;
  if (!(dt > 1e-6)) dt = 1.0 / 30.0;  // repeated or reordered timestamps: assume one camera frame
  auto alpha = [dt](double cutoff) {
    const double tau = 1.0 / (2.0 * CV_PI * cutoff);
    return 1.0 / (1.0 + tau / dt);
  };
  const double aD = alpha(dCutoff_);
  double speed2 = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    dxPrev_[i] = aD * (x[i] - xPrev_[i]) / dt + (1 - aD) * dxPrev_[i];
    speed2 += dxPrev_[i] * dxPrev_[i];
  }
  const double a = alpha(minCutoff_ + beta_ * std::sqrt(speed2));
  for (size_t i = 0; i < x.size(); ++i) xPrev_[i] = a * x[i] + (1 - a) * xPrev_[i];
  tPrev_ = t;
  return xPrev_;
}

capture::Pose PoseSmoother::filter(double t, const capture::Pose& T) {
  cv::Quatd q = cv::Quatd::createFromRotMat(capture::rotationOf(T));
  if (havePrev_ && q.dot(qPrev_) < 0) q = -q;  // same hemisphere as the last output
  const auto tr = translation_.filter(t, {T(0, 3), T(1, 3), T(2, 3)});
  const auto qs = rotation_.filter(t, {q.w, q.x, q.y, q.z});
  qPrev_ = cv::Quatd(qs[0], qs[1], qs[2], qs[3]).normalize();
  havePrev_ = true;
  return capture::makePose(qPrev_.toRotMat3x3(), cv::Vec3d(tr[0], tr[1], tr[2]));
}

const char* toString(TrackStatus s) {
  switch (s) {
    case TrackStatus::Tracked:
      return "tracked";
    case TrackStatus::Held:
      return "held";
    case TrackStatus::Lost:
      return "lost";
  }
  return "lost";
}

TrackStatus MarkerTrack::update(double t, const std::optional<capture::Pose>& measured) {
  if (measured) {
    if (status_ == TrackStatus::Lost) smoother_.reset();
    pose_ = options_.smooth ? smoother_.filter(t, *measured) : *measured;
    lastMeasured_ = measured;
    lastSeen_ = t;
    status_ = TrackStatus::Tracked;
  } else if (pose_ && t - lastSeen_ <= options_.holdSeconds) {
    status_ = TrackStatus::Held;
  } else {
    status_ = TrackStatus::Lost;
  }
  return status_;
}

cv::Vec3d taggedLightPosition(const TaggedPointLight& light, const capture::Pose& T_camera_tag) {
  return capture::transformPoint(T_camera_tag, light.offset);
}

double rotationErrorDeg(const capture::Pose& a, const capture::Pose& b) {
  const cv::Matx33d d = capture::rotationOf(a).t() * capture::rotationOf(b);
  const double c = std::clamp((d(0, 0) + d(1, 1) + d(2, 2) - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / CV_PI;
}

double translationError(const capture::Pose& a, const capture::Pose& b) {
  return cv::norm(capture::translationOf(a) - capture::translationOf(b));
}

}  // namespace mrgi::reconstruction
