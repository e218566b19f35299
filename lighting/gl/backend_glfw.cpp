#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <string>

#include "gl/backends.h"
#include "gl/error.h"

namespace mrgi::gl::detail {
namespace {

void* glfwProc(const char* name) { return reinterpret_cast<void*>(glfwGetProcAddress(name)); }

std::string lastGlfwError() {
  const char* description = nullptr;
  glfwGetError(&description);
  return description ? description : "unknown GLFW error";
}

class GlfwContext final : public BackendContext {
 public:
  explicit GlfwContext(const ContextConfig& config) {
    if (!glfwInit()) throw GlError("window: cannot open a window (" + lastGlfwError() + "); use --gl osmesa");
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_VISIBLE, config.visible ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    window_ = glfwCreateWindow(config.width, config.height, config.title.c_str(), nullptr, nullptr);
    if (!window_) {
      const std::string why = lastGlfwError();
      glfwTerminate();
      throw GlError("window: cannot create a GL 4.5 core window (" + why + ")");
    }
    makeCurrent();
    glfwSwapInterval(0);
    detail_ = std::string("GLFW ") + glfwGetVersionString();
  }
  ~GlfwContext() override {
    glfwDestroyWindow(window_);
    glfwTerminate();
  }

  Backend backend() const override { return Backend::Window; }
  void makeCurrent() override { glfwMakeContextCurrent(window_); }
  void swapBuffers() override { glfwSwapBuffers(window_); }
  bool pollEvents() override {
    glfwPollEvents();
    return !glfwWindowShouldClose(window_);
  }
  int width() const override {
    int w = 0, h = 0;
    glfwGetFramebufferSize(window_, &w, &h);
    return w;
  }
  int height() const override {
    int w = 0, h = 0;
    glfwGetFramebufferSize(window_, &w, &h);
    return h;
  }
  ProcAddress procAddress() const override { return &glfwProc; }
  void* nativeWindow() const override { return window_; }

 private:
  GLFWwindow* window_ = nullptr;
};

}  // namespace

std::unique_ptr<BackendContext> createGlfw(const ContextConfig& config) {
  return std::make_unique<GlfwContext>(config);
}

}  // namespace mrgi::gl::detail
