#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstring>
#include <string>
#include <vector>

#include "gl/backends.h"
#include "gl/error.h"

namespace mrgi::gl::detail {
namespace {

void* eglProc(const char* name) { return reinterpret_cast<void*>(eglGetProcAddress(name)); }

bool hasExtension(const char* list, const char* name) {
  if (!list) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)); p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

class EglContext final : public BackendContext {
 public:
  explicit EglContext(const ContextConfig& config) : width_(config.width), height_(config.height) {
    const char* clientExts = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    auto getPlatformDisplay =
        reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (!getPlatformDisplay) throw GlError("egl: eglGetPlatformDisplayEXT is not available");

    // 1. A real device (EGL_EXT_platform_device): a GPU without any display server.
    if (hasExtension(clientExts, "EGL_EXT_platform_device")) {
      auto queryDevices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
      auto queryDeviceString =
          reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
      EGLDeviceEXT devices[16];
      EGLint count = 0;
      if (queryDevices && queryDevices(16, devices, &count)) {
        // Prefer hardware devices; Mesa's software device advertises EGL_MESA_device_software.
        for (int pass = 0; pass < 2 && display_ == EGL_NO_DISPLAY; ++pass) {
          for (EGLint i = 0; i < count; ++i) {
            const char* devExts = queryDeviceString ? queryDeviceString(devices[i], EGL_EXTENSIONS) : nullptr;
            const bool software = hasExtension(devExts, "EGL_MESA_device_software");
            if (software != (pass == 1)) continue;
            EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
            if (d != EGL_NO_DISPLAY && tryDisplay(d)) {
              detail_ = "EGL device " + std::to_string(i) + (software ? " (software)" : "");
              break;
            }
          }
        }
      }
    }
    // 2. Mesa's surfaceless platform.
    if (display_ == EGL_NO_DISPLAY && hasExtension(clientExts, "EGL_MESA_platform_surfaceless")) {
      EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
      if (d != EGL_NO_DISPLAY && tryDisplay(d)) detail_ = "EGL surfaceless";
    }
    if (display_ == EGL_NO_DISPLAY)
      throw GlError("egl: no EGL device or surfaceless display offers a GL 4.5 core context");
  }
  ~EglContext() override {
    eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display_, context_);
    eglTerminate(display_);
  }

  Backend backend() const override { return Backend::Egl; }
  void makeCurrent() override {
    if (!eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_))
      throw GlError("egl: eglMakeCurrent failed");
  }
  int width() const override { return width_; }
  int height() const override { return height_; }
  ProcAddress procAddress() const override { return &eglProc; }

 private:
  bool tryDisplay(EGLDisplay d) {
    EGLint major = 0, minor = 0;
    if (!eglInitialize(d, &major, &minor)) return false;
    const char* exts = eglQueryString(d, EGL_EXTENSIONS);
    if (!hasExtension(exts, "EGL_KHR_surfaceless_context") || !eglBindAPI(EGL_OPENGL_API)) {
      eglTerminate(d);
      return false;
    }
    const EGLint configAttribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig cfg = nullptr;
    EGLint n = 0;
    const bool haveConfig = eglChooseConfig(d, configAttribs, &cfg, 1, &n) && n > 0;
    const EGLint ctxAttribs[] = {
        EGL_CONTEXT_MAJOR_VERSION,           4,       EGL_CONTEXT_MINOR_VERSION, 5, EGL_CONTEXT_OPENGL_PROFILE_MASK,
        EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    // EGL_KHR_no_config_context lets a surfaceless context exist without a config.
    EGLContext c = eglCreateContext(d, haveConfig ? cfg : EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, ctxAttribs);
    if (c == EGL_NO_CONTEXT) {
      eglTerminate(d);
      return false;
    }
    if (!eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, c)) {
      eglDestroyContext(d, c);
      eglTerminate(d);
      return false;
    }
    display_ = d;
    context_ = c;
    return true;
  }

  EGLDisplay display_ = EGL_NO_DISPLAY;
  EGLContext context_ = EGL_NO_CONTEXT;
  int width_, height_;
};

}  // namespace

std::unique_ptr<BackendContext> createEgl(const ContextConfig& config) { return std::make_unique<EglContext>(config); }

}  // namespace mrgi::gl::detail
