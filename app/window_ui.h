#pragma once
// The window the interactive commands (live, insert) share: Dear ImGui on the GLFW window backend, an
// image view on the left, a control panel on the right, and screenshots of what the window shows.
#include <opencv2/core.hpp>
#include <string>

#include "gl/context.h"

namespace mrgi::app {

class WindowUi {
 public:
  static constexpr int kPanelWidth = 360;
  static constexpr int kCaptionHeight = 24;  ///< the caption line under the image
  /// Window size for showing a width x height image at an integer zoom (the nearest to 640 px wide, raised
  /// until the image is at least 480 px tall) next to the panel: as tall as the image and its caption, so the
  /// window keeps the source's aspect with no band under the image (the panel scrolls when it is longer).
  static cv::Size windowSize(int width, int height);

  /// Needs a Backend::Window context (throws a one-line error otherwise).
  explicit WindowUi(gl::Context& context);
  ~WindowUi();
  WindowUi(const WindowUi&) = delete;
  WindowUi& operator=(const WindowUi&) = delete;

  /// Polls events and starts a UI frame; false once the user closed the window (or pressed Escape).
  bool beginFrame();
  /// Shows an RGB8 (or grey) image in the view area, scaled to fit with its aspect ratio kept.
  void showImage(const cv::Mat& image, const std::string& caption);
  /// The same for an RGBA texture already on the GPU (row 0 at the top), e.g. the compositor's output: nothing
  /// goes through the CPU.
  /// `lines`: segments to draw over it, in the texture's pixels (x0, y0, x1, y1) with their RGB colours.
  struct Line {
    cv::Vec4f ends;
    cv::Vec3b rgb;
  };
  void showTexture(unsigned texture, int width, int height, const std::string& caption,
                   const std::vector<Line>& lines = {});
  /// Opens the control panel (ImGui::Begin); close it with endPanel().
  void beginPanel(const std::string& title);
  void endPanel();
  /// Draws the UI and presents the frame; when `screenshot` is given, the window's pixels as presented
  /// (RGB8) are read back into it first.
  void endFrame(cv::Mat* screenshot = nullptr);

 private:
  gl::Context& context_;
  unsigned texture_ = 0;
  int textureWidth_ = 0, textureHeight_ = 0;
};

}  // namespace mrgi::app
