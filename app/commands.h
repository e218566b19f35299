#pragma once
// Subcommands of the mrgi executable. Each registers its options on the CLI11 app and returns the
// action to run after parsing. Actions return the process exit code and throw for user errors.
#include <CLI/CLI.hpp>
#include <functional>
#include <map>

#include "runtime/pose_source.h"

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
Action addRoomLights(CLI::App& app);

}  // namespace mrgi::app
