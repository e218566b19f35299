#include <map>
#include <stdexcept>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "lighting/techniques/registry.h"
#include "runtime/output.h"

namespace mrgi::app {

CLI::Validator techniqueValidator() {
  std::string names;
  for (const std::string& n : lighting::techniqueSpellings()) names += (names.empty() ? "" : "|") + n;
  return CLI::Validator(
      [](std::string& value) -> std::string {
        try {
          lighting::parseTechniqueChoice(value, nullptr);
        } catch (const std::invalid_argument& e) {
          return e.what();
        }
        return {};
      },
      "TECHNIQUE (" + names + " or REAL+VIRTUAL)", "technique");
}

CLI::Option* addPoseOption(CLI::App& app, runtime::PoseMode& mode) {
  std::map<std::string, runtime::PoseMode> modes;
  for (const std::string& name : runtime::poseModeNames()) modes.emplace(name, runtime::poseModeFromName(name));
  return app.add_option("--pose", mode, runtime::poseModeHelp())
      ->transform(CLI::CheckedTransformer(modes))
      ->option_text(std::string("MODE (marker|ground-truth|odometry|tracked; default ") + runtime::toString(mode) +
                    ")");
}

void addFolderCalibration(CLI::App& app, capture::OpenOptions& open) {
  app.add_option_function<std::string>(
         "--intrinsics",
         [&open](const std::string& v) {
           const std::vector<double> n = parseNumbers(v);  // four finite numbers, checked by the validator
           if (!(n[0] > 0) || !(n[1] > 0))
             throw FlagError("--intrinsics", "the focal lengths fx, fy must be positive, not '" + v + "'");
           open.intrinsics = std::array<double, 4>{n[0], n[1], n[2], n[3]};
         },
         "fx,fy,cx,cy in pixels: the camera of a TUM or Open3D folder (default: its camera_intrinsic.json or "
         "camera.json, else the format's default, said on stderr)")
      ->check(numberList(4, -1e6, 1e6));
  app.add_option("--depth-scale", open.depthUnitsPerMetre,
                 "depth units per metre of a TUM or Open3D folder's 16-bit depth images (default: TUM 5000, Open3D "
                 "1000)")
      ->check(numberAbove(0, 1e7));
}

void addRoomFlags(CLI::App& app, RoomFlags& flags, const std::string& saveWhen) {
  app.add_option("--room", flags.room,
                 "room model (from mrgi room) as the real scene of the lighting, instead of each frame's depth");
  app.add_flag("--fuse-room", flags.fuse,
               "build the room model from the frames as they come (every frame with a pose fused; its surface lights "
               "the scene from the first such frame, refreshed every --fuse-refresh frames fused): the default with a "
               "scene unless --room or --per-frame-mesh");
  app.add_flag("--per-frame-mesh", flags.perFrameMesh,
               "light each frame from its own depth mesh instead of the room fused as the frames come (every "
               "world-space pass then redone each frame)");
  app.add_option("--fuse-refresh", flags.fuseRefresh, "frames fused between refreshes of the fused room's surface")
      ->check(numberIn(1, 100000))
      ->capture_default_str();
  app.add_option("--fuse-every", flags.fuseEvery,
                 "fuse every N-th frame with a pose into the room being built, from the first (fusion's CPU a frame "
                 "for views left out: docs/real-time.md)")
      ->check(numberIn(1, 100))
      ->capture_default_str();
  app.add_flag(
      "--track-room", flags.track,
      "with --fuse-room and odometry or tracked poses, align each frame with the room as fused so far (its surface "
      "at each refresh) before the keyframes; off by default: with the marker in view it placed the bundled "
      "sessions' frames worse (ATE 6 -> 10 mm)");
  app.add_option("--save-room", flags.save,
                 "with --fuse-room: write the room " + saveWhen + " (as mrgi room --out does)");
}

std::shared_ptr<const reconstruction::RoomMesh> openRoom(RoomFlags& flags, bool lit) {
  std::shared_ptr<const reconstruction::RoomMesh> room;
  if (!flags.room.empty()) {
    if (!lit)
      throw std::invalid_argument("--room " + flags.room +
                                  ": needs --scene (the room is the real scene of the lighting)");
    room = std::make_shared<const reconstruction::RoomMesh>(reconstruction::loadRoom(flags.room));
  }
  if (flags.fuse && !flags.room.empty())
    throw std::invalid_argument("--fuse-room builds a new room; --room " + flags.room + " uses a saved one: pass one");
  if (flags.fuse && !lit)
    throw std::invalid_argument("--fuse-room needs --scene (the room is the real scene of the lighting)");
  if (flags.perFrameMesh && (flags.fuse || !flags.room.empty()))
    throw FlagError("--per-frame-mesh",
                    "lights each frame from its own depth: it takes neither --room nor --fuse-room");
  // The default real scene of a lit replay or live window: the room fused as the frames come. Its world-space
  // lighting (the RSMs, the volumes, the VALs) is then redone at its refreshes only, not every frame.
  flags.fuseAsked = flags.fuse;
  const bool fuse = flags.fuse || (lit && flags.room.empty() && !flags.perFrameMesh);
  if (!flags.save.empty() && !fuse)
    throw std::invalid_argument(
        "--save-room " + flags.save +
        " needs the room fused as the frames come (--scene, without --room or --per-frame-mesh)");
  if (flags.track && !fuse)
    throw FlagError("--track-room",
                    "needs the room fused as the frames come (a saved --room is tracked against "
                    "already; --per-frame-mesh has none)");
  flags.fuse = fuse;
  // Checked (and created) before the run; written when it ends.
  if (!flags.save.empty()) {
    const runtime::OutputClaim checked = prepareOutputDirectory(flags.save, "room.json", "mrgi room");
  }
  return room;
}

}  // namespace mrgi::app
