#include "evaluation/synth.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "capture/checks.h"
#include "capture/colour.h"
#include "capture/error.h"
#include "capture/image_io.h"
#include "capture/sensor_model.h"
#include "capture/session.h"
#include "evaluation/reference_scene.h"
#include "evaluation/tabletop.h"
#include "lighting/scene_file.h"
#include "reconstruction/light_estimation.h"
#include "runtime/output.h"

namespace fs = std::filesystem;

namespace mrgi::evaluation {
namespace {

using groundtruth::PathTracer;
using groundtruth::RayCaster;
using runtime::writeExr;
using runtime::writePng;

/// The look-around, as a person scanning the room would move (a camera at 30 frames a second, every few
/// frames kept): from where the orbit ends the camera steps back, still looking at the table, to stand a
/// metre in front of it; there it turns a full circle, tilting 35 degrees up on the way out (walls, ceiling,
/// the lamp) and back down to the table and its marker at the end. It turns at an even rate, so consecutive
/// frames overlap (at 36 frames about 12 degrees apart against a 63-degree field of view), and it moves only
/// while it sees the table: a view of bare walls holds rotation well and translation poorly.
capture::Pose scanCamera(int i, int n, const capture::Pose& orbitEnd) {
  const cv::Vec3d start = capture::translationOf(orbitEnd), eye(0.0, 1.4, 1.0), table(0.0, 0.75, 0.0);
  const double t = (i + 1.0) / std::max(1, n);          // 0 is the orbit's last frame
  const auto ramp = [](double x, double a, double b) {  // 0 before a, 1 after b, smooth between
    const double u = std::clamp((x - a) / (b - a), 0.0, 1.0);
    return u * u * (3 - 2 * u);
  };
  constexpr double kStep = 0.15;  // the share of the frames that step back
  if (t <= kStep) {
    const cv::Vec3d pos = start + (eye - start) * ramp(t, 0.0, kStep);
    return capture::lookAtPose(pos, table);
  }
  const cv::Vec3d d = cv::normalize(table - eye);
  const double yaw0 = std::atan2(d[0], -d[2]), pitch0 = std::asin(d[1]), up = 35.0 * CV_PI / 180;
  const double u = (t - kStep) / (1 - kStep);
  const double pitch = pitch0 + (up - pitch0) * (ramp(u, 0.0, 0.25) - ramp(u, 0.75, 1.0));
  const double yaw = yaw0 + 2 * CV_PI * u;
  const cv::Vec3d dir(std::cos(pitch) * std::sin(yaw), std::sin(pitch), -std::cos(pitch) * std::cos(yaw));
  return capture::lookAtPose(eye, eye + dir);
}

/// The exposure at which at most 1 % of the pixels have a channel at or above the 8-bit level 250 (the
/// sensor's noise aside), never above 1; a fixed exposure: that one.
double pickExposure(const std::optional<double>& fixed, const cv::Mat& radiance) {
  if (fixed) return *fixed;
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
          if (auto h = rc.intersect(origin, d))
            sum += rc.shadeDirect(*h);
          else if (const auto& env = rc.scene().environmentMap)
            sum += env->radiance(d);  // the sky (outdoors, or through a window)
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

/// The fisheye's image of the room: path traced at `spp` with `options` when given, else ray cast.
cv::Mat renderFisheye(const RayCaster& rc, std::optional<groundtruth::PathTraceOptions> options, int spp,
                      const capture::FisheyeCalibration& c) {
  std::optional<PathTracer> tracer;
  if (options) {
    options->spp = spp;
    tracer.emplace(rc, *options);
  }
  const PathTracer* pt = tracer ? &*tracer : nullptr;
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
        } else if (const auto& env = rc.scene().environmentMap) {
          img.at<cv::Vec3f>(y, x) = env->radiance(d);
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

/// Options that do not go together, each named by its flag.
void checkCombinations(const SynthOptions& o) {
  if (!o.environment.empty() && o.render != "pathtrace")
    throw std::invalid_argument("--environment needs --render pathtrace");
  if (o.moveBox && !o.scene.empty())
    throw std::invalid_argument("--move-box cannot be combined with --scene (references of a changing room)");
  if (o.windowSun && !o.environment.empty())
    throw std::invalid_argument("--window-sun needs the room (not --environment)");
  if (o.moveLight) {
    if (!o.environment.empty()) throw std::invalid_argument("--move-light needs the room's lamp (not --environment)");
    if (o.moveBox) throw std::invalid_argument("--move-light cannot be combined with --move-box");
    if (o.fisheyeEvery > 0)
      throw std::invalid_argument(
          "--move-light cannot be combined with --fisheye-every (the fisheye is rendered once)");
  }
}

/// The session's cameras (a 525-pixel focal length at 640 wide, depth registered to colour, millimetres), its
/// marker, the fisheye and the ground truth.
capture::SessionManifest sessionManifest(const SynthOptions& o, const TabletopConfig& tc,
                                         const nlohmann::json& groundTruth) {
  capture::SessionManifest m;
  const double f = 525.0 * o.width / 640.0;
  m.colour = {o.width, o.height, f, f, (o.width - 1) / 2.0, (o.height - 1) / 2.0};
  m.depth = m.colour;
  m.depthUnitsMetres = 0.001;
  m.marker = capture::MarkerSpec{tc.tagFamily, tc.tagSize, tc.tagId};
  if (o.fisheyeEvery > 0) m.fisheye = tableFisheye();
  m.groundTruth = groundTruth;
  return m;
}

/// What the RGB-D sensor records of a render: the colour at `exposure` with its noise, the depth with the
/// sensor's noise model.
capture::RgbdFrame sensorFrame(const RgbdRender& r, const capture::Intrinsics& k, double exposure, uint64_t noiseSeed,
                               uint64_t depthSeed) {
  capture::RgbdFrame rgbd;
  rgbd.colour = cameraImage(exposure == 1.0 ? r.radiance : cv::Mat(r.radiance * exposure), noiseSeed);
  rgbd.exposure = exposure;
  rgbd.depth =
      capture::applyDepthNoise(r.depth, r.normals, k.fx, k.fy, k.cx, k.cy, capture::DepthNoiseModel{}, depthSeed);
  rgbd.colourIntrinsics = rgbd.depthIntrinsics = k;
  return rgbd;
}

/// What a frame's reference composite is rendered from: the room with the objects and without, the objects'
/// scene (for the focus box), the frame's path-tracing options, and the focus's samples per pixel (0: none).
struct ReferenceRender {
  const RayCaster& withObjects;
  const RayCaster& room;
  const groundtruth::Scene& augmented;
  groundtruth::PathTraceOptions options;
  int focusSpp = 0;
  double focusRadii = 3.0;  ///< the focus box: the objects' bounding sphere grown by this many radii
  bool pathTrace = true;
};

/// Writes frame i's reference composite (the camera image of the room with the objects, the frame's own
/// noise), real-pixel delta (half floats when focused) and mask into `dir`.
void writeReference(const ReferenceRender& ref, const groundtruth::PinholeCamera& cam, const cv::Mat& frameRadiance,
                    double exposure, uint64_t noiseSeed, const fs::path& dir, int i) {
  const cv::Mat mask = groundtruth::virtualMask(ref.withObjects, cam);
  cv::Mat rho, delta;
  if (ref.focusSpp > 0) {
    // The delta from its own pair of renders with more samples around the objects (common random
    // numbers in both); the composite is the frame's image plus that delta (the camera's noise kept).
    groundtruth::PathTraceOptions focused = ref.options;
    focused.focus = groundtruth::virtualFocus(ref.augmented, cam, ref.focusRadii);
    focused.focusSpp = ref.focusSpp;
    const cv::Mat rhoN = PathTracer(ref.withObjects, focused).render(cam);
    focused.progress = nullptr;
    const cv::Mat muN = PathTracer(ref.room, focused).render(cam);
    delta = rhoN - muN;
    rhoN.copyTo(delta, mask);
    rho = frameRadiance + delta;
    rhoN.copyTo(rho, mask);
  } else {
    rho = ref.pathTrace ? PathTracer(ref.withObjects, ref.options).render(cam) : frameRadiance;
    delta = rho - frameRadiance;
    rho.copyTo(delta, mask);
  }
  char name[64];
  fs::create_directories(dir);
  std::snprintf(name, sizeof name, "%06d.png", i);
  writePng((dir / name).string(), cameraImage(exposure == 1.0 ? rho : cv::Mat(rho * exposure), noiseSeed));
  std::snprintf(name, sizeof name, "delta_%06d.exr", i);
  writeExr((dir / name).string(), delta, ref.focusSpp > 0);
  std::snprintf(name, sizeof name, "mask_%06d.png", i);
  writePng((dir / name).string(), mask);
}

/// What the manifest says about how the frames and their references were rendered; returns whether the
/// references' deltas come from their own focused renders (path-traced frames with a scene and focus samples).
bool describeReference(const SynthOptions& o, nlohmann::json& groundTruth) {
  const bool pathTrace = o.render == "pathtrace";
  if (pathTrace) {
    groundTruth["scene"]["generator"] =
        "mrgi synth (path traced, " + std::to_string(o.spp) + " spp, " + std::to_string(o.bounces) + " bounces)";
    // The real-time stand-in for the bounce light the path tracer computes.
    groundTruth["scene"]["ambient_note"] =
        "ambient_radiance is a suggestion for real-time shading; the frames carry full global illumination";
  }
  if (!o.scene.empty())
    // Paths in the manifest are relative to the session directory.
    groundTruth["reference"] = {{"scene", fs::relative(fs::absolute(o.scene), fs::absolute(o.out)).generic_string()},
                                {"composite", "reference/NNNNNN.png"},
                                {"delta", "reference/delta_NNNNNN.exr"},
                                {"mask", "reference/mask_NNNNNN.png"},
                                {"note", "the camera image of the room with the scene's objects, same noise"}};
  // A reference delta of its own two renders, more samples around the objects (path-traced frames only).
  const bool focusedReference = !o.scene.empty() && o.referenceFocusSpp > 0 && pathTrace;
  if (focusedReference) {
    groundTruth["reference"]["delta_focus_spp"] = o.referenceFocusSpp;
    groundTruth["reference"]["delta_focus_radii"] = o.referenceFocusRadii;
    groundTruth["reference"]["note"] =
        "the camera image of the room with the scene's objects, same noise; the delta from its own two renders, " +
        std::to_string(o.referenceFocusSpp) + " samples per pixel within " +
        capture::formatNumber(o.referenceFocusRadii) + " radii of the objects (" + std::to_string(o.spp) +
        " elsewhere)";
  }
  return focusedReference;
}

}  // namespace

int writeSynthSession(const SynthOptions& o) {
  TabletopConfig tc;
  tc.tagId = o.tagId;
  tc.tagSize = o.tagSize;
  tc.seed = o.seed;
  tc.windowSun = o.windowSun;
  checkCombinations(o);
  if (!o.environment.empty()) {
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
  const bool focusedReference = describeReference(o, table.groundTruth);
  const RayCaster rc(table.scene);
  // --move-box: from frame `moveAt` on, the room is the same but for the box, moved to the front of the table.
  std::optional<Tabletop> movedTable;  // outlives its ray caster, which refers to its scene
  std::optional<RayCaster> moved;
  const int moveAt = (o.frames + o.scan) / 3;
  if (o.moveBox) {
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
  if (o.moveLight)
    table.groundTruth["scene"]["light_moves"] = {
        {"arc_deg", 120}, {"axis", "world y through the tag"}, {"note", "each frame's lights are in frames.jsonl"}};
  groundtruth::PathTraceOptions po;
  po.spp = o.spp;
  po.bounces = o.bounces;
  po.jitter = true;

  const capture::SessionManifest m = sessionManifest(o, tc, table.groundTruth);
  capture::SessionWriter writer(o.out, m);

  // The room is static: one fisheye image (a quarter of the samples) for every fisheye frame.
  const cv::Mat fisheye = m.fisheye ? renderFisheye(rc, pathTrace ? po : std::optional<groundtruth::PathTraceOptions>{},
                                                    std::max(4, o.spp / 4), *m.fisheye)
                                    : cv::Mat();
  std::optional<RayCaster> augmentedCaster;
  if (!o.scene.empty()) augmentedCaster.emplace(augmented);
  const auto bar = [&o](double fraction) {
    if (o.progress) o.progress(fraction);
  };
  const int total = o.frames + o.scan;
  for (int i = 0; i < total; ++i) {
    const bool scanning = i >= o.frames;
    writer.setColourJpegQuality(scanning ? o.scanJpegQuality : 0);
    capture::Frame frame;
    frame.index = i;
    frame.timestamp = i / 30.0;
    frame.groundTruthT_world_camera =
        scanning ? scanCamera(i - o.frames, o.scan, orbitCamera(o.staticCamera ? 0 : o.frames - 1, o.frames))
                 : orbitCamera(o.staticCamera ? 0 : i, o.frames);
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
    const uint64_t noiseSeed = o.seed * 7919 + static_cast<uint64_t>(i);
    capture::RgbdFrame rgbd = sensorFrame(r, m.colour, pickExposure(o.exposure, r.radiance), noiseSeed,
                                          o.seed * 104729 + static_cast<uint64_t>(i));
    const double exposure = rgbd.exposure;
    if (augmentedCaster && !scanning) {
      const RayCaster& withObjects = litAugmentedRc ? *litAugmentedRc : *augmentedCaster;
      groundtruth::PathTraceOptions rhoOptions = po;
      rhoOptions.progress = [&bar, i, total](double x) { bar((i + 0.5 + 0.5 * x) / total); };
      const ReferenceRender ref{withObjects,
                                room,
                                litAugmented ? *litAugmented : augmented,
                                rhoOptions,
                                focusedReference ? o.referenceFocusSpp : 0,
                                o.referenceFocusRadii,
                                pathTrace};
      writeReference(ref, {m.colour, *frame.groundTruthT_world_camera}, r.radiance, exposure, noiseSeed,
                     fs::path(o.out) / "reference", i);
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
    bar(static_cast<double>(i + 1) / total);  // ray-cast frames report no progress of their own
  }
  return total;
}

}  // namespace mrgi::evaluation
