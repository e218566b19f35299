#pragma once
/// Registry of GLSL sources embedded into the binary at build time (cmake/MrgiShaders.cmake).
/// Names are paths relative to the source root, e.g. "compositor/composite.frag".
#include <map>
#include <string>
#include <string_view>

namespace mrgi::gl {

struct ShaderRegistration {
  ShaderRegistration(const char* name, const char* text);
};

/// Registers a source at run time (tests); replaces an existing entry of the same name.
void registerShaderSource(std::string name, std::string text);
/// The embedded text of name; throws GlError("shader 'name' is not embedded") if unknown.
const std::string& shaderSource(std::string_view name);
bool hasShaderSource(std::string_view name);

}  // namespace mrgi::gl
