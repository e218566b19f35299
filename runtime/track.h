#pragma once
// `mrgi track`: the AprilTag marker's pose per frame of a source (or one image), per tag, or the camera's pose
// per frame from a pose source (runtime/pose_source.h); one line a frame on stdout (JSON lines with `json`).
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "runtime/pose_source.h"

namespace mrgi::runtime {

struct TrackOptions {
  std::string input;  ///< session directory, TUM sequence, .oni file, or one image (with intrinsics)
  bool json = false;
  std::string family;                   ///< empty: the session's, else tag36h11
  double size = 0;                      ///< tag edge, metres; 0: the session's, else 0.1
  int id = -1;                          ///< only this tag (-1: the session's marker, else every tag)
  std::optional<cv::Vec4d> intrinsics;  ///< fx, fy, cx, cy for a single image or a TUM or Open3D folder
  double depthUnitsPerMetre = 0;        ///< a folder's depth units per metre (0: the format's own)
  double hold = 0.5;                    ///< seconds the last pose is held after the tag disappears
  bool noSmooth = false;
  double smoothCutoff = -1, smoothBeta = -1, smoothDerivative = -1;  ///< < 0: the tracker's defaults
  bool refineDepth = false;
  float decimate = 1.0f;
  std::optional<PoseMode> pose;  ///< set: one camera pose per frame from that source instead of per tag
};

/// Tracks and prints; returns 0. Throws when the marker is never seen (per tag) or no frame could be placed.
int track(const TrackOptions& o);

}  // namespace mrgi::runtime
