// mrgi synth: writes a synthetic tabletop session with ground truth through the session writer.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "app/cli_checks.h"
#include "app/commands.h"
#include "app/output.h"
#include "app/tabletop.h"
#include "capture/checks.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/sensor_model.h"
#include "capture/session.h"
#include "evaluation/reference_scene.h"
#include "lighting/scene_file.h"
#include "reconstruction/light_estimation.h"

namespace fs = std::filesystem;

namespace mrgi::app {
namespace {

using groundtruth::PathTracer;
using groundtruth::RayCaster;

struct SynthOptions {
  std::string out;
  int frames = 20;
  int width = 640, height = 480;
  uint64_t seed = 1;
  int tagId = 0;
  double tagSize = 0.16;
  bool staticCamera = false;         ///< every frame from the orbit's first pose (only the sensor noise changes)
  int fisheyeEvery = 30;             ///< a fisheye frame every N frames (the room is static), 0 = none
  std::string render = "pathtrace";  ///< pathtrace (global illumination) | raycast (direct light + constant ambient)
  int spp = 64, bounces = 3;
  /// The reference delta's samples per pixel around the objects (groundtruth::virtualFocus); 0: the delta is
  /// the composite's render minus the frame's own (spp, one seed, the camera's noise in both).
  int referenceFocusSpp = 0;
  std::string scene;            ///< virtual objects whose path-traced reference composite each frame gets
  std::string environment;      ///< HDR equirect EXR: outdoors under it instead of the room
  double environmentScale = 0;  ///< 0: a white upward surface in the open reads 0.6
  int scan = 0;                 ///< look-around frames after the orbit (walls, ceiling, the lamp)
  std::string exposure = "1";   ///< "auto" (at most 1 % of pixels clip) or a fixed relative exposure
  bool moveBox = false;         ///< the box moves to the front of the table a third of the way through (carving)
  bool moveLight = false;       ///< the lamp moves a third of the way round the table over the orbit
};

/// The look-around: standing at the table's front edge, the camera turns a full circle twice, once
/// looking 35 degrees up (walls, ceiling, the lamp) and once 20 degrees down (the floor, the table's far
/// side and the box's back).
capture::Pose scanCamera(int i, int n) {
  const cv::Vec3d eye(0.0, 1.35, 0.95);
  const int half = std::max(1, n / 2);
  const bool up = i < half;
  const int k = up ? i : i - half, m = up ? half : std::max(1, n - half);
  const double yaw = -CV_PI + 2 * CV_PI * (k + 0.5) / m, pitch = (up ? 35.0 : -20.0) * CV_PI / 180;
  const cv::Vec3d dir(std::cos(pitch) * std::sin(yaw), std::sin(pitch), -std::cos(pitch) * std::cos(yaw));
  return capture::lookAtPose(eye, eye + dir);
}

/// The exposure at which at most 1 % of the pixels have a channel at or above the 8-bit level 250 (the
/// sensor's noise aside), never above 1; "1" or a number: that exposure.
double pickExposure(const std::string& mode, const cv::Mat& radiance) {
  if (mode != "auto") return parseNumbers(mode)[0];  // checked by the flag's validator
  std::vector<float> peak(radiance.total());
  for (size_t i = 0; i < peak.size(); ++i) {
    const cv::Vec3f v = radiance.at<cv::Vec3f>(static_cast<int>(i));
    peak[i] = std::max({v[0], v[1], v[2]});
  }
  const size_t q = peak.size() * 99 / 100;
  std::nth_element(peak.begin(), peak.begin() + static_cast<std::ptrdiff_t>(q), peak.end());
  // Level 245 leaves room for the sensor noise (sigma 1.2 levels) below the clip detector's 250.
  const double limit = capture::srgbToLinear(245.f / 255.f);
  return peak[q] > limit ? limit / peak[q] : 1.0;
}

/// Loads an equirectangular EXR (linear RGB, 2:1) as the environment; scale 0 picks the exposure at which
/// a white upward-facing surface under the open sky has radiance 0.6.
std::shared_ptr<const groundtruth::EnvironmentMap> loadEnvironment(const std::string& path, double& scale) {
  const std::string expected = "cannot be read as an HDR environment (float EXR, equirectangular, width = 2 x height)";
  cv::Mat img;
  try {
    img = capture::readAny(path);  // RGB
  } catch (const capture::InputError& e) {
    const std::string why = e.what();
    throw capture::CaptureError(path, expected + ": " + why.substr(std::min(why.size(), path.size() + 2)));
  }
  if (img.depth() != CV_32F || img.cols != 2 * img.rows) throw capture::CaptureError(path, expected);
  if (scale <= 0) {
    // Irradiance on an upward plane: sum of L cos(theta) over the upper half's texels (solid angle each),
    // from the map as the path tracer sees it (non-finite and negative texels cleared).
    const groundtruth::EnvironmentMap unscaled(img, 1.f);
    double E = 0;
    const int W = unscaled.width(), H = unscaled.height();
    for (int y = 0; y < H / 2; ++y) {
      const double theta = CV_PI * (y + 0.5) / H;
      const double dOmega = (2 * CV_PI / W) * (CV_PI / H) * std::sin(theta);
      for (int x = 0; x < W; ++x)
        E += capture::luminance(cv::Vec3d(unscaled.image().at<cv::Vec3f>(y, x))) * std::cos(theta) * dOmega;
    }
    if (!(E > 0)) throw capture::CaptureError(path, "is black above the horizon");
    scale = 0.6 * CV_PI / E;
  }
  return std::make_shared<groundtruth::EnvironmentMap>(img, static_cast<float>(scale));
}

cv::Vec3f toFloat(const cv::Vec3d& v) {
  return {static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])};
}

struct RgbdRender {
  cv::Mat radiance;  // CV_32FC3 linear, 2x2 supersampled
  cv::Mat depth;     // CV_32FC1 ideal z, metres
  cv::Mat normals;   // CV_32FC3 camera space
};

/// Camera radiance by the path tracer (anti-aliased) when one is given, else ray cast (2x2 supersampled).
RgbdRender renderRgbd(const RayCaster& rc, const PathTracer* pt, const capture::Intrinsics& k,
                      const capture::Pose& T_wc) {
  RgbdRender r{cv::Mat(k.height, k.width, CV_32FC3), cv::Mat(k.height, k.width, CV_32FC1),
               cv::Mat(k.height, k.width, CV_32FC3)};
  const cv::Vec3f origin = toFloat(capture::transformPoint(T_wc, {0, 0, 0}));
  const cv::Matx33d R = capture::rotationOf(T_wc), Rt = R.t();
  cv::parallel_for_(cv::Range(0, k.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < k.width; ++x) {
        cv::Vec3f sum(0, 0, 0);
        for (int s = 0; s < (pt ? 0 : 4); ++s) {  // 2x2 supersampling for clean tag edges
          const double px = x + (s % 2 ? 0.25 : -0.25), py = y + (s / 2 ? 0.25 : -0.25);
          const cv::Vec3f d = cv::normalize(toFloat(R * cv::Vec3d((px - k.cx) / k.fx, (py - k.cy) / k.fy, 1.0)));
          if (auto h = rc.intersect(origin, d)) sum += rc.shadeDirect(*h);
        }
        r.radiance.at<cv::Vec3f>(y, x) = sum * 0.25f;
        // Depth and normal at the pixel centre, as a depth camera measures them.
        const cv::Vec3d dc((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0);
        const cv::Vec3f d = cv::normalize(toFloat(R * dc));
        // The lamp is a solid object to the depth sensor too.
        const auto h = rc.intersect(origin, d, 1e-4f, 1e30f, true);
        r.depth.at<float>(y, x) = h ? static_cast<float>(h->t / cv::norm(dc)) : 0.f;
        r.normals.at<cv::Vec3f>(y, x) = h ? toFloat(Rt * cv::Vec3d(h->normal)) : cv::Vec3f(0, 0, 0);
      }
  });
  if (pt) r.radiance = pt->render({k, T_wc});
  return r;
}

cv::Mat renderFisheye(const RayCaster& rc, const PathTracer* pt, const capture::FisheyeCalibration& c) {
  cv::Mat img(c.height, c.width, CV_32FC3, cv::Scalar(0, 0, 0));
  const capture::Pose& T = *c.T_world_fisheye;
  const cv::Vec3f origin = toFloat(capture::transformPoint(T, {0, 0, 0}));
  const cv::Matx33d R = capture::rotationOf(T);
  cv::parallel_for_(cv::Range(0, c.height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      for (int x = 0; x < c.width; ++x) {
        cv::Vec3d ray;
        if (!reconstruction::fisheyePixelToRay(c, x, y, ray)) continue;  // the lens model folds over: no ray
        if (ray[2] < std::cos(CV_PI * 0.5 * 1.2)) continue;              // outside the lens' field of view
        const cv::Vec3f d = cv::normalize(toFloat(R * ray));
        if (pt) {
          cv::RNG rng(static_cast<uint64_t>(y) * 100003u + static_cast<uint64_t>(x) + 1);
          cv::Vec3f sum(0, 0, 0);
          for (int s = 0; s < pt->options().spp; ++s) sum += pt->trace(origin, d, rng);
          img.at<cv::Vec3f>(y, x) = sum * (1.f / static_cast<float>(pt->options().spp));
        } else if (auto h = rc.intersect(origin, d)) {
          img.at<cv::Vec3f>(y, x) = rc.shadeDirect(*h);
        }
      }
  });
  return img;
}

capture::FisheyeCalibration tableFisheye() {
  // The calibration of a real 800x503 fisheye (equidistant model), as OpenCV's fisheye module estimates it
  // from ../shared/data/fisheye-ros-calib; mounted on the table, looking at the ceiling.
  capture::FisheyeCalibration c;
  c.width = 800;
  c.height = 503;
  c.K = cv::Matx33d(290.050152, 0, 399.938345, 0, 289.392837, 273.885669, 0, 0, 1);
  c.D = {-0.030464, -0.019695, 0.002098, 0.001030};
  // Optical axis (z) = world up; x = world x; y = z x x = world -z.
  c.T_world_fisheye = capture::Pose(1, 0, 0, -0.45, 0, 0, 1, 0.76, 0, -1, 0, 0.25, 0, 0, 0, 1);
  return c;
}

/// Camera linear radiance -> sRGB 8-bit plus the frame's sensor noise (the same noise for a given frame).
cv::Mat cameraImage(const cv::Mat& radiance, uint64_t noiseSeed) {
  cv::Mat srgb = capture::encodeSrgb(radiance);
  cv::Mat noiseImg(srgb.size(), CV_16SC3), noisy, out;
  cv::RNG rng(noiseSeed);
  rng.fill(noiseImg, cv::RNG::NORMAL, 0, 1.2);
  srgb.convertTo(noisy, CV_16SC3);
  noisy += noiseImg;
  noisy.convertTo(out, CV_8UC3);  // saturating
  return out;
}

/// --move-light: the lamp's position at frame i of an orbit of n frames, a third of the way round the vertical
/// axis through the tag from where it starts, at the same height (look-around frames keep the last).
cv::Vec3f movedLight(const cv::Vec3f& start, int i, int n) {
  const double t = n > 1 ? std::min(i, n - 1) / static_cast<double>(n - 1) : 0.0;
  const double r = std::hypot(start[0], start[2]), a = std::atan2(start[2], start[0]) + t * 2.0 * CV_PI / 3.0;
  return {static_cast<float>(r * std::cos(a)), start[1], static_cast<float>(r * std::sin(a))};
}

int runSynth(const SynthOptions& o) {
  TabletopConfig tc;
  tc.tagId = o.tagId;
  tc.tagSize = o.tagSize;
  tc.seed = o.seed;
  if (!o.environment.empty()) {
    if (o.render != "pathtrace") throw std::invalid_argument("--environment needs --render pathtrace");
    double scale = o.environmentScale;
    tc.environment = loadEnvironment(o.environment, scale);
    tc.environmentInfo = {{"file", fs::path(o.environment).filename().string()},
                          {"scale", scale},
                          {"mapping", "equirectangular, y up, row 0 = zenith, u = 0.5 at -z"}};
  }
  Tabletop table = buildTabletop(tc);
  const bool pathTrace = o.render == "pathtrace";
  // The reference's virtual objects (marker frame) move into the room through the true marker pose.
  groundtruth::Scene augmented;
  if (!o.scene.empty()) {
    const lighting::SceneDescription desc = lighting::loadScene(o.scene);
    if (desc.objects.empty()) throw capture::CaptureError(o.scene, "has no virtual object to render a reference of");
    augmented = table.scene;
    addVirtualObjects(desc.objects, table.T_world_marker, augmented);
  }
  if (pathTrace) {
    table.groundTruth["scene"]["generator"] =
        "mrgi synth (path traced, " + std::to_string(o.spp) + " spp, " + std::to_string(o.bounces) + " bounces)";
    // The real-time stand-in for the bounce light the path tracer computes.
    table.groundTruth["scene"]["ambient_note"] =
        "ambient_radiance is a suggestion for real-time shading; the frames carry full global illumination";
  }
  if (!o.scene.empty())
    // Paths in the manifest are relative to the session directory.
    table.groundTruth["reference"] = {
        {"scene", fs::relative(fs::absolute(o.scene), fs::absolute(o.out)).generic_string()},
        {"composite", "reference/NNNNNN.png"},
        {"delta", "reference/delta_NNNNNN.exr"},
        {"mask", "reference/mask_NNNNNN.png"},
        {"note", "the camera image of the room with the scene's objects, same noise"}};
  // A reference delta of its own two renders, more samples around the objects (path-traced frames only).
  const bool focusedReference = !o.scene.empty() && o.referenceFocusSpp > 0 && pathTrace;
  if (focusedReference) {
    table.groundTruth["reference"]["delta_focus_spp"] = o.referenceFocusSpp;
    table.groundTruth["reference"]["note"] =
        "the camera image of the room with the scene's objects, same noise; the delta from its own two renders, " +
        std::to_string(o.referenceFocusSpp) + " samples per pixel around the objects (" + std::to_string(o.spp) +
        " elsewhere)";
  }
  const RayCaster rc(table.scene);
  // --move-box: from frame `moveAt` on, the room is the same but for the box, moved to the front of the table.
  std::optional<Tabletop> movedTable;  // outlives its ray caster, which refers to its scene
  std::optional<RayCaster> moved;
  const int moveAt = (o.frames + o.scan) / 3;
  if (o.moveBox) {
    if (!o.scene.empty())
      throw std::invalid_argument("--move-box cannot be combined with --scene (references of a changing room)");
    TabletopConfig mc = tc;
    mc.boxOffset = movedBoxOffset();
    movedTable = buildTabletop(mc);
    moved.emplace(movedTable->scene);
    const auto [lo, hi] = tabletopBox();
    const cv::Vec3f d = movedBoxOffset();
    table.groundTruth["scene"]["box_moves"] = {{"at_frame", moveAt},
                                               {"min", {lo[0] + d[0], lo[1] + d[1], lo[2] + d[2]}},
                                               {"max", {hi[0] + d[0], hi[1] + d[1], hi[2] + d[2]}}};
  }
  if (o.moveLight) {
    if (!o.environment.empty()) throw std::invalid_argument("--move-light needs the room's lamp (not --environment)");
    if (o.moveBox) throw std::invalid_argument("--move-light cannot be combined with --move-box");
    if (o.fisheyeEvery > 0)
      throw std::invalid_argument(
          "--move-light cannot be combined with --fisheye-every (the fisheye is rendered once)");
    table.groundTruth["scene"]["light_moves"] = {
        {"arc_deg", 120}, {"axis", "world y through the tag"}, {"note", "each frame's lights are in frames.jsonl"}};
  }
  groundtruth::PathTraceOptions po;
  po.spp = o.spp;
  po.bounces = o.bounces;
  po.jitter = true;

  capture::SessionManifest m;
  const double f = 525.0 * o.width / 640.0;
  m.colour = {o.width, o.height, f, f, (o.width - 1) / 2.0, (o.height - 1) / 2.0};
  m.depth = m.colour;
  m.depthUnitsMetres = 0.001;
  m.marker = capture::MarkerSpec{tc.tagFamily, tc.tagSize, tc.tagId};
  if (o.fisheyeEvery > 0) m.fisheye = tableFisheye();
  m.groundTruth = table.groundTruth;
  capture::SessionWriter writer(o.out, m);

  cv::Mat fisheye;
  if (m.fisheye) {
    groundtruth::PathTraceOptions fo = po;
    fo.spp = std::max(4, o.spp / 4);
    const PathTracer fpt(rc, fo);
    fisheye = renderFisheye(rc, pathTrace ? &fpt : nullptr, *m.fisheye);
  }
  std::optional<RayCaster> augmentedCaster;
  if (!o.scene.empty()) augmentedCaster.emplace(augmented);
  const capture::DepthNoiseModel noise;
  ProgressBar bar("synth");
  const int total = o.frames + o.scan;
  for (int i = 0; i < total; ++i) {
    const bool scanning = i >= o.frames;
    capture::Frame frame;
    frame.index = i;
    frame.timestamp = i / 30.0;
    frame.groundTruthT_world_camera =
        scanning ? scanCamera(i - o.frames, o.scan) : orbitCamera(o.staticCamera ? 0 : i, o.frames);
    po.seed = o.seed * 1000003u + static_cast<uint64_t>(i);
    // With a reference the frame's two renders share its step of the bar.
    const double share = augmentedCaster && pathTrace && !scanning ? 0.5 : 1.0;
    po.progress = [&bar, i, share, total](double x) { bar((i + share * x) / total); };
    // --move-light: this frame's scenes with the lamp where it is now (the casters refer to them).
    std::optional<groundtruth::Scene> litRoom, litAugmented;
    std::optional<RayCaster> litRc, litAugmentedRc;
    if (o.moveLight && !table.scene.lights.empty()) {
      const cv::Vec3f p = movedLight(table.scene.lights[0].position, i, o.frames);
      litRoom = table.scene;
      litRoom->lights[0].position = p;
      litRc.emplace(*litRoom);
      if (augmentedCaster) {
        litAugmented = augmented;
        litAugmented->lights[0].position = p;
        litAugmentedRc.emplace(*litAugmented);
      }
      capture::GroundTruthLight l;
      l.position = cv::Vec3d(p);
      l.intensity = cv::Vec3d(table.scene.lights[0].intensity);
      l.radius = table.scene.lights[0].radius;
      frame.groundTruthLights = std::vector<capture::GroundTruthLight>{l};
    }
    const RayCaster& room = litRc ? *litRc : moved && i >= moveAt ? *moved : rc;
    const PathTracer pt(room, po);
    const RgbdRender r = renderRgbd(room, pathTrace ? &pt : nullptr, m.colour, *frame.groundTruthT_world_camera);
    capture::RgbdFrame rgbd;
    const uint64_t noiseSeed = o.seed * 7919 + static_cast<uint64_t>(i);
    const double exposure = pickExposure(o.exposure, r.radiance);
    rgbd.colour = cameraImage(exposure == 1.0 ? r.radiance : cv::Mat(r.radiance * exposure), noiseSeed);
    rgbd.exposure = exposure;
    rgbd.depth = capture::applyDepthNoise(r.depth, r.normals, m.colour.fx, m.colour.fy, m.colour.cx, m.colour.cy, noise,
                                          o.seed * 104729 + static_cast<uint64_t>(i));
    rgbd.colourIntrinsics = rgbd.depthIntrinsics = m.colour;
    if (augmentedCaster && !scanning) {
      // The ideal composite: the same camera (seed, noise) looking at the room with the objects in it.
      const groundtruth::PinholeCamera cam{m.colour, *frame.groundTruthT_world_camera};
      groundtruth::PathTraceOptions rhoOptions = po;
      rhoOptions.progress = [&bar, i, total](double x) { bar((i + 0.5 + 0.5 * x) / total); };
      const RayCaster& withObjects = litAugmentedRc ? *litAugmentedRc : *augmentedCaster;
      const cv::Mat mask = groundtruth::virtualMask(withObjects, cam);
      cv::Mat rho, delta;
      if (focusedReference) {
        // The delta from its own pair of renders with more samples around the objects (common random
        // numbers in both); the composite is the frame's image plus that delta (the camera's noise kept).
        groundtruth::PathTraceOptions focused = rhoOptions;
        focused.focus = groundtruth::virtualFocus(litAugmented ? *litAugmented : augmented, cam);
        focused.focusSpp = o.referenceFocusSpp;
        const cv::Mat rhoN = PathTracer(withObjects, focused).render(cam);
        focused.progress = nullptr;
        const cv::Mat muN = PathTracer(room, focused).render(cam);
        delta = rhoN - muN;
        rhoN.copyTo(delta, mask);
        rho = r.radiance + delta;
        rhoN.copyTo(rho, mask);
      } else {
        rho = pathTrace ? PathTracer(withObjects, rhoOptions).render(cam) : r.radiance;
        delta = rho - r.radiance;
        rho.copyTo(delta, mask);
      }
      char name[64];
      const fs::path dir = fs::path(o.out) / "reference";
      fs::create_directories(dir);
      std::snprintf(name, sizeof name, "%06d.png", i);
      writePng((dir / name).string(), cameraImage(exposure == 1.0 ? rho : cv::Mat(rho * exposure), noiseSeed));
      std::snprintf(name, sizeof name, "delta_%06d.exr", i);
      writeExr((dir / name).string(), delta, focusedReference);
      std::snprintf(name, sizeof name, "mask_%06d.png", i);
      writePng((dir / name).string(), mask);
    }
    frame.rgbd = std::move(rgbd);
    if (m.fisheye && i % o.fisheyeEvery == 0) {
      capture::FisheyeFrame ff;
      ff.image = fisheye;
      ff.exposure = 1.0;
      ff.calibration = *m.fisheye;
      frame.fisheye = std::move(ff);
    }
    writer.append(frame);
  }
  std::printf("wrote %d frames to %s\n", total, o.out.c_str());
  return 0;
}

}  // namespace

Action addSynth(CLI::App& app) {
  auto o = std::make_shared<SynthOptions>();
  app.add_option("--out", o->out, "new session directory (must not exist or be empty)")->required();
  app.add_option("--frames", o->frames, "number of frames along the camera orbit")->check(numberIn(1, 100000));
  app.add_option("--environment", o->environment,
                 "outdoors under this HDR environment (equirectangular EXR) instead of the room");
  app.add_option("--environment-scale", o->environmentScale,
                 "multiplies the environment (default: a white upward surface reads 0.6)")
      ->check(numberIn(0, 1e6));
  app.add_flag("--static-camera", o->staticCamera,
               "keep the camera at the orbit's first pose (only the sensor noise changes)");
  app.add_option("--width", o->width, "image width")->check(numberIn(16, 8192));
  app.add_option("--height", o->height, "image height")->check(numberIn(12, 8192));
  app.add_option("--seed", o->seed, "noise seed (output is deterministic for a seed)");
  app.add_option("--tag-id", o->tagId, "tag36h11 id of the marker on the table")->check(numberIn(0, 586));
  app.add_option("--tag-size", o->tagSize, "marker black-square edge in metres")->check(numberAbove(0, 10));
  app.add_option("--render", o->render, "pathtrace (global illumination, default) or raycast (direct light + ambient)")
      ->check(CLI::IsMember({"pathtrace", "raycast"}));
  app.add_option("--spp", o->spp, "path-traced samples per pixel")->check(numberIn(1, 1 << 16));
  app.add_option("--reference-focus-spp", o->referenceFocusSpp,
                 "with --scene: the reference delta from its own two renders, this many samples per pixel around the "
                 "objects (three radii), --spp elsewhere, written as half floats (0 = the composite's render minus the "
                 "frame's)")
      ->check(numberIn(0, 1 << 20));
  app.add_option("--bounces", o->bounces, "path-traced bounces")->check(numberIn(0, 64));
  app.add_option("--scene", o->scene,
                 "also write each frame's reference composite with this scene's objects (reference/)");
  app.add_option("--scan", o->scan,
                 "append N look-around frames (walls, ceiling, the lamp; no marker in view, no reference)")
      ->check(numberIn(0, 100000));
  app.add_flag("--move-light", o->moveLight,
               "the lamp moves a third of the way round the table over the orbit (each frame records its lights)");
  app.add_flag("--move-box", o->moveBox,
               "the box moves to the front of the table a third of the way through (a room that changes: carving)");
  app.add_option("--exposure", o->exposure,
                 "auto (at most 1 % of pixels clip; recorded per frame) or a relative exposure")
      ->check(numberList(1, capture::kMinExposure, capture::kMaxExposure, {"auto"}));
  app.add_option("--fisheye-every", o->fisheyeEvery, "store a fisheye HDR frame every N frames (0 = no fisheye)")
      ->check(numberIn(0, 1e6));
  return [o] { return runSynth(*o); };
}

}  // namespace mrgi::app
