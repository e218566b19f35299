#include "app/window_ui.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <opencv2/imgproc.hpp>

#include "gl/glapi.h"
#include "gl/objects.h"

namespace mrgi::app {

cv::Size WindowUi::windowSize(int width, int height) {
  width = std::max(width, 1), height = std::max(height, 1);
  int zoom = std::max(1, static_cast<int>(std::lround(640.0 / width)));
  while (height * zoom < 480 && zoom < 16) ++zoom;
  return {width * zoom + kPanelWidth, height * zoom + kCaptionHeight};
}

WindowUi::WindowUi(gl::Context& context) : context_(context) {
  auto* window = static_cast<GLFWwindow*>(context.nativeWindow());
  if (!window) throw std::runtime_error("the interactive window needs --gl window");
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini next to the user's files
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForOpenGL(window, true);
  ImGui_ImplOpenGL3_Init("#version 450");
}

WindowUi::~WindowUi() {
  if (texture_) glDeleteTextures(1, &texture_);
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
}

bool WindowUi::beginFrame() {
  if (!context_.pollEvents()) return false;
  auto* window = static_cast<GLFWwindow*>(context_.nativeWindow());
  if (glfwGetKey(window, GLFW_KEY_ESCAPE) == GLFW_PRESS) return false;
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  return true;
}

void WindowUi::showImage(const cv::Mat& image, const std::string& caption) {
  if (!image.empty()) {
    cv::Mat rgba;
    if (image.channels() == 1)
      cv::cvtColor(image, rgba, cv::COLOR_GRAY2RGBA);
    else
      cv::cvtColor(image, rgba, cv::COLOR_RGB2RGBA);
    if (!texture_ || textureWidth_ != rgba.cols || textureHeight_ != rgba.rows) {
      if (texture_) glDeleteTextures(1, &texture_);
      glCreateTextures(GL_TEXTURE_2D, 1, &texture_);
      glTextureStorage2D(texture_, 1, GL_RGBA8, rgba.cols, rgba.rows);
      glTextureParameteri(texture_, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
      glTextureParameteri(texture_, GL_TEXTURE_MAG_FILTER, GL_NEAREST);  // integer zoom shows whole pixels
      textureWidth_ = rgba.cols, textureHeight_ = rgba.rows;
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTextureSubImage2D(texture_, 0, 0, 0, rgba.cols, rgba.rows, GL_RGBA, GL_UNSIGNED_BYTE, rgba.ptr());
  }
  showTexture(image.empty() ? 0 : texture_, image.cols, image.rows, caption);
}

void WindowUi::showTexture(unsigned texture, int width, int height, const std::string& caption,
                           const std::vector<Line>& lines) {
  const ImGuiViewport* vp = ImGui::GetMainViewport();
  const float viewW = vp->Size.x - kPanelWidth, viewH = vp->Size.y;
  ImGui::SetNextWindowPos(vp->Pos);
  ImGui::SetNextWindowSize(ImVec2(viewW, viewH));
  ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(0, 0));
  ImGui::PushStyleVar(ImGuiStyleVar_WindowBorderSize, 0.0f);
  ImGui::Begin("##view", nullptr,
               ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoBringToFrontOnFocus |
                   ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoBackground);
  if (texture && width > 0 && height > 0) {
    // Largest integer zoom that fits (fractional when the image is larger than the view).
    float zoom = std::min(viewW / static_cast<float>(width),
                          (viewH - static_cast<float>(kCaptionHeight)) / static_cast<float>(height));
    if (zoom >= 1.f) zoom = std::floor(zoom);
    const ImVec2 size(width * zoom, height * zoom);
    ImGui::SetCursorPos(ImVec2(0, 0));
    const ImVec2 at = ImGui::GetCursorScreenPos();
    ImGui::Image(reinterpret_cast<ImTextureID>(static_cast<intptr_t>(texture)), size);
    ImDrawList* draw = ImGui::GetWindowDrawList();
    for (const Line& l : lines)  // pixel centres at +0.5
      draw->AddLine(ImVec2(at.x + (l.ends[0] + 0.5f) * zoom, at.y + (l.ends[1] + 0.5f) * zoom),
                    ImVec2(at.x + (l.ends[2] + 0.5f) * zoom, at.y + (l.ends[3] + 0.5f) * zoom),
                    IM_COL32(l.rgb[0], l.rgb[1], l.rgb[2], 255), 2.0f);
  }
  ImGui::SetCursorPos(ImVec2(6, viewH - 20));
  ImGui::TextUnformatted(caption.c_str());
  ImGui::End();
  ImGui::PopStyleVar(2);
}

void WindowUi::beginPanel(const std::string& title) {
  const ImGuiViewport* vp = ImGui::GetMainViewport();
  ImGui::SetNextWindowPos(ImVec2(vp->Pos.x + vp->Size.x - kPanelWidth, vp->Pos.y));
  ImGui::SetNextWindowSize(ImVec2(kPanelWidth, vp->Size.y));
  ImGui::Begin(title.c_str(), nullptr,
               ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoSavedSettings);
  ImGui::PushItemWidth(kPanelWidth * 0.5f);  // room for the labels
}

void WindowUi::endPanel() {
  ImGui::PopItemWidth();
  ImGui::End();
}

void WindowUi::endFrame(cv::Mat* screenshot) {
  ImGui::Render();
  const int w = context_.width(), h = context_.height();
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glViewport(0, 0, w, h);
  glClearColor(0.08f, 0.08f, 0.09f, 1.f);
  glClear(GL_COLOR_BUFFER_BIT);
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
  if (screenshot) {
    cv::Mat rgba(h, w, CV_8UC4);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.ptr());
    gl::countSynchronousReadback();
    cv::flip(rgba, rgba, 0);  // GL rows run bottom-up
    cv::cvtColor(rgba, *screenshot, cv::COLOR_RGBA2RGB);
  }
  context_.swapBuffers();
}

}  // namespace mrgi::app
