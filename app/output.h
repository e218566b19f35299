#pragma once
// What the subcommands write: atomic PNG/EXR files, output folders that never swallow a user's files,
// and a progress bar on the terminal.
#include <functional>
#include <memory>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

namespace mrgi::app {

/// Linear RGB float image -> EXR (atomically; errors name the file).
void writeExr(const std::string& path, const cv::Mat& rgb);
/// RGB8 or grey 8/16-bit image -> PNG (atomically).
void writePng(const std::string& path, const cv::Mat& rgb);
/// Creates the folder a file is about to be written into (nothing for a bare file name).
void createParentDirectory(const std::string& path);
/// Creates `out`, or accepts it when empty or holding an earlier output of this command: its `marker` file
/// (e.g. summary.json) is a JSON object whose "generated_by" is `generator` ("mrgi replay"). Refuses any
/// other folder, so that nothing the user had is overwritten.
void prepareOutputDirectory(const std::string& out, const std::string& marker, const std::string& generator);
/// A file name for inside an output folder: relative, no ".." (nothing written outside the folder).
void checkInsideOutput(const std::string& name, const std::string& flag);

/// "label [#####.....]  45%" on stderr, redrawn in place when stderr is a terminal (silent otherwise).
class ProgressBar {
 public:
  explicit ProgressBar(std::string label);
  ~ProgressBar();
  void operator()(double fraction);

 private:
  std::string label_;
  bool tty_;
  int shown_ = -1;
};

/// A progress reporter for long precomputes (lighting::PipelineConfig::progress): one ProgressBar per label,
/// shown while that precompute runs.
std::function<void(const std::string& what, double fraction)> precomputeProgress();

/// Ctrl-C (SIGINT) and SIGTERM while alive only raise a flag, so a long command stops between two complete
/// frames and still finishes its output (summary, video). A second Ctrl-C ends the process at once.
class InterruptGuard {
 public:
  InterruptGuard();
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;
  static bool interrupted();
};

/// An MP4 (MPEG-4 part 2 through OpenCV's VideoWriter) written to a temporary name and renamed into place
/// when closed, so the file at `path` is always a complete video.
class Mp4Writer {
 public:
  Mp4Writer(std::string path, int width, int height, double fps);
  ~Mp4Writer();
  void write(const cv::Mat& rgb);
  /// Finishes the file and moves it into place; returns the number of frames written.
  int close();

 private:
  std::string path_, partial_;
  cv::Ptr<cv::VideoWriter> writer_;
  int frames_ = 0;
};

}  // namespace mrgi::app
