#pragma once
/// GL context backends. One binary carries all three; the backend is chosen at run time and every GL
/// entry point is resolved through that backend's get-proc-address (see gl/glapi.h).
#include <memory>
#include <string>
#include <string_view>

namespace mrgi::gl {

enum class Backend {
  OSMesa,  ///< headless software rendering (Mesa llvmpipe); the default, works on any machine
  Egl,     ///< headless on a GPU: EGL device platform, falling back to Mesa's surfaceless platform
  Window,  ///< a visible GLFW window (needs a display; under CI, Xvfb)
};

/// Parses "osmesa" | "egl" | "window"; throws std::invalid_argument naming the bad value.
Backend parseBackend(std::string_view name);
std::string_view backendName(Backend backend);

struct ContextConfig {
  Backend backend = Backend::OSMesa;
  int width = 640;  ///< default framebuffer size in pixels (window size for Backend::Window)
  int height = 480;
  std::string title = "mrgi";
  bool visible = true;       ///< Backend::Window only: false creates a hidden window
  bool debugOutput = false;  ///< enable KHR_debug messages on stderr
};

/// An OpenGL 4.5 core context, current on the creating thread. Move-only through unique_ptr.
class Context {
 public:
  virtual ~Context() = default;
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  virtual Backend backend() const = 0;
  virtual void makeCurrent() = 0;
  /// Presents the default framebuffer (window backend); a no-op headless.
  virtual void swapBuffers() {}
  /// Processes window events; returns false once the user asked to close the window.
  virtual bool pollEvents() { return true; }
  /// The window backend's GLFWwindow* (for UI toolkits); nullptr headless.
  virtual void* nativeWindow() const { return nullptr; }
  /// Default framebuffer size in pixels.
  virtual int width() const = 0;
  virtual int height() const = 0;

  /// GL_RENDERER / GL_VERSION strings of the live context, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  const std::string& renderer() const { return renderer_; }
  const std::string& version() const { return version_; }
  /// Extra backend detail (e.g. which EGL platform or device was used).
  const std::string& detail() const { return detail_; }

 protected:
  Context() = default;
  std::string renderer_, version_, detail_;
  friend std::unique_ptr<Context> createContext(const ContextConfig&);
};

/// Creates a context, makes it current and loads GL 4.5 core through the backend's get-proc-address.
/// Throws GlError with a one-line reason when the backend is unavailable (no display, no EGL device,
/// GL version below 4.5, missing entry points).
std::unique_ptr<Context> createContext(const ContextConfig& config);

}  // namespace mrgi::gl
