// mrgi calibrate-fisheye and mrgi lights: the flags of the fisheye light probe (runtime/light_probe.h).
#include <memory>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "capture/checks.h"
#include "runtime/light_probe.h"

namespace mrgi::app {

Action addCalibrateFisheye(CLI::App& app) {
  auto o = std::make_shared<CalibrateOptions>();
  app.add_option("dir", o->dir, "folder of checkerboard images from the fisheye camera")->required();
  app.add_option("--board", o->board, "inner corners per row x per column")->capture_default_str();
  app.add_option("--square", o->square, "checkerboard square edge in metres")
      ->check(numberAbove(0, 10))
      ->capture_default_str();
  app.add_option("--out", o->out, "calibration YAML to write (ROS camera_calibration form)")->required();
  return [o] { return calibrateFisheye(*o); };
}

Action addLights(CLI::App& app) {
  auto o = std::make_shared<LightsOptions>();
  app.add_option("image", o->image,
                 "fisheye image or equirectangular probe: HDR (.exr, Radiance .hdr; linear) or LDR (sRGB)")
      ->required();
  app.add_option("--calib", o->calib,
                 "fisheye calibration YAML (K, D); without it the image is an equirectangular probe (2:1)");
  app.add_option("--count", o->count, "number of lights; 0 = choose by energy concentration")
      ->check(numberIn(0, 4096))
      ->capture_default_str();
  app.add_flag("--variance", o->variance,
               "variance-minimising split instead of the energy median (always with a remainder)");
  app.add_option(
         "--ambient-threshold", o->ambientThreshold,
         "light above this multiple of the mean luminance goes to the lights, the rest to ambient_sh (SH bands "
         "0-2, fitted to the irradiance); 0: all of it to the lights (default: 2 for a whole-sphere probe, 1 for a "
         "fisheye's field)")
      ->check(numberIn(0.0, 1e6));
  app.add_option("--exposure", o->exposure, "relative exposure: radiance = linear value / exposure")
      ->check(numberIn(capture::kMinExposure, capture::kMaxExposure));
  app.add_option("--max-theta", o->maxThetaDeg, "ignore pixels further than this from the optical axis (degrees)")
      ->check(numberIn(1.0, 180.0));
  app.add_flag("--json", o->json,
               "one JSON object: lights [a scene file's directional lights], estimated [{direction towards the light, "
               "power}], total_power");
  return [o] { return estimateLights(*o); };
}

}  // namespace mrgi::app
