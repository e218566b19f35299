#pragma once
/// GLSL programs built from embedded shader files, with `#include "file"` and `#define` variants.
/// Compile and link errors are thrown as one line naming the shader file and line.
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "gl/glapi.h"
#include "gl/objects.h"

namespace mrgi::gl {

/// Preprocessor defines prepended after the #version line: {"NAME", "VALUE"} -> "#define NAME VALUE".
using Defines = std::vector<std::pair<std::string, std::string>>;

/// Result of resolving includes: the text handed to GL and, for each of its lines, where it came from.
/// (Drivers disagree on `#line` source-string numbers, so locations are mapped back through this table.)
struct PreprocessedSource {
  std::string text;
  std::vector<std::string> origins;  ///< origins[i] = "file:line" of text line i+1 ("<defines>" for injected)
};

/// Expands `#include "path"` (relative to the including file, then to the root) once per file and inserts
/// the defines after #version. Throws GlError on a missing include, a cycle or a missing #version line.
PreprocessedSource preprocessShader(const std::string& name, const Defines& defines);

/// Keeps the first error line of a driver log and rewrites its "0:12(3): " (Mesa) or "0(12) : " (NVIDIA)
/// location as the original "file:line: " through origins.
std::string mapShaderLog(const std::string& log, const std::vector<std::string>& origins);

class Program {
 public:
  Program() = default;
  /// A vertex + fragment program; names are registry names ("compositor/fullscreen.vert").
  static Program graphics(const std::string& vert, const std::string& frag, const Defines& defines = {});
  /// A vertex + geometry + fragment program.
  static Program graphics(const std::string& vert, const std::string& geom, const std::string& frag,
                          const Defines& defines = {});
  /// A compute program.
  static Program compute(const std::string& comp, const Defines& defines = {});

  GLuint id() const { return handle_.id(); }
  void use() const { glUseProgram(handle_.id()); }
  /// Uniform location by name, cached; -1 if the uniform is absent or optimised away.
  GLint location(const std::string& name) const;
  void set(const std::string& name, int v) const { glProgramUniform1i(id(), location(name), v); }
  void set(const std::string& name, float v) const { glProgramUniform1f(id(), location(name), v); }
  void set(const std::string& name, float x, float y) const { glProgramUniform2f(id(), location(name), x, y); }
  void set(const std::string& name, float x, float y, float z) const {
    glProgramUniform3f(id(), location(name), x, y, z);
  }
  void set(const std::string& name, int x, int y, int z) const { glProgramUniform3i(id(), location(name), x, y, z); }
  void set(const std::string& name, float x, float y, float z, float w) const {
    glProgramUniform4f(id(), location(name), x, y, z, w);
  }
  void setMat4(const std::string& name, const float* columnMajor) const {
    glProgramUniformMatrix4fv(id(), location(name), 1, GL_FALSE, columnMajor);
  }

 private:
  ProgramHandle handle_;
  mutable std::unordered_map<std::string, GLint> locations_;
};

}  // namespace mrgi::gl
