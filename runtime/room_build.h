#pragma once
// `mrgi room` and `mrgi room-lights`: the persistent model of the real room built from a recording (every
// trusted frame's filtered depth fused at its camera pose, runtime/room_fusion.h) and saved; and the lights a
// saved room gives a point (reconstruction/room_lights.h), printed and drawn.
#include <opencv2/core.hpp>
#include <string>

#include "reconstruction/room_model.h"
#include "runtime/pose_source.h"

namespace mrgi::runtime {

struct BuildRoomOptions {
  std::string source, out;    ///< the recording; the room folder written (room.ply, room_appearance.npy, room.json)
  capture::OpenOptions open;  ///< a folder's calibration and depth scale
  PoseMode pose = PoseMode::Tracked;
  int frames = 0;      ///< at most this many frames read (0 = all)
  int every = 1;       ///< every Nth frame integrated
  int trackEvery = 0;  ///< odometry against the room fused so far, its surface anew every N fused frames
  bool noOptimise = false;
  reconstruction::RoomOptions room;
  bool json = false;  ///< one JSON object on stdout instead of lines
};
/// Builds and saves the room; returns 0. Throws when no frame could be fused (naming the source).
int buildRoom(const BuildRoomOptions& o);

struct RoomLightsOptions {
  std::string room;          ///< room folder
  cv::Vec3d at{0, 0, 0.06};  ///< where the virtual object will be, marker frame (metres)
  int count = 4;
  double gain = 0, whiteAlbedo = 0.8;
  std::string map;  ///< PNG of the room's environment at `at`, lights circled
  bool json = false;
};
/// Prints the lights (and writes the map); returns 0.
int roomLights(const RoomLightsOptions& o);

}  // namespace mrgi::runtime
