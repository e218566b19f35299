#include "evaluation/reference_frame.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "capture/colour.h"
#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/image_io.h"
#include "capture/session.h"
#include "compositor/compositor.h"
#include "evaluation/reference_scene.h"
#include "runtime/frame_pipeline.h"
#include "runtime/output.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace mrgi::evaluation {

using namespace mrgi::runtime;

int renderReferenceFrame(const ReferenceOptions& o) {
  auto source = capture::open(o.source);
  if (!source->info().hasRgbd) throw capture::CaptureError(o.source, "has no RGB-D frames");
  LightingSetup setup = prepareLighting(lighting::loadScene(o.scene), o.scene, *source, o.source, o.pose);

  FrameOptions fo;
  fo.pose = o.pose;
  fo.meshStride = o.meshStride;
  fo.gpu = false;
  const capture::Intrinsics& k0 = source->info().colourIntrinsics;
  FramePipeline frames(setup, k0.width, k0.height, fo);
  gl::Profiler profiler;
  // Odometry carries the pose from frame to frame: the frames before the chosen one are tracked too.
  const bool carried = o.pose == PoseMode::Odometry || o.pose == PoseMode::Tracked;
  std::optional<capture::Frame> frame;
  for (int i = 0; i <= o.frame; ++i) {
    frame = source->next();
    if (!frame)
      throw capture::CaptureError(
          o.source, "has no frame " + std::to_string(o.frame) + " (it ends after " + std::to_string(i) + ")");
    if (carried && i < o.frame && frame->rgbd) frames.measure(*frame, profiler);
  }
  if (!frame->rgbd) throw capture::CaptureError(o.source, "frame " + std::to_string(o.frame) + " has no RGB-D image");
  const capture::Intrinsics k = frame->rgbd->colourIntrinsics;
  const FrameResult r = frames.measure(*frame, profiler);
  if (!r.T_marker_camera)
    throw capture::CaptureError(o.source, "frame " + std::to_string(o.frame) + ": no camera pose (--pose " +
                                              std::string(toString(o.pose)) + "), nothing to place the objects on");
  // After every input check: nothing is created on error.
  const OutputClaim claim = prepareOutputDirectory(o.out, "reference.json", "mrgi reference");
  const RealSurface real = frames.realSurface(*frame, r, profiler);
  const ReferenceScenes scenes = reconstructedScenes(*frames.setup(), real, k, *r.T_marker_camera);

  groundtruth::PathTraceOptions po;
  po.spp = o.spp;
  po.bounces = o.bounces;
  po.seed = o.seed;
  po.threads = o.threads;
  ProgressBar bar("reference frame " + std::to_string(o.frame));
  po.progress = [&bar](double f) { bar(f); };
  const auto t0 = std::chrono::steady_clock::now();
  const auto images = groundtruth::renderDifferential(scenes.withObjects, scenes.realOnly, scenes.camera, po);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const cv::Mat delta = images.delta();

  const fs::path dir(o.out);
  writeExr((dir / "rho.exr").string(), images.rho);
  writeExr((dir / "mu.exr").string(), images.mu);
  writeExr((dir / "delta.exr").string(), delta);
  writePng((dir / "mask.png").string(), images.mask);
  writePng((dir / "composite.png").string(), compositor::compositeReference(frame->rgbd->colour, delta, images.mask));
  json info = {{"generated_by", "mrgi reference"},
               {"source", o.source},
               {"scene", o.scene},
               {"frame", o.frame},
               {"spp", o.spp},
               {"bounces", o.bounces},
               {"seed", o.seed},
               {"pose", toString(o.pose)},
               {"marker", r.info.value("marker", "")},
               {"triangles_real", real.indices.size() / 3},
               {"virtual_pixels", cv::countNonZero(images.mask)},
               {"ms", ms},
               {"T_marker_camera", capture::poseToJson(*r.T_marker_camera)}};
  capture::writeFileAtomically(dir / "reference.json", info.dump(2) + "\n");
  std::printf("reference of frame %d (%d spp, %d bounces) in %.1f s -> %s\n", o.frame, o.spp, o.bounces, ms / 1000,
              o.out.c_str());
  return 0;
}

}  // namespace mrgi::evaluation
