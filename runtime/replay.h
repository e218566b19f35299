#pragma once
// `mrgi replay`'s loop: a recording through the frame pipeline, headless (or in a window), each composite
// written as frame_NNNN.png (and an MP4) on a writer thread while the next frame is worked on, optionally the
// real-pixel delta and debug views, and summary.json (per-frame stages, poses, timings, latency).
#include <memory>
#include <string>

#include "reconstruction/room_model.h"
#include "runtime/pose_source.h"
#include "runtime/session_setup.h"

namespace mrgi::runtime {

struct ReplayOptions {
  std::string source;         ///< session directory, TUM directory, Open3D folder or .oni file
  capture::OpenOptions open;  ///< a folder's calibration and depth scale
  std::string out;            ///< output folder (new, empty, or an earlier replay's)
  int frames = 0;             ///< at most this many frames (0 = all)
  std::string gl = "osmesa";
  SceneChoice scene;  ///< empty scene file: the camera images only
  bool dumpDelta = false;
  bool debug = false;
  PoseMode pose = PoseMode::Tracked;
  int meshStride = 2;
  bool recomputeAll = false;
  bool sequential = false;         ///< no frame prepared on the worker while GL works on the one before
  bool finishStages = false;       ///< GL finishes each stage before the next starts (exact per-stage GPU times)
  bool verbose = false;            ///< a line per frame on stdout with its stages' times, in pipeline order
  std::string mp4 = "replay.mp4";  ///< inside `out`; empty: none
  double fps = 0;                  ///< 0: from the source's timestamps
  RoomOptions rooms;               ///< a saved room or one fused as the frames come
  std::shared_ptr<const reconstruction::RoomMesh> room;  ///< rooms.room, loaded
};

/// Replays the source; returns 0, or 130 when interrupted (Ctrl-C: every frame before is written). Throws for
/// bad input (one message naming the file) and when no frame could be placed.
int replay(const ReplayOptions& o);

}  // namespace mrgi::runtime
