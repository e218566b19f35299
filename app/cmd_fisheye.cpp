// mrgi calibrate-fisheye and mrgi lights: the fisheye light-probe side of reconstruction.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <regex>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/commands.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/v4l2_source.h"
#include "reconstruction/fisheye_calibration.h"
#include "reconstruction/light_estimation.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::app {
namespace {

struct CalibrateOptions {
  std::string dir, board = "6x8", out;
  double square = 0.025;
};

int runCalibrate(const CalibrateOptions& o) {
  std::smatch m;
  if (!std::regex_match(o.board, m, std::regex(R"((\d+)[xX](\d+))")) || std::stoi(m[1]) < 2 || std::stoi(m[2]) < 2)
    throw std::invalid_argument("--board: expected inner corners as COLSxROWS (e.g. 6x8), got '" + o.board + "'");
  if (!fs::is_directory(o.dir)) throw capture::CaptureError(o.dir, "is not a directory of checkerboard images");
  std::vector<std::string> paths;
  for (const auto& e : fs::directory_iterator(o.dir))
    if (e.is_regular_file() && capture::isImageFile(e.path())) paths.push_back(e.path().string());
  std::sort(paths.begin(), paths.end());
  if (paths.empty()) throw capture::CaptureError(o.dir, "holds no images (.png .jpg .bmp .pgm .ppm .tif)");
  reconstruction::FisheyeCalibrationResult r;
  try {
    r = reconstruction::calibrateFisheye(paths, {std::stoi(m[1]), std::stoi(m[2])}, o.square);
  } catch (const std::runtime_error& e) {
    throw capture::CaptureError(o.dir, e.what());
  }
  capture::writeFisheyeCalibration(o.out, r.calibration);
  for (const auto& why : r.rejected) std::fprintf(stderr, "skipped %s\n", why.c_str());
  const auto& K = r.calibration.K;
  const auto& D = r.calibration.D;
  std::printf("%s\n", json{{"out", o.out},
                           {"views_used", r.used.size()},
                           {"views_skipped", r.rejected.size()},
                           {"rms_px", r.rms},
                           {"K", {K(0, 0), K(1, 1), K(0, 2), K(1, 2)}},
                           {"D", {D[0], D[1], D[2], D[3]}}}
                          .dump()
                          .c_str());
  return 0;
}

struct LightsOptions {
  std::string image, calib;
  int count = 16;
  bool json = false, variance = false;
  double exposure = 1.0, maxThetaDeg = 108;
  double ambientThreshold = 1.0;  ///< 0: every bit of light to the lights, no SH remainder
};

int runLights(const LightsOptions& o) {
  const capture::FisheyeCalibration c = capture::readFisheyeCalibration(o.calib);
  if (!fs::is_regular_file(o.image)) throw capture::CaptureError(o.image, "image is missing");
  cv::Mat img = capture::readAny(o.image);  // RGB
  if (img.depth() == CV_16U) img.convertTo(img, CV_32F, 1.0 / 65535.0);
  if (img.cols != c.width || img.rows != c.height)
    throw capture::CaptureError(o.image, "is " + std::to_string(img.cols) + "x" + std::to_string(img.rows) +
                                             " but the calibration " + o.calib + " is for " + std::to_string(c.width) +
                                             "x" + std::to_string(c.height));
  cv::Mat saturated;
  const cv::Mat radiance = reconstruction::linearRadiance(img, o.exposure, &saturated);
  const auto rays = reconstruction::fisheyeRays(c, o.maxThetaDeg * CV_PI / 180);
  // Lights for the part above the threshold, SH for the remainder (LightSplit); threshold 0: all lights.
  reconstruction::LightSplitOptions so;
  so.medianCut.count = o.count;
  so.medianCut.varianceSplit = o.variance || o.ambientThreshold > 0;
  so.threshold = o.ambientThreshold;
  reconstruction::LightSplit split;
  if (o.ambientThreshold > 0)
    split = reconstruction::splitLights(radiance, rays, so);
  else
    split.lights = reconstruction::medianCut(radiance, rays, so.medianCut);
  const auto& lights = split.lights;
  const bool variance = so.medianCut.varianceSplit;
  const cv::Vec3d total = reconstruction::totalPower(radiance, rays);
  const double satFraction = static_cast<double>(cv::countNonZero(saturated)) / saturated.total();
  if (o.json) {
    json arr = json::array();
    for (const auto& l : lights)
      arr.push_back({{"direction", {l.direction[0], l.direction[1], l.direction[2]}},
                     {"power", {l.power[0], l.power[1], l.power[2]}},
                     {"solid_angle_sr", l.solidAngle}});
    json sh = json::array();
    for (const auto& c : split.ambientSh) sh.push_back({c[0], c[1], c[2]});
    std::printf("%s\n", json{{"lights", arr},
                             {"ambient_sh", sh},
                             {"ambient_threshold", o.ambientThreshold},
                             {"total_power", {total[0], total[1], total[2]}},
                             {"count", lights.size()},
                             {"split", variance ? "variance" : "median"},
                             {"solid_angle_sr", rays.totalSolidAngle},
                             {"saturated_fraction", satFraction},
                             {"frame", "fisheye camera (x right, y down, z forward)"}}
                            .dump()
                            .c_str());
  } else {
    std::printf("%zu lights (%s split), total power (%.4g, %.4g, %.4g), %.1f%% pixels saturated\n", lights.size(),
                variance ? "variance" : "median", total[0], total[1], total[2], 100 * satFraction);
    const cv::Vec3d dc = split.ambientSh[0] * (2 * std::sqrt(CV_PI));
    std::printf("  remainder as SH bands 0-2: power (%.4g, %.4g, %.4g)\n", dc[0], dc[1], dc[2]);
    for (const auto& l : lights)
      std::printf("  dir (%+.3f %+.3f %+.3f)  power (%.4g, %.4g, %.4g)\n", l.direction[0], l.direction[1], l.direction[2],
                  l.power[0], l.power[1], l.power[2]);
  }
  if (satFraction > 0.01)
    std::fprintf(stderr, "warning: %.1f%% of %s is saturated; its light power is underestimated\n", 100 * satFraction,
                 o.image.c_str());
  return 0;
}

}  // namespace

Action addCalibrateFisheye(CLI::App& app) {
  auto o = std::make_shared<CalibrateOptions>();
  app.add_option("dir", o->dir, "folder of checkerboard images from the fisheye camera")->required();
  app.add_option("--board", o->board, "inner corners per row x per column")->capture_default_str();
  app.add_option("--square", o->square, "checkerboard square edge in metres")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--out", o->out, "calibration YAML to write (ROS camera_calibration form)")->required();
  return [o] { return runCalibrate(*o); };
}

Action addLights(CLI::App& app) {
  auto o = std::make_shared<LightsOptions>();
  app.add_option("image", o->image, "fisheye image: HDR (.exr/.hdr, linear) or LDR (sRGB)")->required();
  app.add_option("--calib", o->calib, "fisheye calibration YAML (K, D)")->required();
  app.add_option("--count", o->count, "number of lights; 0 = choose by energy concentration")
      ->check(CLI::Range(0, 4096))
      ->capture_default_str();
  app.add_flag("--variance", o->variance, "variance-minimising split instead of the energy median (always with a remainder)");
  app.add_option("--ambient-threshold", o->ambientThreshold,
                 "light above this multiple of the mean luminance goes to the lights, the rest to ambient_sh (SH bands "
                 "0-2); 0: all of it to the lights")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  app.add_option("--exposure", o->exposure, "relative exposure: radiance = linear value / exposure")
      ->check(CLI::PositiveNumber);
  app.add_option("--max-theta", o->maxThetaDeg, "ignore pixels further than this from the optical axis (degrees)")
      ->check(CLI::Range(1.0, 180.0));
  app.add_flag("--json", o->json, "one JSON object: lights [{direction, power}], total_power");
  return [o] { return runLights(*o); };
}

}  // namespace mrgi::app
