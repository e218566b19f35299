// mrgi track: the flags of tracking a marker or the camera per frame (runtime/track.h).
#include <memory>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "runtime/track.h"

namespace mrgi::app {

Action addTrack(CLI::App& app) {
  auto o = std::make_shared<TrackOptions>();
  auto intrinsics = std::make_shared<std::string>();
  app.add_option("input", o->input,
                 "session directory, TUM sequence, Open3D RGB-D folder, .oni file, or one image (with --intrinsics)")
      ->required();
  app.add_flag("--json", o->json,
               "one JSON object per line per frame and tag: frame, status, id, T_camera_tag (with --pose: per frame: "
               "frame, status, by, T_camera_world)");
  auto pose = std::make_shared<runtime::PoseMode>(runtime::PoseMode::Tracked);
  CLI::Option* poseOption = addPoseOption(app, *pose);
  poseOption->description("the camera's pose per frame from this source (" + runtime::poseModeHelp() +
                          ") instead of each tag's pose: JSON lines frame, status (tracked|lost), by "
                          "(marker|odometry|relocalised|ground-truth), "
                          "T_camera_world (row-major 4x4, metres; world = the marker frame)");
  app.add_option("--family", o->family, "AprilTag family (default: the session's, else tag36h11)")->check(tagFamily());
  app.add_option("--size", o->size, "tag black-square edge in metres (default: the session's, else 0.1)")
      ->check(numberIn(1e-3, 10));
  app.add_option("--id", o->id, "track only this tag id (default: the session's marker, else every tag)")
      ->check(numberIn(0, 1e6));
  app.add_option("--intrinsics", *intrinsics,
                 "fx,fy,cx,cy in pixels, for a single image input or a TUM or Open3D folder (default: its "
                 "camera_intrinsic.json or camera.json, else the format's default, said on stderr)")
      ->check(numberList(4, -1e6, 1e6));
  app.add_option("--depth-scale", o->depthUnitsPerMetre,
                 "depth units per metre of a TUM or Open3D folder's 16-bit depth images (default: TUM 5000, Open3D "
                 "1000)")
      ->check(numberAbove(0, 1e7));
  app.add_option("--hold", o->hold, "seconds to hold the last pose after the tag disappears before 'lost'")
      ->check(numberIn(0, 3600));
  app.add_flag("--no-smooth", o->noSmooth, "report raw per-frame poses (no One-Euro smoothing)");
  app.add_option("--smooth-cutoff", o->smoothCutoff, "One-Euro cutoff at rest, Hz")->check(numberAbove(0, 1e3));
  app.add_option("--smooth-beta", o->smoothBeta, "One-Euro cutoff added per unit of speed")->check(numberIn(0, 1e3));
  app.add_option("--smooth-derivative", o->smoothDerivative, "One-Euro cutoff of the speed estimate, Hz")
      ->check(numberAbove(0, 1e3));
  app.add_flag("--refine-depth", o->refineDepth,
               "re-seat the pose on the depth plane under the tag (registered depth)");
  app.add_option("--decimate", o->decimate, "detect quads on an image decimated by this factor (faster)")
      ->check(numberIn(1.0, 8.0));
  return [o, pose, poseOption, intrinsics] {
    if (poseOption->count() > 0) o->pose = *pose;
    if (!intrinsics->empty()) {
      const std::vector<double> v = parseNumbers(*intrinsics);  // four finite numbers, checked by the validator
      if (!(v[0] > 0) || !(v[1] > 0))
        throw FlagError("--intrinsics", "the focal lengths fx, fy must be positive, not '" + *intrinsics + "'");
      o->intrinsics = cv::Vec4d(v[0], v[1], v[2], v[3]);
    }
    return track(*o);
  };
}

}  // namespace mrgi::app
