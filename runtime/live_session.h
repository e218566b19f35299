#pragma once
// The live demo's work without its window: the sensor (or a recording played in its place), the scene as the
// user edits it (technique, preset, knobs: the frame pipeline rebuilt on a change), each frame read, recorded
// when asked, prepared on a worker while GL renders the one before, and rendered; and the counts the window
// and the summary show. `mrgi live` draws it and its panel (app/cmd_live.cpp).
#include <chrono>
#include <future>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "capture/live_source.h"
#include "capture/session.h"
#include "compositor/compositor.h"
#include "gl/context.h"
#include "gl/profiler.h"
#include "runtime/frame_pipeline.h"
#include "runtime/session_setup.h"

namespace mrgi::runtime {

struct LiveSessionOptions {
  capture::LiveSourceOptions in;
  SceneChoice scene;  ///< empty scene file: the camera images only
  PoseMode pose = PoseMode::Tracked;
  RoomOptions rooms;
  std::shared_ptr<const reconstruction::RoomMesh> room;  ///< rooms.room, loaded
  std::string record;                                    ///< folder a recording goes into (empty: live-DATE-TIME)
  bool recordNow = false;                                ///< record from the first frame
};

class LiveSession {
 public:
  /// Opens the source and prepares the lighting (bad input stops here), then the GL context `contextFor(width,
  /// height)` describes for the source's image size, and the frame pipeline.
  LiveSession(const LiveSessionOptions& options,
              const std::function<std::unique_ptr<gl::Context>(int width, int height)>& contextFor);
  ~LiveSession();

  /// Works on the next frame: false at the end of a recording that does not loop (ended() then) or on a frame
  /// without RGB-D. `composite`: the composite is shown as the compositor's texture (nothing read back); `ahead`:
  /// the worker may read and prepare the frame after it meanwhile.
  bool advance(bool composite, bool ahead);
  /// Takes back the frame the worker is preparing (before anything reads the pipeline between frames).
  void join();
  /// Rebuilds the frame pipeline for the scene as edited (scene()); lights estimated from the last fisheye frame
  /// carry over.
  void rebuild();

  lighting::SceneDescription& scene() { return scene_; }  ///< edit, then rebuild()
  const SceneChoice& sceneChoice() const { return o_.scene; }
  FramePipeline& frames() { return *frames_; }
  compositor::Compositor& compositor() { return *compositor_; }
  gl::Context& context() { return *context_; }
  const capture::LiveSource& source() const { return *live_; }
  const std::optional<capture::Frame>& frame() const { return frame_; }
  FrameResult& result() { return result_; }
  const cv::Mat& lastFisheye() const { return lastFisheye_; }
  bool ended() const { return ended_; }
  int64_t processed() const { return processed_; }
  double frameMs() const { return frameMs_; }
  size_t lightCount() const { return lightCount_; }
  /// The share of the sphere of directions the room covers around the objects, as its lights were last
  /// estimated (negative: not lit from a room).
  double roomCoverage() const { return roomCoverage_; }
  const std::map<std::string, gl::StageTime>& stages() const { return stages_; }

  /// Recording: frames as they arrive (before registration) into a session; turning it off closes the session
  /// and readies the next folder. Returns what happened, for the status line.
  bool recording() const { return recording_; }
  std::string setRecording(bool on);
  const std::string& recordDir() const { return recordDir_; }
  int64_t framesRecorded() const { return recorder_ ? recorder_->framesWritten() : 0; }

  /// The window has shown the frame advance() last worked on (the throughput counts to here).
  void shown() { loopEnd_ = std::chrono::steady_clock::now(); }
  /// Ends the session: the fused room saved when asked; returns the summary (frames, poses, the window's size
  /// and renderer, throughput, the recording, the room; `screenshot`: the file written, if any).
  nlohmann::json finish(const std::string& screenshot);

 private:
  LiveSessionOptions o_;
  std::unique_ptr<capture::LiveSource> live_;
  std::optional<LightingSetup> base_;
  bool fuse_ = false;  ///< a room is fused as the frames come (--fuse-room, or the lights come from it)
  lighting::SceneDescription scene_;
  FrameOptions fo_;
  std::unique_ptr<gl::Context> context_;
  std::unique_ptr<compositor::Compositor> compositor_;
  std::unique_ptr<FramePipeline> frames_;
  gl::Profiler profiler_;
  std::future<FrameAhead> ahead_;
  std::optional<FrameAhead> pending_;  ///< a frame the worker delivered that the loop has not taken yet
  std::optional<capture::SessionWriter> recorder_;
  std::string recordDir_;
  bool recording_ = false, ended_ = false;
  std::optional<capture::Frame> frame_;
  FrameResult result_;
  cv::Mat lastFisheye_;
  std::map<std::string, gl::StageTime> stages_;
  double frameMs_ = 0, pipelineMs_ = 0;
  std::chrono::steady_clock::time_point loopStart_, loopEnd_;  ///< the first frame's start, the last frame's end
  int64_t processed_ = 0, preparedAhead_ = 0;
  size_t lightCount_ = 0;  ///< of the frame shown (the worker may be changing the setup's)
  double roomCoverage_ = -1;
  std::map<std::string, int64_t> posedBy_;  ///< frames by how they were posed (marker, odometry, ..., lost)
};

}  // namespace mrgi::runtime
