#pragma once
// What a command that lights a source sets up before its first frame, the same for replay, live, insert and
// bench: the scene the user chose (a scene file, overridden by a measured preset and a technique) and the room
// that stands for the real scene (a saved one, or one fused as the frames come).
#include <memory>
#include <string>

#include "lighting/scene_file.h"
#include "reconstruction/room_model.h"

namespace mrgi::runtime {

/// The scene file and what overrides it (--scene, --preset, --presets, --technique).
struct SceneChoice {
  std::string scene;      ///< scene file (JSON); empty: nothing is lit
  std::string preset;     ///< fast | balanced | accurate from `presets`; empty: the scene file's knobs
  std::string presets;    ///< presets file written by mrgi bench --presets
  std::string technique;  ///< a technique's spelling ("dlpv", "REAL+VIRTUAL"); empty: the scene file's
};

/// The scene file with the preset's technique and knobs applied, then the technique (its knobs completed).
/// Throws for a bad file (naming it) or an unknown preset.
lighting::SceneDescription loadChosenScene(const SceneChoice& choice);

/// The room as the real scene of the lighting (--room, --fuse-room, --fuse-refresh, --track-room, --save-room).
struct RoomOptions {
  std::string room;           ///< a saved room (mrgi room --out)
  bool fuse = false;          ///< fuse a room from the frames as they come (replay's and live's default with a scene)
  bool fuseAsked = false;     ///< --fuse-room given: as the frames come even where a recording is fused first
  bool perFrameMesh = false;  ///< light each frame from its own depth mesh instead (no room)
  int fuseRefresh = 30;       ///< frames fused between refreshes of the fused room's surface
  int fuseEvery = 1;          ///< every N-th frame with a pose fused (1: every one)
  bool track = false;         ///< odometry aligns each frame with the room being fused
  std::string save;           ///< the fused room at the end, as mrgi room writes it
  bool any() const { return !room.empty() || fuse; }
};

}  // namespace mrgi::runtime
