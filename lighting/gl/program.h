#pragma once
/// GLSL programs built from embedded shader files, with `#include "file"` and `#define` variants.
/// Compile and link errors are thrown as one line naming the shader file and line.
#include <memory>
#include <set>
#include <string>
#include <unordered_map>
#include <unordered_set>
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

/// The names of the uniforms a preprocessed source declares ("uniform vec3 uA[4];" -> "uA"; blocks aside),
/// comments skipped.
std::set<std::string> declaredUniforms(const std::string& source);

/// Whether setting a uniform no stage of the program declares (a misspelt name) is an error: the environment's
/// MRGI_STRICT_UNIFORMS (1 or 0; the tests set 1), else on in debug builds and off in release builds, where
/// such a call does nothing, as GL's location -1 does.
bool strictUniforms();

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
  /// Uniform location by name ("uA", "uA[2]"), cached; -1 if it is optimised away. A name no stage declares
  /// throws GlError naming the program when strictUniforms(), else gives -1.
  GLint location(const std::string& name) const;
  /// Whether one of its stages declares the uniform (shared drawing code that sets what only some programs use).
  bool declares(const std::string& name) const { return declared_ && declared_->count(name) > 0; }
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
  std::string name_;                                                 ///< its shaders' names, for messages
  std::shared_ptr<const std::unordered_set<std::string>> declared_;  ///< uniforms its stages declare
  mutable std::unordered_map<std::string, GLint> locations_;
};

}  // namespace mrgi::gl
