#include "evaluation/tag_pixels.h"

#include <open3d/camera/PinholeCameraIntrinsic.h>
#include <open3d/geometry/Image.h>
#include <open3d/geometry/RGBDImage.h>
#include <open3d/pipelines/odometry/Odometry.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/json_io.h"
#include "capture/visp_folder.h"
#include "reconstruction/room_model.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::evaluation {
namespace {

capture::Pose poseFromJson(const json& m, const std::string& file, const std::string& what) {
  if (!m.is_array() || m.size() != 4) throw capture::CaptureError(file, what + " is not a 4x4 matrix");
  capture::Pose T;
  for (int r = 0; r < 4; ++r) {
    if (!m[r].is_array() || m[r].size() != 4) throw capture::CaptureError(file, what + " is not a 4x4 matrix");
    for (int c = 0; c < 4; ++c) {
      if (!m[r][c].is_number()) throw capture::CaptureError(file, what + " holds a value that is not a number");
      T(r, c) = m[r][c].get<double>();
      if (!std::isfinite(T(r, c))) throw capture::CaptureError(file, what + " holds a value that is not finite");
    }
  }
  return T;
}

/// Where the camera ray through pixel p meets the plane z = 0 of the board (camera frame), or nullopt when it
/// runs along the plane or meets it behind the camera.
std::optional<cv::Vec3d> onBoard(const cv::Point2d& p, const capture::Intrinsics& k,
                                 const capture::Pose& T_camera_board) {
  const cv::Vec3d d((p.x - k.cx) / k.fx, (p.y - k.cy) / k.fy, 1.0);
  const cv::Vec3d n(T_camera_board(0, 2), T_camera_board(1, 2), T_camera_board(2, 2));
  const cv::Vec3d t = capture::translationOf(T_camera_board);
  const double nd = n.dot(d);
  if (std::abs(nd) < 1e-9) return std::nullopt;
  const double s = n.dot(t) / nd;
  if (!(s > 0)) return std::nullopt;
  return s * d;
}

std::optional<cv::Point2d> project(const cv::Vec3d& x, const capture::Intrinsics& k) {
  if (!(x[2] > 1e-6)) return std::nullopt;
  return cv::Point2d(k.fx * x[0] / x[2] + k.cx, k.fy * x[1] / x[2] + k.cy);
}

std::shared_ptr<open3d::geometry::RGBDImage> toOpen3d(const capture::RgbdFrame& f) {
  open3d::geometry::Image colour, depth;
  colour.Prepare(f.colour.cols, f.colour.rows, 3, 1);
  const cv::Mat c = f.colour.isContinuous() ? f.colour : f.colour.clone();
  std::memcpy(colour.data_.data(), c.data, colour.data_.size());
  depth.Prepare(f.depth.cols, f.depth.rows, 1, 4);
  const cv::Mat d = f.depth.isContinuous() ? f.depth : f.depth.clone();
  std::memcpy(depth.data_.data(), d.data, depth.data_.size());
  // Metres already (scale 1), truncated at Open3D's default 3 m as its odometry's own option is.
  return open3d::geometry::RGBDImage::CreateFromColorAndDepth(colour, depth, 1.0, 3.0, true);
}

}  // namespace

TagSequence loadTagSequence(const std::string& dirName, int maxFrames) {
  const fs::path dir(dirName);
  TagSequence seq;
  seq.path = dirName;
  const std::string tagFile = (dir / "apriltag_data.json").string();
  const capture::VispFolder folder(dirName);
  seq.intrinsics = folder.intrinsics();
  const json tags = capture::readJsonFile(tagFile);
  if (!tags.is_object() || !tags.contains("tag_size") || !tags["tag_size"].is_number() || !tags.contains("grid") ||
      !tags["grid"].is_array() || !tags.contains("detections") || !tags["detections"].is_array())
    throw capture::CaptureError(tagFile, "expected tag_size, grid and detections");
  seq.tagSize = tags["tag_size"].get<double>();
  capture::checkNumber(seq.tagSize, capture::kMinTagSizeM, capture::kMaxTagSizeM, tagFile, "tag_size");
  for (int i = 0; maxFrames <= 0 || i < maxFrames; ++i) {
    std::optional<capture::Frame> f = folder.frame(i);
    if (!f) break;
    if (static_cast<size_t>(i) >= tags["grid"].size() || static_cast<size_t>(i) >= tags["detections"].size())
      throw capture::CaptureError(tagFile, "no board pose or detections for frame " + std::to_string(i));
    seq.frames.push_back(std::move(*f));
    seq.T_camera_board.push_back(poseFromJson(tags["grid"][i], tagFile, "grid[" + std::to_string(i) + "]"));
    std::map<int, std::array<cv::Point2d, 4>> frameCorners;
    const json& det = tags["detections"][i];
    if (!det.is_object())
      throw capture::CaptureError(tagFile, "detections[" + std::to_string(i) + "] is not an object");
    for (const auto& [id, d] : det.items()) {
      const json& c = d.contains("tag_corners") ? d["tag_corners"] : json();
      if (!c.is_array() || c.size() != 4) throw capture::CaptureError(tagFile, "a tag without four corners");
      std::array<cv::Point2d, 4> q;
      for (int k = 0; k < 4; ++k) {
        if (!c[k].is_array() || c[k].size() != 2 || !c[k][0].is_number() || !c[k][1].is_number())
          throw capture::CaptureError(tagFile, "a tag corner that is not two numbers");
        q[k] = {c[k][1].get<double>(), c[k][0].get<double>()};  // stored as (row, column)
      }
      int tagId = -1;
      try {
        size_t used = 0;
        tagId = std::stoi(id, &used);
        if (used != id.size()) tagId = -1;
      } catch (const std::exception&) {
      }
      if (tagId < 0) throw capture::CaptureError(tagFile, "a tag id that is not a number: '" + id + "'");
      frameCorners[tagId] = q;
    }
    seq.corners.push_back(std::move(frameCorners));
  }
  if (seq.frames.empty()) throw capture::CaptureError(dirName, "no color_image_0000.png: not a ViSP RGB-D sequence");
  return seq;
}

cv::Point2d tagCentre(const std::array<cv::Point2d, 4>& c) {
  // c0 + s (c2 - c0) = c1 + t (c3 - c1)
  const cv::Point2d a = c[2] - c[0], b = c[3] - c[1], r = c[1] - c[0];
  const double det = a.x * -b.y - a.y * -b.x;
  if (std::abs(det) < 1e-12) return 0.25 * (c[0] + c[1] + c[2] + c[3]);
  const double s = (r.x * -b.y - r.y * -b.x) / det;
  return c[0] + s * a;
}

std::vector<std::array<cv::Vec3d, 4>> boardTagQuads(const TagSequence& seq) {
  const capture::Intrinsics& k = seq.intrinsics;
  // Each tag's corners on the board (board frame), from every frame that detected it, averaged.
  std::map<int, std::array<cv::Vec3d, 4>> board;
  std::map<int, int> seen;
  for (size_t f = 0; f < seq.frames.size(); ++f) {
    const capture::Pose T_board_camera = capture::inversePose(seq.T_camera_board[f]);
    for (const auto& [id, q] : seq.corners[f]) {
      std::array<cv::Vec3d, 4> x;
      bool ok = true;
      for (int c = 0; c < 4 && ok; ++c) {
        const auto p = onBoard(q[c], k, seq.T_camera_board[f]);
        ok = p.has_value();
        if (ok) x[c] = capture::transformPoint(T_board_camera, *p);
      }
      if (!ok) continue;
      auto& sum = board[id];  // zero when new
      ++seen[id];
      for (int c = 0; c < 4; ++c) sum[c] += x[c];
    }
  }
  // The board's tags lie on a regular grid: the ones never detected (a tag partly hidden in every frame) sit on it
  // too, with the detected ones' mean shape.
  std::vector<std::array<cv::Vec3d, 4>> quads;
  for (const auto& [id, sum] : board) {
    std::array<cv::Vec3d, 4> x;
    for (int c = 0; c < 4; ++c) x[c] = sum[c] / seen[id];
    quads.push_back(x);
  }
  if (quads.size() >= 3) {
    std::vector<cv::Vec2d> centres;
    std::array<cv::Vec3d, 4> shape{};
    for (const auto& q : quads) {
      const cv::Vec3d c = 0.25 * (q[0] + q[1] + q[2] + q[3]);
      centres.emplace_back(c[0], c[1]);
      for (int k = 0; k < 4; ++k) shape[k] += (q[k] - c) / static_cast<double>(quads.size());
    }
    cv::Vec2d a(0, 0), b(0, 0);
    for (size_t u = 0; u < centres.size(); ++u)
      for (size_t v = 0; v < centres.size(); ++v) {
        const cv::Vec2d d = centres[v] - centres[u];
        if (u == v || cv::norm(d) < 1e-3) continue;
        if (cv::norm(a) == 0 || cv::norm(d) < cv::norm(a)) a = d;
      }
    for (size_t u = 0; u < centres.size(); ++u)
      for (size_t v = 0; v < centres.size(); ++v) {
        const cv::Vec2d d = centres[v] - centres[u];
        if (u == v || std::abs(a[0] * d[1] - a[1] * d[0]) < 0.5 * cv::norm(a) * cv::norm(d)) continue;
        if (cv::norm(b) == 0 || cv::norm(d) < cv::norm(b)) b = d;
      }
    const double det = a[0] * b[1] - a[1] * b[0];
    if (std::abs(det) > 1e-9) {
      int iLo = 1 << 20, iHi = -(1 << 20), jLo = 1 << 20, jHi = -(1 << 20);
      for (const cv::Vec2d& c : centres) {
        const cv::Vec2d r = c - centres[0];
        const int ii = static_cast<int>(std::lround((r[0] * b[1] - r[1] * b[0]) / det));
        const int jj = static_cast<int>(std::lround((a[0] * r[1] - a[1] * r[0]) / det));
        iLo = std::min(iLo, ii), iHi = std::max(iHi, ii), jLo = std::min(jLo, jj), jHi = std::max(jHi, jj);
      }
      for (int ii = iLo; ii <= iHi; ++ii)
        for (int jj = jLo; jj <= jHi; ++jj) {
          const cv::Vec2d c = centres[0] + ii * a + jj * b;
          bool taken = false;
          for (const cv::Vec2d& d : centres) taken = taken || cv::norm(d - c) < 0.3 * cv::norm(a);
          if (taken) continue;
          std::array<cv::Vec3d, 4> q;
          for (int k = 0; k < 4; ++k) q[k] = cv::Vec3d(c[0], c[1], 0) + shape[k];
          quads.push_back(q);
        }
    }
  }
  return quads;
}

int paintTagsOut(TagSequence& seq, size_t i) { return paintTagsOut(seq, i, boardTagQuads(seq)); }

int paintTagsOut(TagSequence& seq, size_t i, const std::vector<std::array<cv::Vec3d, 4>>& quads) {
  const capture::Intrinsics& k = seq.intrinsics;
  // In frame i: each tag's quad grown to hold its white border (a tag36h11's is one of its 8 cells a side).
  capture::RgbdFrame& rgbd = *seq.frames[i].rgbd;
  cv::Mat mask(rgbd.colour.size(), CV_8UC1, cv::Scalar(0)), around(rgbd.colour.size(), CV_8UC1, cv::Scalar(0));
  for (const auto& x : quads) {
    cv::Vec3d centre(0, 0, 0);
    for (int c = 0; c < 4; ++c) centre += 0.25 * x[c];
    const auto quad = [&](double grow) {
      std::vector<cv::Point> poly;
      for (int c = 0; c < 4; ++c) {
        const auto p = project(capture::transformPoint(seq.T_camera_board[i], centre + grow * (x[c] - centre)), k);
        if (!p) return std::vector<cv::Point>{};
        poly.emplace_back(static_cast<int>(std::lround(p->x)), static_cast<int>(std::lround(p->y)));
      }
      return poly;
    };
    const auto inner = quad(1.4), outer = quad(1.6);
    if (inner.empty() || outer.empty()) continue;
    cv::fillConvexPoly(around, outer, cv::Scalar(255));
    cv::fillConvexPoly(mask, inner, cv::Scalar(255));
  }
  // Only the board: the depth within 3 cm of its plane, or none. The sensor's depth and the plane the tags' poses
  // give differ by a few centimetres (the depth camera's own offset): the plane is moved by their median
  // difference over the quads first.
  const auto planeDepth = [&](int x, int y) {
    const auto p = onBoard({double(x), double(y)}, k, seq.T_camera_board[i]);
    return p ? (*p)[2] : -1.0;
  };
  std::vector<double> offsets;
  for (int y = 0; y < mask.rows; y += 2)
    for (int x = 0; x < mask.cols; x += 2)
      if (mask.at<uchar>(y, x) && rgbd.depth.at<float>(y, x) > 0 && planeDepth(x, y) > 0)
        offsets.push_back(rgbd.depth.at<float>(y, x) - planeDepth(x, y));
  if (offsets.empty()) return 0;
  std::nth_element(offsets.begin(), offsets.begin() + static_cast<long>(offsets.size() / 2), offsets.end());
  const double offset = offsets[offsets.size() / 2];
  const auto onPlane = [&](int x, int y) {
    const float z = rgbd.depth.at<float>(y, x);
    if (!(z > 0)) return true;
    const double zp = planeDepth(x, y);
    return zp > 0 && std::abs(zp + offset - z) < 0.03;
  };
  // The board's own colour: the median of its pixels around the tags and between them.
  std::vector<uchar> channel[3];
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x)
      if (around.at<uchar>(y, x) && !mask.at<uchar>(y, x) && rgbd.depth.at<float>(y, x) > 0 && onPlane(x, y))
        for (int c = 0; c < 3; ++c) channel[c].push_back(rgbd.colour.at<cv::Vec3b>(y, x)[c]);
  if (channel[0].empty()) return 0;
  cv::Vec3b paper;
  for (int c = 0; c < 3; ++c) {
    std::nth_element(channel[c].begin(), channel[c].begin() + channel[c].size() / 2, channel[c].end());
    paper[c] = channel[c][channel[c].size() / 2];
  }
  int painted = 0;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x)
      if (mask.at<uchar>(y, x) && onPlane(x, y)) rgbd.colour.at<cv::Vec3b>(y, x) = paper, ++painted;
  return painted;
}

TagPixelError tagPixelError(const TagSequence& seq, const std::vector<std::optional<capture::Pose>>& T_world_camera) {
  TagPixelError out;
  if (seq.frames.empty() || T_world_camera.size() != seq.frames.size() || !T_world_camera[0]) return out;
  // The tags' centres, once, on the board's plane in the first frame (camera 0).
  std::map<int, cv::Vec3d> centres;
  for (const auto& [id, q] : seq.corners[0])
    if (const auto p = onBoard(tagCentre(q), seq.intrinsics, seq.T_camera_board[0])) centres[id] = *p;
  std::vector<double> errors;
  for (size_t f = 1; f < seq.frames.size(); ++f) {
    double sum = 0;
    int n = 0;
    bool any = false;
    for (const auto& [id, q] : seq.corners[f]) any = any || centres.count(id);
    if (!any) {
      out.frameRmsPx.push_back(-1);
      continue;
    }
    ++out.frames;
    if (!T_world_camera[f]) {
      out.frameRmsPx.push_back(-1);
      continue;
    }
    ++out.tracked;
    const capture::Pose T_f_0 = capture::inversePose(*T_world_camera[f]) * *T_world_camera[0];
    for (const auto& [id, q] : seq.corners[f]) {
      const auto it = centres.find(id);
      if (it == centres.end()) continue;
      const auto p = project(capture::transformPoint(T_f_0, it->second), seq.intrinsics);
      const double e = p ? cv::norm(*p - tagCentre(q)) : 1e6;
      errors.push_back(e);
      sum += e * e, ++n;
    }
    out.frameRmsPx.push_back(n ? std::sqrt(sum / n) : -1);
  }
  out.samples = static_cast<int>(errors.size());
  if (errors.empty()) return out;
  double sq = 0;
  for (double e : errors) sq += e * e;
  out.rmsPx = std::sqrt(sq / static_cast<double>(errors.size()));
  std::sort(errors.begin(), errors.end());
  out.p95Px = errors[std::min(errors.size() - 1, static_cast<size_t>(std::ceil(0.95 * errors.size())) - 1)];
  out.maxPx = errors.back();
  return out;
}

std::vector<std::optional<capture::Pose>> open3dTrajectory(const TagSequence& seq, bool hybrid) {
  std::vector<std::optional<capture::Pose>> out;
  if (seq.frames.empty()) return out;
  const capture::Intrinsics& k = seq.intrinsics;
  const open3d::camera::PinholeCameraIntrinsic intrinsic(k.width, k.height, k.fx, k.fy, k.cx, k.cy);
  open3d::pipelines::odometry::OdometryOption option;  // its defaults
  capture::Pose T = capture::identityPose();
  out.push_back(T);
  auto previous = toOpen3d(*seq.frames[0].rgbd);
  for (size_t f = 1; f < seq.frames.size(); ++f) {
    auto current = toOpen3d(*seq.frames[f].rgbd);
    std::shared_ptr<open3d::pipelines::odometry::RGBDOdometryJacobian> jacobian;
    if (hybrid)
      jacobian = std::make_shared<open3d::pipelines::odometry::RGBDOdometryJacobianFromHybridTerm>();
    else
      jacobian = std::make_shared<open3d::pipelines::odometry::RGBDOdometryJacobianFromColorTerm>();
    // The motion carrying this frame (source) onto the previous one (target): previous from current.
    const auto [ok, step, info] = open3d::pipelines::odometry::ComputeRGBDOdometry(
        *current, *previous, intrinsic, Eigen::Matrix4d::Identity(), *jacobian, option);
    if (ok) {
      capture::Pose S;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) S(r, c) = step(r, c);
      T = T * S;
    }
    out.push_back(T);
    previous = current;
  }
  return out;
}

std::vector<std::optional<capture::Pose>> trackedTrajectory(const TagSequence& seq, runtime::PoseMode mode,
                                                            int markerId, const runtime::TrackingOptions& options,
                                                            int fuseRefresh) {
  runtime::MarkerSpec marker;
  marker.size = seq.tagSize;
  marker.id = markerId;
  auto source = runtime::makePoseSource(mode, marker, std::nullopt, options);
  gl::Profiler none;
  std::vector<std::optional<capture::Pose>> out;
  std::optional<reconstruction::RoomModel> room;
  if (fuseRefresh > 0) room.emplace();
  int sinceRefresh = 0;
  for (const capture::Frame& f : seq.frames) {
    out.push_back(source->locate(f, none).T_world_camera);
    if (!room || !out.back()) continue;
    // Fused at the pose just found, as replay --fuse-room does; its surface handed over every fuseRefresh frames.
    const capture::RgbdFrame& rgbd = *f.rgbd;
    if (!room->integrate(rgbd.depth, rgbd.colour, rgbd.colourIntrinsics, *out.back(), rgbd.exposure).integrated)
      continue;
    if (++sinceRefresh < fuseRefresh) continue;
    sinceRefresh = 0;
    auto mesh = std::make_shared<const reconstruction::RoomMesh>(room->mesh());
    if (!mesh->positions.empty()) source->useModel(std::move(mesh));
  }
  return out;
}

std::vector<std::optional<capture::Pose>> boardTrajectory(const TagSequence& seq) {
  std::vector<std::optional<capture::Pose>> out;
  for (const capture::Pose& T : seq.T_camera_board) out.push_back(capture::inversePose(T));
  return out;
}

TagPixelTable tagPixelTable(const std::string& dir, int frames, int markerId) {
  using Trajectory = std::vector<std::optional<capture::Pose>>;
  const TagSequence inView = loadTagSequence(dir, frames);
  TagSequence painted = inView;
  for (capture::Frame& f : painted.frames) f.rgbd->colour = f.rgbd->colour.clone();  // its own pixels to paint
  const auto quads = boardTagQuads(inView);
  for (size_t i = 1; i < painted.frames.size(); ++i) paintTagsOut(painted, i, quads);
  // Every frame painted, the first included: a recording without a marker (the world founded on its first frame).
  TagSequence bare = painted;
  bare.frames[0].rgbd->colour = bare.frames[0].rgbd->colour.clone();
  paintTagsOut(bare, 0, quads);
  runtime::TrackingOptions founded;
  founded.worldFromFirstFrame = true;
  runtime::TrackingOptions fine;
  fine.odometry.maxWidth = inView.intrinsics.width;
  struct Row {
    std::string name;
    const TagSequence* seq;
    std::function<Trajectory()> run;
  };
  const auto ours = [&](const TagSequence& s, runtime::PoseMode mode, const runtime::TrackingOptions& to) {
    return [&s, mode, to, markerId] { return trackedTrajectory(s, mode, markerId, to); };
  };
  const std::string full = "its finest level at " + std::to_string(inView.intrinsics.width) + " px";
  const std::vector<Row> rows = {
      {"the board's own poses (the harness's floor)", &inView, [&] { return boardTrajectory(inView); }},
      {"ours, --pose odometry, tags painted out", &painted, ours(painted, runtime::PoseMode::Odometry, {})},
      {"ours, --pose odometry, tags painted out, " + full, &painted, ours(painted, runtime::PoseMode::Odometry, fine)},
      {"ours, --pose tracked, tags painted out", &painted, ours(painted, runtime::PoseMode::Tracked, {})},
      {"ours, --pose odometry, tags painted out, against the room as it is fused (every 3 frames)", &painted,
       [&] { return trackedTrajectory(painted, runtime::PoseMode::Odometry, markerId, {}, 3); }},
      {"Open3D colour term, tags painted out", &painted, [&] { return open3dTrajectory(painted, false); }},
      {"Open3D hybrid term, tags painted out", &painted, [&] { return open3dTrajectory(painted, true); }},
      {"ours, --pose odometry, every frame painted (no marker)", &bare,
       ours(bare, runtime::PoseMode::Odometry, founded)},
      {"Open3D colour term, every frame painted", &bare, [&] { return open3dTrajectory(bare, false); }},
      {"Open3D hybrid term, every frame painted", &bare, [&] { return open3dTrajectory(bare, true); }},
      {"ours, --pose tracked, tags in view", &inView, ours(inView, runtime::PoseMode::Tracked, {})},
      {"Open3D hybrid term, tags in view", &inView, [&] { return open3dTrajectory(inView, true); }},
  };
  TagPixelTable out{dir, inView.frames.size(), {}};
  for (const Row& r : rows) {
    const auto start = std::chrono::steady_clock::now();
    const Trajectory poses = r.run();
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() /
                      static_cast<double>(r.seq->frames.size());
    out.rows.push_back({r.name, tagPixelError(*r.seq, poses), ms});
  }
  return out;
}

nlohmann::json tagPixelJson(const TagPixelTable& table) {
  nlohmann::json j = {{"sequence", table.sequence}, {"frames", table.frames}, {"rows", nlohmann::json::array()}};
  for (const TagPixelRow& r : table.rows)
    j["rows"].push_back({{"poses", r.poses},
                         {"rms_px", r.error.rmsPx},
                         {"p95_px", r.error.p95Px},
                         {"max_px", r.error.maxPx},
                         {"frames", r.error.frames},
                         {"tracked", r.error.tracked},
                         {"ms_per_frame", r.msPerFrame},
                         {"frame_rms_px", r.error.frameRmsPx}});
  return j;
}

}  // namespace mrgi::evaluation
