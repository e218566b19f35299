#pragma once
// Subcommands of the mrgi executable. Each registers its options on the CLI11 app and returns the
// action to run after parsing. Actions return the process exit code and throw for user errors.
#include <CLI/CLI.hpp>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include "capture/frame_source.h"
#include "reconstruction/room_model.h"
#include "runtime/pose_source.h"
#include "runtime/session_setup.h"

namespace mrgi::runtime {}
namespace mrgi::evaluation {}

namespace mrgi::app {

// The subcommands use the shared per-frame work and the evaluation libraries unqualified.
using namespace mrgi::runtime;
using namespace mrgi::evaluation;

using Action = std::function<int()>;

/// Registers every subcommand on `app` (the one mrgi CLI) and returns the action of each.
std::map<CLI::App*, Action> addCommands(CLI::App& app);

/// Checks a --technique value against the registry (a name, an alias, "REAL+VIRTUAL").
CLI::Validator techniqueValidator();
/// --pose MODE (runtime/pose_source.h), the same in every command that places a camera.
CLI::Option* addPoseOption(CLI::App& app, runtime::PoseMode& mode);

/// --intrinsics fx,fy,cx,cy and --depth-scale: a TUM or Open3D folder's calibration (capture::OpenOptions).
void addFolderCalibration(CLI::App& app, capture::OpenOptions& open);

/// The room flags of replay and live: a saved room as the real scene of the lighting, or one fused as the
/// frames come (refreshed, tracked against, saved at the end).
using RoomFlags = runtime::RoomOptions;
/// Registers --room, --fuse-room, --fuse-refresh, --track-room and --save-room; `saveWhen` ends --save-room's help.
void addRoomFlags(CLI::App& app, RoomFlags& flags, const std::string& saveWhen);
/// Checks the room flags together (one-line errors naming the flag), readies --save-room's folder and loads
/// --room (nullptr when none). `lit`: a scene is set up to be lit (a room needs one).
/// Without --room and --per-frame-mesh, a lit scene's real scene is the room fused as the frames come: `flags`
/// then gets fuse set.
std::shared_ptr<const reconstruction::RoomMesh> openRoom(RoomFlags& flags, bool lit);

Action addInfo(CLI::App& app);
Action addReplay(CLI::App& app);
Action addSynth(CLI::App& app);
Action addTrack(CLI::App& app);
Action addCalibrateFisheye(CLI::App& app);
Action addLights(CLI::App& app);
Action addImportVisp(CLI::App& app);
Action addInsert(CLI::App& app);
Action addBench(CLI::App& app);
Action addReference(CLI::App& app);
Action addLive(CLI::App& app);
Action addRecord(CLI::App& app);
Action addRoom(CLI::App& app);
Action addCompare(CLI::App& app);
Action addTrackPixels(CLI::App& app);
Action addRoomLights(CLI::App& app);

}  // namespace mrgi::app
