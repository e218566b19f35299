#pragma once
// `mrgi insert`'s work: a virtual object added to a scene file (or replacing one of its objects), placed
// relative to the marker (or the world a marker-less recording's first frame founded) on one measured frame of
// a recording — at a pixel's surface point, rested on the plane below it — previewed, and saved. The
// interactive window drives the same steps.
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "capture/frame_source.h"
#include "compositor/compositor.h"
#include "gl/context.h"
#include "runtime/frame_pipeline.h"

namespace mrgi::runtime {

struct InsertOptions {
  std::string session;        ///< the recording whose frame the object is placed on
  capture::OpenOptions open;  ///< a folder's calibration and depth scale
  std::string model;          ///< OBJ, PLY or glTF
  cv::Vec3d translate{0, 0, 0}, rotateDeg{0, 0, 0};
  double scale = 1.0;
  cv::Vec3d albedo{0.8, 0.8, 0.8};
  std::string scene;  ///< base scene (lights, technique, other objects); empty: `save` when it exists
  std::string room;   ///< mrgi room output: the real scene of the preview's lighting
  std::string save;   ///< the scene file written
  int replace = -1;   ///< the base scene's object replaced (-1: the object is appended)
  PoseMode pose = PoseMode::Tracked;
  int64_t frame = 0;  ///< the frame measured and previewed on
};

/// Which way is up when an object is rested on a plane.
struct SnapUp {
  enum class Kind { Camera, Marker, Given } kind = Kind::Camera;  ///< image up, the tag's normal, `given`
  cv::Vec3d given{0, 0, 1};                                       ///< marker frame
};

class Insertion {
 public:
  /// Reads the base scene and adds the object (bad input stops here, before anything is written), opens the GL
  /// context `contextFor(width, height)` describes for the recording's image size, and measures the frame.
  /// Throws when the frame has no camera pose.
  Insertion(const InsertOptions& options, const std::function<gl::ContextConfig(int width, int height)>& contextFor);
  /// Puts the object's origin on the surface seen at pixel (u, v). Throws when outside the image or without depth.
  /// Returns a note when the pixel has no depth and the nearest one with depth, at most kNearestDepthPixels
  /// away, stands in; throws when none is that near.
  std::optional<std::string> placeAtPixel(int u, int v);
  static constexpr int kNearestDepthPixels = 8;
  /// Rests the object (as placed so far in document()) on the plane below it, found in the frame's depth;
  /// returns why not when there is none.
  std::optional<std::string> snap(const SnapUp& up);
  /// The frame's composite with the scene as it is now (`scene`: the document, re-read when edited).
  cv::Mat render(const std::optional<nlohmann::json>& scene = std::nullopt);
  /// Writes document() to the save file (atomically).
  void save() const;

  nlohmann::json& document() { return doc_; }  ///< the scene file being written
  size_t index() const { return index_; }      ///< the object's index in it
  /// What was done: scene, object, pose, the plane rested on, and the placement as the document has it now.
  nlohmann::json report() const;
  gl::Context& context() { return *context_; }
  const capture::Frame& frame() const { return *frame_; }
  const FrameResult& measured() const { return result_; }
  const LightingSetup& setup() const { return *frames_->setup(); }
  const std::string& savePath() const { return savePath_; }  ///< absolute

 private:
  InsertOptions o_;
  std::unique_ptr<capture::FrameSource> source_;
  nlohmann::json doc_;
  nlohmann::json facts_;  ///< report()'s own part: scene, object, pose, plane
  size_t index_ = 0;
  std::string savePath_;
  lighting::SceneDescription scene_;
  FrameOptions frameOptions_;
  std::unique_ptr<gl::Context> context_;
  std::unique_ptr<compositor::Compositor> compositor_;
  std::unique_ptr<FramePipeline> frames_;
  std::optional<capture::Frame> frame_;
  FrameResult result_;
};

}  // namespace mrgi::runtime
