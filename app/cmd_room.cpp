// mrgi room and mrgi room-lights: the flags of building a room from a recording and of the lights it gives a
// point (runtime/room_build.h).
#include <memory>
#include <vector>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "runtime/room_build.h"

namespace mrgi::app {

Action addRoomLights(CLI::App& app) {
  auto o = std::make_shared<RoomLightsOptions>();
  auto at = std::make_shared<std::vector<double>>(std::vector<double>{0, 0, 0.06});
  app.add_option("room", o->room, "room folder (mrgi room)")->required();
  app.add_option("--at", *at, "where the virtual object will be, marker frame (metres: x,y,z or x y z)")
      ->delimiter(',')
      ->expected(3)
      ->check(numberIn(-1e4, 1e4))
      ->capture_default_str();
  app.add_option("--count", o->count, "lights from the split")->check(numberIn(1, 16))->capture_default_str();
  app.add_option("--gain", o->gain, "gain on saturated radiance (0 = estimate from the white-patch assumption)")
      ->check(numberIn(0.0, 1e4))
      ->capture_default_str();
  app.add_option("--white-albedo", o->whiteAlbedo, "the white patch's albedo for the estimate")
      ->check(numberIn(0.05, 1.0))
      ->capture_default_str();
  app.add_option("--map", o->map, "write the room's environment at that point (lat-long PNG, lights circled)");
  app.add_flag("--json", o->json, "print one JSON object");
  return [o, at] {
    o->at = {(*at)[0], (*at)[1], (*at)[2]};
    return roomLights(*o);
  };
}

Action addRoom(CLI::App& app) {
  auto o = std::make_shared<BuildRoomOptions>();
  app.add_option("source", o->source,
                 "recording to build the room from (session, TUM sequence, Open3D RGB-D folder, .oni file)")
      ->required();
  app.add_option("--out", o->out, "room folder to write (room.ply, room_appearance.npy, room.json)")->required();
  addPoseOption(app, o->pose);
  addFolderCalibration(app, o->open);
  app.add_option("--frames", o->frames, "read at most N frames (0 = all)")->check(numberIn(0, 1e9));
  app.add_option("--every", o->every, "integrate every Nth frame")->check(numberIn(1, 1e6));
  app.add_option(
         "--track-every", o->trackEvery,
         "with odometry or tracked poses, align the next frames with the room fused so far, its surface taken anew "
         "every N fused frames (0 = keyframes only: on the bundled sessions, whose marker is in view, every 2 or 5 "
         "frames moved the room 2.0 -> 2.4-2.8 mm (synth), 7.0 -> 6.6 (pt), 4.2 -> 5.9-7.8 (hdr) from the true one)")
      ->check(numberIn(0, 1e6))
      ->capture_default_str();
  app.add_flag("--no-optimise", o->noOptimise,
               "with odometry or tracked poses, fuse each frame at the tracker's pose instead of optimising the whole "
               "trajectory first (a pose graph of odometry, loop-closure and marker edges; off with --track-every)");
  app.add_option("--voxel", o->room.voxelM, "voxel edge in metres")->check(numberIn(0.002, 0.2))->capture_default_str();
  app.add_option("--trunc", o->room.truncM, "truncation distance of the signed distance, metres (at least 2 voxels)")
      ->check(numberIn(0.004, 1.0))
      ->capture_default_str();
  app.add_option("--max-blocks", o->room.maxBlocks, "memory budget in voxel blocks of 16^3 voxels")
      ->check(numberIn(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--max-depth", o->room.maxDepthM, "depth beyond this (metres) is not integrated")
      ->check(numberAbove(0.1, 20))
      ->capture_default_str();
  app.add_option("--outlier", o->room.outlierM,
                 "a frame is not integrated when more than 30 % of its points in observed space lie farther than this "
                 "(metres) from the model (its pose disagrees)")
      ->check(numberAbove(0, 1))
      ->capture_default_str();
  app.add_flag("--json", o->json, "print one JSON object (per-frame integration, blocks, timing) instead of lines");
  return [o] { return buildRoom(*o); };
}

}  // namespace mrgi::app
