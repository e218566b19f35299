#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/commands.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/registration.h"
#include "compositor/compositor.h"
#include "gl/context.h"
#include "capture/session.h"
#include "lighting/debug_views.h"
#include "lighting/pipeline.h"
#include "lighting/scene_file.h"
#include "reconstruction/albedo.h"
#include "reconstruction/depth.h"
#include "reconstruction/depth_filter.h"
#include "reconstruction/light_estimation.h"
#include "reconstruction/marker.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::app {
namespace {

struct ReplayOptions {
  std::string source;
  std::string out;
  int frames = 0;
  std::string gl = "osmesa";
  std::string scene;
  std::string technique;  // empty: the scene file's
  bool dumpDelta = false;
  bool debug = false;
  std::string pose = "marker";
  int meshStride = 2;
};

/// What the lighting path needs besides the frames: the scene, the marker and the lights.
struct LightingSetup {
  lighting::SceneDescription scene;
  std::string tagFamily = "tag36h11";
  double tagSize = 0.16;
  int tagId = -1;
  std::vector<lighting::SceneLight> lights;  ///< marker frame
  cv::Vec3d ambient{0, 0, 0};
  std::optional<capture::Pose> T_world_marker;  ///< ground truth, for --pose ground-truth
  std::optional<capture::FisheyeCalibration> fisheye;  ///< lights estimated per fisheye frame
};

LightingSetup prepareLighting(const ReplayOptions& o, const capture::FrameSource& source) {
  LightingSetup setup;
  setup.scene = lighting::loadScene(o.scene);
  if (!o.technique.empty()) setup.scene.technique = lighting::parseTechnique(o.technique);
  const auto* session = dynamic_cast<const capture::SessionSource*>(&source);
  const json* gt = session && session->manifest().groundTruth.is_object() ? &session->manifest().groundTruth : nullptr;
  if (session && session->manifest().marker) {
    setup.tagFamily = session->manifest().marker->family;
    setup.tagSize = session->manifest().marker->sizeMetres;
    setup.tagId = session->manifest().marker->id;
  }
  if (gt && gt->contains("T_world_marker"))
    setup.T_world_marker = capture::poseFromJson((*gt)["T_world_marker"], o.source, "ground_truth.T_world_marker");
  if (setup.scene.lightSource == lighting::LightSource::Scene) {
    setup.lights = setup.scene.lights;
  } else if (setup.scene.lightSource == lighting::LightSource::Fisheye) {
    if (!session || !session->manifest().fisheye)
      throw capture::CaptureError(o.scene, "lights: \"fisheye\" but " + o.source + " has no fisheye calibration");
    setup.fisheye = session->manifest().fisheye;
    // Lights come from the environment image, which already holds all the room's light: no extra ambient.
    setup.scene.ambientFromManifest = false;
  } else {
    if (!gt || !gt->contains("lights") || !setup.T_world_marker)
      throw capture::CaptureError(o.scene, "lights: \"manifest\" but " + o.source +
                                               " has no ground-truth lights; list the lights in the scene file");
    const capture::Pose T_marker_world = capture::inversePose(*setup.T_world_marker);
    for (const json& l : (*gt)["lights"]) {
      if (l.value("type", "") != "point") continue;
      lighting::SceneLight s;
      s.type = lighting::LightType::Point;
      const auto p = l.at("position"), i = l.at("intensity_w_sr");
      s.position = capture::transformPoint(T_marker_world, {p[0].get<double>(), p[1].get<double>(), p[2].get<double>()});
      s.intensity = {i[0].get<double>(), i[1].get<double>(), i[2].get<double>()};
      setup.lights.push_back(s);
    }
  }
  setup.ambient = setup.scene.ambientRadiance;
  if (setup.scene.ambientFromManifest && gt && gt->contains("scene") && (*gt)["scene"].contains("ambient_radiance")) {
    const auto a = (*gt)["scene"]["ambient_radiance"];
    setup.ambient = {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
  }
  if (o.pose == "ground-truth" && !setup.T_world_marker)
    throw capture::CaptureError(o.source, "--pose ground-truth needs ground_truth.T_world_marker in the manifest");
  return setup;
}

void writeExr(const std::string& path, const cv::Mat& rgb) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<uchar> bytes;
  if (!cv::imencode(".exr", bgr, bytes)) throw capture::CaptureError(path, "cannot encode EXR");
  capture::writeFileAtomically(path, bytes);
}

/// Refuses to write into a folder holding anything but an earlier replay's output.
void prepareOutputDirectory(const std::string& out) {
  std::error_code ec;
  if (fs::exists(out, ec)) {
    if (!fs::is_directory(out, ec)) throw capture::CaptureError(out, "exists and is not a directory");
    if (!fs::is_empty(out, ec) && !fs::exists(fs::path(out) / "summary.json", ec))
      throw capture::CaptureError(out, "is not empty and holds no earlier mrgi output; refusing to overwrite");
  }
  fs::create_directories(out, ec);
  if (ec) throw capture::CaptureError(out, "cannot create output directory: " + ec.message());
}

void writePng(const std::string& path, const cv::Mat& rgb) {
  capture::writeFileAtomically(path, capture::encodePng(rgb, path));
}

int runReplay(const ReplayOptions& o) {
  const gl::Backend backend = gl::parseBackend(o.gl);
  auto source = capture::open(o.source);
  const capture::SourceInfo& info = source->info();
  if (!info.hasRgbd) throw capture::CaptureError(o.source, "has no RGB-D frames to replay");
  const int width = info.colourIntrinsics.width, height = info.colourIntrinsics.height;
  // A bad scene file stops here, before anything is written.
  std::optional<LightingSetup> setup;
  if (!o.scene.empty()) setup = prepareLighting(o, *source);
  prepareOutputDirectory(o.out);

  gl::ContextConfig cfg;
  cfg.backend = backend;
  cfg.width = width;
  cfg.height = height;
  cfg.title = "mrgi replay: " + o.source;
  auto context = gl::createContext(cfg);
  compositor::Compositor compositor(width, height);
  gl::Profiler profiler;

  std::unique_ptr<lighting::LightingPipeline> pipeline;
  std::optional<reconstruction::FisheyeRays> fisheyeRays;
  if (setup && setup->fisheye) fisheyeRays = reconstruction::fisheyeRays(*setup->fisheye);
  std::optional<reconstruction::TagDetector> detector;
  reconstruction::MarkerTrack track;
  if (setup) {
    lighting::PipelineConfig pc;
    pc.width = width;
    pc.height = height;
    pc.technique = setup->scene.technique;
    pc.lpv = setup->scene.lpv;
    pipeline = std::make_unique<lighting::LightingPipeline>(pc, setup->scene.objects);
    reconstruction::DetectorOptions dopt;
    dopt.family = setup->tagFamily;
    detector.emplace(dopt);
  }

  const int64_t total = info.frameCount ? *info.frameCount : -1;
  const int64_t limit = o.frames > 0 ? (total >= 0 ? std::min<int64_t>(o.frames, total) : o.frames) : total;
  json perFrame = json::array();
  std::map<std::string, std::pair<double, double>> sums;  // stage -> (cpu, gpu) ms
  int64_t done = 0;
  const auto start = std::chrono::steady_clock::now();
  while (limit < 0 || done < limit) {
    std::optional<capture::Frame> frame;
    {
      auto s = profiler.cpu("read");
      frame = source->next();
    }
    if (!frame) break;
    capture::RgbdFrame& rgbd = *frame->rgbd;
    if (!rgbd.depthRegistered) {
      auto s = profiler.cpu("register");
      capture::ensureRegistered(rgbd);
    }
    json frameInfo;
    cv::Mat composite;
    if (!pipeline) {
      {
        auto s = profiler.cpu("normals");
        reconstruction::computeNormals(reconstruction::backProject(rgbd.depth, rgbd.depthIntrinsics));
      }
      composite = compositor.composite(rgbd.colour, cv::Mat(), cv::Mat(), &profiler);
    } else {
      if (fisheyeRays && frame->fisheye) {
        // A new environment image: re-estimate the lights (skipped on frames without one).
        auto s = profiler.cpu("lights");
        reconstruction::MedianCutOptions mo;
        mo.count = setup->scene.fisheyeLightCount;
        mo.varianceSplit = true;
        auto lights = reconstruction::medianCut(reconstruction::linearRadiance(frame->fisheye->image), *fisheyeRays, mo);
        const capture::Pose T_world_fisheye = setup->fisheye->T_world_fisheye.value_or(capture::identityPose());
        const capture::Pose T_marker_world =
            setup->T_world_marker ? capture::inversePose(*setup->T_world_marker) : capture::identityPose();
        lights = reconstruction::lightsToWorld(lights, T_marker_world * T_world_fisheye);
        setup->lights.clear();
        for (const auto& l : lights) {
          lighting::SceneLight s;
          s.type = lighting::LightType::Directional;
          s.direction = -l.direction;  // from the light into the scene
          s.irradiance = l.power;
          setup->lights.push_back(s);
        }
        frameInfo["lights_estimated"] = setup->lights.size();
      }
      // Marker -> camera pose in the lighting world (the marker frame).
      std::optional<capture::Pose> T_marker_camera;
      if (o.pose == "ground-truth" && frame->groundTruthT_world_camera) {
        T_marker_camera = capture::inversePose(*setup->T_world_marker) * *frame->groundTruthT_world_camera;
        frameInfo["marker"] = "ground-truth";
      } else {
        auto s = profiler.cpu("marker");
        std::optional<capture::Pose> measured;
        for (const auto& d : detector->detect(rgbd.colour)) {
          if (setup->tagId >= 0 && d.id != setup->tagId) continue;
          auto pose = reconstruction::estimateTagPose(d, setup->tagSize, rgbd.colourIntrinsics, {}, track.lastMeasured());
          if (pose) {
            measured = pose->T_camera_tag;
            break;
          }
        }
        const auto status = track.update(frame->timestamp, measured);
        frameInfo["marker"] = reconstruction::toString(status);
        if (status != reconstruction::TrackStatus::Lost && track.pose()) T_marker_camera = capture::inversePose(*track.pose());
      }
      cv::Mat depth, positions, normals;
      {
        auto s = profiler.cpu("depth_filter");
        reconstruction::DepthFilterOptions fo;
        const cv::Mat guide = reconstruction::guideFromColour(rgbd.colour);
        depth = reconstruction::guidedFilterDepth(rgbd.depth, guide,
                                                  reconstruction::filterRadiusPixels(rgbd.depth, rgbd.colourIntrinsics, fo), fo);
      }
      {
        auto s = profiler.cpu("normals");
        positions = reconstruction::backProject(depth, rgbd.colourIntrinsics);
        normals = reconstruction::computeNormals(positions);
      }
      if (T_marker_camera) {
        const capture::Pose T_camera_marker = capture::inversePose(*T_marker_camera);
        cv::Mat albedo;
        {
          auto s = profiler.cpu("albedo");
          reconstruction::AlbedoLights al;
          for (const auto& l : setup->lights) {
            if (l.type == lighting::LightType::Directional) {
              reconstruction::EstimatedLight e;
              e.direction = -(capture::rotationOf(T_camera_marker) * l.direction);
              e.power = l.irradiance;
              al.distant.push_back(e);
            } else {
              al.points.push_back({capture::transformPoint(T_camera_marker, l.position), l.intensity});
            }
          }
          al.ambientIrradiance = CV_PI * setup->ambient;
          albedo = reconstruction::estimateAlbedo(rgbd.colour, positions, normals, rgbd.colourIntrinsics, al).albedo;
        }
        {
          auto s = profiler.cpu("mesh");
          const auto mesh = reconstruction::buildDepthMesh(positions, normals, o.meshStride);
          std::vector<lighting::MeshVertex> vertices;
          std::vector<uint32_t> indices;
          lighting::buildRealVertices(mesh, albedo, *T_marker_camera, vertices, indices);
          pipeline->setRealMesh(vertices, indices);
        }
        lighting::CameraView view;
        view.intrinsics = rgbd.colourIntrinsics;
        view.T_world_camera = *T_marker_camera;
        pipeline->run(view, setup->lights, setup->ambient, &profiler);
        composite = compositor.composite(rgbd.colour, pipeline->shade(), &profiler);
      } else {
        // Marker lost: nothing can be placed; the frame is the background.
        composite = compositor.composite(rgbd.colour, cv::Mat(), cv::Mat(), &profiler);
      }
      cv::Mat shade;  // read back once for both the debug views and the dump
      if ((o.debug || o.dumpDelta) && T_marker_camera) {
        auto s = profiler.cpu("readback");
        shade = pipeline->downloadShade();
      }
      if (o.debug && T_marker_camera) {
        auto s = profiler.cpu("debug");
        char prefix[32];
        std::snprintf(prefix, sizeof prefix, "debug_%04lld_", static_cast<long long>(done));
        const fs::path base = fs::path(o.out) / prefix;
        auto png = [&](const std::string& name, const cv::Mat& img) { writePng(base.string() + name + ".png", img); };
        double scale = 0;
        png("delta", lighting::signedImage(shade, scale));
        frameInfo["debug_delta_scale"] = scale;
        const cv::Mat albedo = pipeline->downloadGBuffer(2);
        png("gbuffer_albedo", lighting::linearImage(albedo));
        png("gbuffer_normal", lighting::normalImage(pipeline->downloadGBuffer(1)));
        cv::Mat mask;
        cv::extractChannel(albedo, mask, 3);
        mask.convertTo(mask, CV_8U, 255);
        png("gbuffer_mask", mask);
        const lighting::RsmTexels rsm = pipeline->downloadRsm(true);
        double rsmScale = 0;
        png("rsm_flux", lighting::signedImage(rsm.flux, rsmScale));
        png("rsm_normal", lighting::normalImage(rsm.normal));
        double volScale = 0;
        const auto vol = pipeline->downloadVolume(setup->scene.technique == lighting::Technique::Dlpv ? "delta" : "rho_full");
        png("dlpv_slices", lighting::volumeSlices(vol, 4, 4, volScale));
        frameInfo["debug_volume_scale"] = volScale;
      }
      if (o.dumpDelta) {
        auto s = profiler.cpu("dump");
        if (shade.empty()) shade = cv::Mat(height, width, CV_32FC4, cv::Scalar::all(0));
        cv::Mat delta(height, width, CV_32FC3), mask(height, width, CV_8UC1);
        for (int y = 0; y < height; ++y)
          for (int x = 0; x < width; ++x) {
            const cv::Vec4f v = shade.at<cv::Vec4f>(y, x);
            const bool virt = v[3] > 0.5f;
            delta.at<cv::Vec3f>(y, x) = virt ? cv::Vec3f(0, 0, 0) : cv::Vec3f(v[0], v[1], v[2]);
            mask.at<uchar>(y, x) = virt ? 255 : 0;
          }
        char name[32];
        std::snprintf(name, sizeof name, "delta_%04lld.exr", static_cast<long long>(done));
        writeExr((fs::path(o.out) / name).string(), delta);
        std::snprintf(name, sizeof name, "mask_%04lld.png", static_cast<long long>(done));
        writePng((fs::path(o.out) / name).string(), mask);
      }
    }
    if (context->backend() == gl::Backend::Window) {
      compositor.present(context->width(), context->height());
      context->swapBuffers();
      if (!context->pollEvents()) break;
    }
    {
      auto s = profiler.cpu("write");
      char name[32];
      std::snprintf(name, sizeof name, "frame_%04lld.png", static_cast<long long>(done));
      writePng((fs::path(o.out) / name).string(), composite);
    }
    json stages;
    std::string line;
    for (const auto& [name, t] : profiler.resolve()) {
      stages[name] = {{"cpu_ms", t.cpuMs}, {"gpu_ms", t.gpuMs}};
      sums[name].first += t.cpuMs;
      sums[name].second += t.gpuMs;
      char buf[64];
      std::snprintf(buf, sizeof buf, " %s %.1f", name.c_str(), std::max(t.cpuMs, t.gpuMs));
      line += buf;
    }
    json record = {{"frame", done}, {"index", frame->index}, {"t", frame->timestamp}, {"stages", stages}};
    for (const auto& [k, v] : frameInfo.items()) record[k] = v;
    perFrame.push_back(record);
    ++done;
    // Per-stage timings of every frame (ms; the larger of CPU wall and GPU time).
    std::printf("frame %lld/%lld:%s ms\n", static_cast<long long>(done), static_cast<long long>(limit),
                line.c_str());
    std::fflush(stdout);
  }
  if (done == 0) throw capture::CaptureError(o.source, "no frame could be replayed");
  const double wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  json summary;
  summary["source"] = o.source;
  summary["frames"] = done;
  summary["resolution"] = {width, height};
  summary["gl"] = {{"backend", std::string(gl::backendName(backend))},
                   {"renderer", context->renderer()},
                   {"version", context->version()},
                   {"detail", context->detail()}};
  json mean;
  for (const auto& [name, s] : sums) mean[name] = {{"cpu_ms", s.first / done}, {"gpu_ms", s.second / done}};
  summary["stages_ms"] = mean;
  if (setup) {
    summary["scene"] = o.scene;
    summary["technique"] = lighting::techniqueName(setup->scene.technique);
    const auto& k = setup->scene.lpv;
    summary["knobs"] = {{"resolution", k.resolution}, {"steps", k.steps}, {"rsm_size", k.rsmSize},
                        {"size_factor", k.sizeFactor}, {"damping", k.damping}, {"direct_steps", k.directSteps}};
    summary["lights"] = setup->lights.size();
  }
  summary["wall_ms_per_frame"] = wallMs / done;
  summary["per_frame"] = perFrame;
  const std::string summaryPath = (fs::path(o.out) / "summary.json").string();
  std::ofstream(summaryPath + ".tmp") << summary.dump(2) << "\n";
  fs::rename(summaryPath + ".tmp", summaryPath);
  std::printf("replayed %lld frames into %s (%.1f ms/frame)\n", static_cast<long long>(done), o.out.c_str(),
              wallMs / done);
  return 0;
}

}  // namespace

Action addReplay(CLI::App& app) {
  auto o = std::make_shared<ReplayOptions>();
  app.add_option("SESSION", o->source, "session directory, TUM directory or .oni file")->required();
  app.add_option("--out", o->out, "output folder for frame_NNNN.png and summary.json")->required();
  app.add_option("--frames", o->frames, "replay at most N frames (0 = all)")->check(CLI::NonNegativeNumber);
  app.add_option("--gl", o->gl, "GL backend: osmesa (headless, default), egl (headless GPU), window")
      ->check(CLI::IsMember({"osmesa", "egl", "window"}));
  app.add_option("--scene", o->scene, "scene file (JSON): virtual objects relative to the marker, lights, technique");
  app.add_option("--technique", o->technique, "lighting technique, overrides the scene file's")
      ->check(CLI::IsMember({"dlpv", "lpv-diff"}));
  app.add_flag("--dump-delta", o->dumpDelta, "also write delta_NNNN.exr (linear RGB added to real pixels) and mask_NNNN.png (255 = virtual)");
  app.add_flag("--debug", o->debug, "also write debug_NNNN_*.png: delta (red = negative), G-buffer albedo/normal/mask, "
                                     "RSM flux/normal of the last light, DLPV z-slices");
  app.add_option("--pose", o->pose, "camera pose from the tracked marker (default) or the session's ground truth")
      ->check(CLI::IsMember({"marker", "ground-truth"}));
  app.add_option("--mesh-stride", o->meshStride, "real-scene mesh over every N-th depth pixel")->check(CLI::Range(1, 16));
  return [o] { return runReplay(*o); };
}

}  // namespace mrgi::app
