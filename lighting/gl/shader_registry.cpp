#include "gl/shader_registry.h"

#include "gl/error.h"

namespace mrgi::gl {
namespace {
std::map<std::string, std::string, std::less<>>& registry() {
  static std::map<std::string, std::string, std::less<>> r;  // constructed on first use: safe at static init
  return r;
}
}  // namespace

ShaderRegistration::ShaderRegistration(const char* name, const char* text) { registry()[name] = text; }

void registerShaderSource(std::string name, std::string text) { registry()[std::move(name)] = std::move(text); }

const std::string& shaderSource(std::string_view name) {
  auto it = registry().find(name);
  if (it == registry().end()) throw GlError("shader '" + std::string(name) + "' is not embedded in this binary");
  return it->second;
}

bool hasShaderSource(std::string_view name) { return registry().count(name) != 0; }

}  // namespace mrgi::gl
