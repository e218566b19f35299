#include "gl/context.h"

#include <stdexcept>
#include <string>

#include "gl/backends.h"
#include "gl/error.h"
#include "gl/glapi.h"

namespace mrgi::gl {

Backend parseBackend(std::string_view name) {
  if (name == "osmesa") return Backend::OSMesa;
  if (name == "egl") return Backend::Egl;
  if (name == "window") return Backend::Window;
  throw std::invalid_argument("unknown GL backend '" + std::string(name) + "' (expected osmesa, egl or window)");
}

std::string_view backendName(Backend backend) {
  switch (backend) {
    case Backend::OSMesa:
      return "osmesa";
    case Backend::Egl:
      return "egl";
    case Backend::Window:
      return "window";
  }
  return "?";
}

void checkGlError(const char* where) {
  const GLenum err = glGetError();
  if (err != GL_NO_ERROR) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "0x%04x", err);
    throw GlError(std::string(where) + ": GL error " + buf);
  }
}

namespace {
void APIENTRY debugCallback(GLenum, GLenum type, GLuint, GLenum severity, GLsizei, const GLchar* message, const void*) {
  if (severity == GL_DEBUG_SEVERITY_NOTIFICATION) return;
  std::fprintf(stderr, "GL debug (type 0x%x): %s\n", type, message);
}
}  // namespace

std::unique_ptr<Context> createContext(const ContextConfig& config) {
  if (config.width <= 0 || config.height <= 0)
    throw GlError("createContext(): size " + std::to_string(config.width) + "x" + std::to_string(config.height) +
                  " is not positive");
  std::unique_ptr<detail::BackendContext> ctx;
  switch (config.backend) {
    case Backend::OSMesa:
      ctx = detail::createOsmesa(config);
      break;
    case Backend::Egl:
      ctx = detail::createEgl(config);
      break;
    case Backend::Window:
      ctx = detail::createGlfw(config);
      break;
  }
  const std::string name(backendName(config.backend));
  const char* missing = nullptr;
  const auto proc = ctx->procAddress();
  // glGetString and glGetIntegerv exist in every version: read the version before judging the rest.
  loadGl(proc, &missing);
  if (!glGetString || !glGetIntegerv) throw GlError(name + ": cannot resolve basic GL entry points");
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  const char* version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  const char* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  if (major * 10 + minor < 45)
    throw GlError(name + ": GL 4.5 core required, the context offers " + (version ? version : "nothing"));
  if (missing) throw GlError(name + ": GL 4.5 entry point " + missing + " is missing");
  ctx->version_ = version ? version : "";
  ctx->renderer_ = renderer ? renderer : "";
  if (config.debugOutput) {
    glEnable(GL_DEBUG_OUTPUT);
    glDebugMessageCallback(debugCallback, nullptr);
  }
  return ctx;
}

}  // namespace mrgi::gl
