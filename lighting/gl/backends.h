#pragma once
// Internal to mrgi_gl: backend constructors. These files include platform headers (osmesa.h pulls in the
// system GL header), so they never see gl/glapi.h; context.cpp joins them with the loader.
#include <memory>

#include "gl/context.h"

namespace mrgi::gl::detail {

using ProcAddress = void* (*)(const char*);

struct BackendContext : Context {
  virtual ProcAddress procAddress() const = 0;
};

std::unique_ptr<BackendContext> createOsmesa(const ContextConfig& config);
std::unique_ptr<BackendContext> createEgl(const ContextConfig& config);
std::unique_ptr<BackendContext> createGlfw(const ContextConfig& config);

}  // namespace mrgi::gl::detail
