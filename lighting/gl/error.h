#pragma once
#include <stdexcept>
#include <string>

namespace mrgi::gl {

/// A GL failure the user can see: backend unavailable, shader compile/link error, incomplete framebuffer.
class GlError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Throws GlError("<where>: GL error 0x...") if glGetError reports one. For bugs, not user input.
void checkGlError(const char* where);

}  // namespace mrgi::gl
