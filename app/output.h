#pragma once
// What the subcommands write: atomic PNG/EXR files, output folders that never swallow a user's files,
// and a progress bar on the terminal.
#include <string>

#include <opencv2/core.hpp>

namespace mrgi::app {

/// Linear RGB float image -> EXR (atomically; errors name the file).
void writeExr(const std::string& path, const cv::Mat& rgb);
/// RGB8 or grey 8/16-bit image -> PNG (atomically).
void writePng(const std::string& path, const cv::Mat& rgb);
/// Creates the folder a file is about to be written into (nothing for a bare file name).
void createParentDirectory(const std::string& path);
/// Creates `out`, or accepts it when empty or holding an earlier output of this command (it contains
/// `marker`, e.g. summary.json); refuses any other folder so that nothing the user had is overwritten.
void prepareOutputDirectory(const std::string& out, const std::string& marker);

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

}  // namespace mrgi::app
