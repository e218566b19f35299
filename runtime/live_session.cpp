#include "runtime/live_session.h"

#include <ctime>

#include "capture/error.h"
#include "runtime/output.h"
#include "runtime/room_fusion.h"
#include "runtime/threads.h"

using nlohmann::json;

namespace mrgi::runtime {
namespace {

std::string defaultRecordDir() {
  char buf[64];
  const std::time_t t = std::time(nullptr);
  std::strftime(buf, sizeof buf, "live-%Y%m%d-%H%M%S", std::localtime(&t));
  return buf;
}

}  // namespace

LiveSession::LiveSession(const LiveSessionOptions& o,
                         const std::function<std::unique_ptr<gl::Context>(int, int)>& contextFor)
    : o_(o), live_(std::make_unique<capture::LiveSource>(o.in)) {
  const int width = live_->info().colourIntrinsics.width, height = live_->info().colourIntrinsics.height;
  if (!o.scene.scene.empty()) {
    scene_ = loadChosenScene(o.scene);
    if (scene_.lightSource == lighting::LightSource::Fisheye && o.in.source.empty()) {
      // Live: the lights come from the V4L2 fisheye camera, not from a session manifest.
      if (o.in.fisheye.empty())
        throw capture::CaptureError(o.scene.scene, "lights: \"fisheye\" needs --fisheye /dev/videoN live");
      scene_.lightSource = lighting::LightSource::Scene;
      base_ = prepareLighting(scene_, o.scene.scene, *live_, live_->name(), o.pose);
      base_->fisheye = live_->fisheyeCalibration();
      if (!base_->fisheye) throw capture::CaptureError(o.in.fisheye, "delivered no fisheye frame");
      base_->scene.ambientFromManifest = false;
    } else {
      base_ = prepareLighting(scene_, o.scene.scene, *live_, live_->name(), o.pose, o.rooms.any());
    }
    // The scene as resolved against the source (where its lights come from: "auto" is the room's here as in
    // replay and insert): the panel edits this one, and each rebuild starts from it.
    scene_ = base_->scene;
  }
  // A recording played in the window is lit as replay lights it: by the room of all its frames, fused first. A
  // sensor's room grows as the frames come (and so do its lights).
  std::shared_ptr<const reconstruction::RoomMesh> room = o.room;
  bool fusedFirst = false;
  if (base_ && !o.in.source.empty() && fusesRecordingFirst(*base_, o.rooms, room != nullptr)) {
    live_.reset();  // the fusion reads the recording itself (a device's recording plays once at a time)
    room = fuseWholeRecording(o.in.source, o.pose, {});
    base_->lightsFromFusedRoom = false;
    fusedFirst = true;
    live_ = std::make_unique<capture::LiveSource>(o.in);
  }
  context_ = contextFor(width, height);
  compositor_ = std::make_unique<compositor::Compositor>(width, height);
  fo_.pose = o.pose;
  fo_.foundWorldAnew = true;  // a scene placed in a recording's first-frame world is placed in this camera's first
  fo_.room = room;
  fo_.cacheDir = o.rooms.room;  // techniques keep what they precompute beside the saved room
  fo_.progress = precomputeProgress();
  fuse_ = !fusedFirst && (o.rooms.fuse || (base_ && base_->lightsFromFusedRoom));
  if (fuse_) fo_.fuse = std::make_shared<reconstruction::RoomModel>();  // kept across rebuilds
  fo_.fuseRefresh = o.rooms.fuseRefresh;
  fo_.fuseEvery = o.rooms.fuseEvery;
  fo_.trackFusedRoom = o.rooms.track;
  fo_.techniqueStats = false;  // the window shows none: nothing of them is read back
  recordDir_ = o.record.empty() ? defaultRecordDir() : o.record;
  recording_ = o.recordNow;
  rebuild();
}

LiveSession::~LiveSession() {
  try {
    join();  // the worker reads the source and the pipeline: it finishes before they go
  } catch (...) {
  }
}

void LiveSession::join() {
  if (ahead_.valid()) pending_ = ahead_.get();
}

void LiveSession::rebuild() {
  join();
  std::optional<LightingSetup> s = base_;
  if (s) s->scene = scene_;
  // Lights and ambient estimated from the last fisheye frame carry over (the next one may be many frames away).
  if (s && frames_ && frames_->setup()) {
    s->lights = frames_->setup()->lights;
    s->ambient = frames_->setup()->ambient;
    s->ambientSh = frames_->setup()->ambientSh;
  }
  const capture::Intrinsics& k = live_->info().colourIntrinsics;
  frames_ = std::make_unique<FramePipeline>(std::move(s), k.width, k.height, fo_);
  if (pending_) pending_->prepared.reset();  // prepared by the pipeline just replaced: worked on again
}

bool LiveSession::advance(bool composite, bool ahead) {
  // While the composite view plays, frame n + 1 is read and prepared (marker, depth filter, albedo, real mesh
  // and the techniques' own inputs, or its fusion into the room: FramePipeline::prepare) on a worker while GL
  // renders frame n. The other views read the pipeline between frames: there frames are worked on in the loop.
  ahead = ahead && composite;
  join();
  FrameAhead next;
  if (pending_) {
    next = std::move(*pending_);
    pending_.reset();
  } else {
    next.frame = live_->next();
  }
  if (!next.frame) {
    ended_ = true;
    return false;
  }
  if (!next.frame->rgbd) return false;
  if (recording_) {
    const capture::Frame& arrived = next.arrived ? *next.arrived : *next.frame;  // before registration
    if (!recorder_) recorder_.emplace(recordDir_, capture::manifestFor(*live_, arrived));
    recorder_->append(arrived);
  }
  frame_ = std::move(next.frame);
  // The composite view shows the compositor's texture as it is: nothing is read back. Every other view reads
  // what it shows.
  compositor_->setReadback(composite ? compositor::Compositor::Readback::None : compositor::Compositor::Readback::Now);
  const auto t0 = std::chrono::steady_clock::now();
  if (processed_ == 0) loopStart_ = t0;
  if (next.stages) profiler_.adopt(*next.stages);
  if (next.prepared) ++preparedAhead_;
  std::optional<PreparedFrame> prepared = std::move(next.prepared);
  if (!prepared) prepared = frames_->prepare(*frame_, profiler_);  // before the worker's next
  if (ahead) ahead_ = readAhead([this] { return live_->next(); }, frames_.get());
  if (prepared) {
    frames_->render(*frame_, *prepared, *compositor_, profiler_);
    lightCount_ = prepared->lights.size();
    result_ = std::move(prepared->result);
  } else {
    result_ = frames_->process(*frame_, *compositor_, profiler_);
    lightCount_ = frames_->setup() ? frames_->setup()->lights.size() : 0;
  }
  // Lights from the room see what it covers around the objects: the share, as last estimated, for the panel.
  if (const auto room = result_.info.find("room");
      room != result_.info.end() && room->contains("lights") && (*room)["lights"].contains("coverage"))
    roomCoverage_ = (*room)["lights"]["coverage"].get<double>();
  frameMs_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  pipelineMs_ += frameMs_;
  // Stage times a frame late, when their GPU timestamps have arrived (the loop never waits for them).
  profiler_.endFrame();
  for (auto& t : profiler_.collect(false)) stages_ = std::move(t.stages);
  if (frame_->fisheye) lastFisheye_ = frame_->fisheye->image;
  ++processed_;
  if (frames_->setup()) ++posedBy_[result_.pose.tracked() ? toString(result_.pose.by) : "lost"];
  return true;
}

std::string LiveSession::setRecording(bool on) {
  if (on || !recorder_) {
    recording_ = on;
    return {};
  }
  recording_ = false;
  const std::string said = "recorded " + std::to_string(recorder_->framesWritten()) + " frames into " + recordDir_;
  recorder_.reset();
  recordDir_ = o_.record.empty() ? defaultRecordDir() : o_.record + "-" + std::to_string(processed_);
  return said;
}

json LiveSession::finish(const std::string& screenshot) {
  join();
  json summary = {{"source", live_->name()},
                  {"frames", processed_},
                  {"pose", {{"mode", toString(o_.pose)}, {"frames", posedBy_}}},
                  {"window", {context_->width(), context_->height()}},
                  {"lights", lightCount_},  // in force at the last frame shown
                  {"renderer", context_->renderer()},
                  {"process", processSettingsInEffect()}};  // how it took its cores and memory
  // Throughput of the window loop (frame, UI and swap; no writes), from the first frame's start to the last's
  // end, and the mean time of the frame pipeline alone within it.
  if (processed_ > 0) {
    const double wallMs = std::chrono::duration<double, std::milli>(loopEnd_ - loopStart_).count();
    summary["wall_ms_per_frame"] = wallMs / static_cast<double>(processed_);
    summary["fps"] = wallMs > 0 ? 1e3 * static_cast<double>(processed_) / wallMs : 0.0;
    summary["pipeline_ms_per_frame"] = pipelineMs_ / static_cast<double>(processed_);
    summary["prepared_ahead"] = preparedAhead_;
  }
  if (roomCoverage_ >= 0) summary["room_coverage"] = roomCoverage_;
  if (!screenshot.empty()) summary["screenshot"] = screenshot;
  if (recorder_) summary["recorded"] = {{"session", recordDir_}, {"frames", recorder_->framesWritten()}};
  if (fo_.fuse) {
    if (frames_) frames_->finishFusion();  // the frames handed to its fusion thread are in the room
    summary["room"] = {{"integrated", fo_.fuse->framesIntegrated()},
                       {"refused", fo_.fuse->framesRefused()},
                       {"blocks", fo_.fuse->blocks()}};
    if (!o_.rooms.save.empty() && fo_.fuse->framesIntegrated() > 0 &&
        !saveRoomModel(o_.rooms.save, *fo_.fuse, live_->name()).positions.empty())
      summary["room"]["saved"] = o_.rooms.save;
  }
  return summary;
}

}  // namespace mrgi::runtime
