#include "runtime/track.h"

#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>

#include "capture/checks.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/registration.h"
#include "capture/session.h"
#include "reconstruction/depth_filter.h"
#include "reconstruction/marker.h"
#include "runtime/output.h"
#include "runtime/pose_source.h"
#include "runtime/source.h"

using nlohmann::json;

namespace mrgi::runtime {
namespace {

/// Throws FlagError("--id") when id is not one of family's.
void checkTagId(const std::string& family, int id) {
  if (const std::string problem = capture::tagProblem(family, id); !problem.empty())
    throw capture::FlagError("--id", problem);
}

json poseJson(const capture::Pose& T) {
  json rows = json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  return rows;
}

/// A folder's calibration and depth scale from the flags (--intrinsics also serves a single image).
capture::OpenOptions folderOptions(const TrackOptions& o) {
  capture::OpenOptions open;
  if (o.intrinsics)
    open.intrinsics =
        std::array<double, 4>{(*o.intrinsics)[0], (*o.intrinsics)[1], (*o.intrinsics)[2], (*o.intrinsics)[3]};
  open.depthUnitsPerMetre = o.depthUnitsPerMetre;
  return open;
}

/// --pose: the camera's pose per frame from a pose source, one line each, then a summary on stderr.
int runCameraTrack(const TrackOptions& o) {
  auto source = openSource(o.input, folderOptions(o));
  if (!source->info().hasRgbd) throw capture::CaptureError(o.input, "has no RGB-D frames to track");
  MarkerSpec marker;
  std::optional<capture::Pose> T_world_marker = groundTruthT_world_marker(*source);
  TrackingOptions tracking;
  tracking.worldFromFirstFrame = true;  // no marker named: a first frame without a tag founds the world
  if (const capture::SessionManifest* manifest = source->sessionManifest()) {
    if (const auto& m = manifest->marker)
      marker = {m->family, m->sizeMetres, m->id}, tracking.worldFromFirstFrame = false;
  }
  if (!o.family.empty()) marker.family = o.family;
  if (o.size > 0) marker.size = o.size;
  if (o.id >= 0) marker.id = o.id;
  if (o.id >= 0) checkTagId(marker.family, o.id);
  auto poses = makePoseSource(*o.pose, marker, T_world_marker, tracking);
  gl::Profiler profiler;
  std::map<std::string, int> counts;
  int64_t frames = 0;
  while (auto frame = source->next()) {
    if (!frame->rgbd) continue;
    capture::ensureRegistered(*frame->rgbd);
    const CameraPose p = poses->locate(*frame, profiler);
    ++frames;
    ++counts[p.tracked() ? toString(p.by) : "lost"];
    // How the frame was posed (CameraPose::facts: status, by, the marker's state, odometry's quality, the
    // marker's correction), its number and pose.
    json line = p.facts();
    line["frame"] = frame->index;
    line["T_camera_world"] = p.tracked() ? poseJson(capture::inversePose(*p.T_world_camera)) : json();
    if (o.json) {
      std::printf("%s\n", jsonText(line, o.input).c_str());
    } else if (p.tracked()) {
      const cv::Vec3d c = capture::translationOf(*p.T_world_camera);
      std::printf("frame %lld: tracked by %s, camera at (%.4f, %.4f, %.4f) m\n", static_cast<long long>(frame->index),
                  toString(p.by), c[0], c[1], c[2]);
    } else {
      std::printf("frame %lld: lost\n", static_cast<long long>(frame->index));
    }
    std::fflush(stdout);
  }
  std::string summary;
  for (const auto& [by, n] : counts) summary += (summary.empty() ? "" : ", ") + std::to_string(n) + " " + by;
  std::fprintf(stderr, "%lld frames (--pose %s): %s\n", static_cast<long long>(frames), toString(*o.pose),
               summary.c_str());
  if (counts["lost"] == frames)
    throw capture::CaptureError(o.input, std::string("no frame could be placed (--pose ") + toString(*o.pose) + ")");
  return 0;
}

}  // namespace

int track(const TrackOptions& o) {
  if (o.pose) return runCameraTrack(o);
  // Inputs: one image (with --intrinsics) or any frame source.
  std::unique_ptr<capture::FrameSource> source;
  std::optional<capture::Frame> single;
  std::string family = o.family.empty() ? "tag36h11" : o.family;
  double size = o.size;
  int wantedId = o.id;
  if (capture::isImageFile(o.input)) {
    if (!o.intrinsics) throw capture::CaptureError(o.input, "a single image needs --intrinsics fx,fy,cx,cy");
    const cv::Mat img = capture::readColour(o.input);
    capture::RgbdFrame rgbd;
    rgbd.colour = img;
    const cv::Vec4d& k = *o.intrinsics;
    rgbd.colourIntrinsics = {img.cols, img.rows, k[0], k[1], k[2], k[3]};
    single = capture::Frame{};
    single->rgbd = rgbd;
  } else {
    source = openSource(o.input, folderOptions(o));
    if (!source->info().hasRgbd) throw capture::CaptureError(o.input, "has no colour frames to track a marker in");
    if (const capture::SessionManifest* manifest = source->sessionManifest())
      if (const auto& m = manifest->marker) {
        if (o.family.empty()) family = m->family;
        if (!(size > 0)) size = m->sizeMetres;
        if (wantedId < 0 && m->id >= 0) wantedId = m->id;
      }
  }
  if (!(size > 0)) size = 0.1;
  if (o.id >= 0) checkTagId(family, o.id);
  reconstruction::DetectorOptions dopt;
  dopt.family = family;
  dopt.decimate = o.decimate;
  const reconstruction::TagDetector detector(dopt);
  reconstruction::TrackerOptions topt;
  topt.holdSeconds = o.hold;
  topt.smooth = !o.noSmooth;
  if (o.smoothCutoff >= 0) topt.minCutoff = o.smoothCutoff;
  if (o.smoothBeta >= 0) topt.beta = o.smoothBeta;
  if (o.smoothDerivative >= 0) topt.derivativeCutoff = o.smoothDerivative;
  std::map<int, reconstruction::MarkerTrack> tracks;
  if (wantedId >= 0) tracks.emplace(wantedId, reconstruction::MarkerTrack(topt));
  bool everSeen = false;

  auto process = [&](const capture::Frame& frame) {
    const capture::RgbdFrame& f = *frame.rgbd;
    const auto detections = detector.detect(f.colour);
    std::map<int, std::pair<reconstruction::TagDetection, reconstruction::TagPose>> measured;
    cv::Mat depth;
    if (o.refineDepth && !f.depth.empty() && f.depthRegistered) depth = f.depth;
    for (const auto& d : detections) {
      if (wantedId >= 0 && d.id != wantedId) continue;
      auto it = tracks.find(d.id);
      const capture::Pose* previous = it != tracks.end() ? it->second.lastMeasured() : nullptr;
      const auto pose = reconstruction::measureTagPose(d, size, f.colourIntrinsics, depth, previous);
      if (!pose) continue;
      measured.emplace(d.id, std::make_pair(d, *pose));
      tracks.try_emplace(d.id, reconstruction::MarkerTrack(topt));
    }
    everSeen |= !measured.empty();
    if (tracks.empty()) {  // nothing seen yet and no id asked for
      const json line = {{"frame", frame.index}, {"status", "lost"}, {"id", nullptr}, {"T_camera_tag", nullptr}};
      std::printf("%s\n", o.json ? jsonText(line, o.input).c_str()
                                 : ("frame " + std::to_string(frame.index) + ": no tag").c_str());
      return;
    }
    for (auto& [id, track] : tracks) {
      const auto m = measured.find(id);
      const auto status = track.update(
          frame.timestamp, m != measured.end() ? std::optional(m->second.second.T_camera_tag) : std::nullopt);
      json line = {{"frame", frame.index}, {"status", reconstruction::toString(status)}, {"id", id}};
      line["T_camera_tag"] =
          (status != reconstruction::TrackStatus::Lost && track.pose()) ? poseJson(*track.pose()) : json();
      if (m != measured.end()) {
        line["reprojection_rms_px"] = m->second.second.reprojectionRms;
        line["ambiguous"] = m->second.second.ambiguous;
        line["depth_refined"] = m->second.second.depthRefined;
        line["decision_margin"] = m->second.first.decisionMargin;
      }
      if (o.json) {
        std::printf("%s\n", jsonText(line, o.input).c_str());
      } else if (track.pose() && status != reconstruction::TrackStatus::Lost) {
        const auto& T = *track.pose();
        std::printf("frame %lld: tag %d %s, t = (%.4f, %.4f, %.4f) m\n", static_cast<long long>(frame.index), id,
                    reconstruction::toString(status), T(0, 3), T(1, 3), T(2, 3));
      } else {
        std::printf("frame %lld: tag %d lost\n", static_cast<long long>(frame.index), id);
      }
    }
    std::fflush(stdout);
  };

  if (single) {
    process(*single);
  } else {
    while (auto frame = source->next())
      if (frame->rgbd) process(*frame);
  }
  if (!everSeen) {
    const std::string what = family + (wantedId >= 0 ? " id " + std::to_string(wantedId) : std::string(" tag"));
    throw capture::CaptureError(o.input, "marker never seen (" + what + " not detected in any frame)");
  }
  return 0;
}

}  // namespace mrgi::runtime
