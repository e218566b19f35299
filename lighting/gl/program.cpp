#include "gl/program.h"

#include <cstdlib>
#include <regex>
#include <set>
#include <sstream>

#include "gl/error.h"
#include "gl/shader_registry.h"

namespace mrgi::gl {
namespace {

std::string directoryOf(const std::string& path) {
  const auto slash = path.rfind('/');
  return slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
}

struct Expander {
  PreprocessedSource out;
  std::set<std::string> included;
  std::vector<std::string> stack;

  void emit(const std::string& line, const std::string& origin) {
    out.text += line + "\n";
    out.origins.push_back(origin);
  }

  void expand(const std::string& name, bool top, const Defines& defines) {
    std::istringstream in(shaderSource(name));
    std::string line;
    int lineNo = 0;
    bool sawVersion = false;
    static const std::regex includeRe(R"re(^\s*#\s*include\s+"([^"]+)"\s*$)re");
    while (std::getline(in, line)) {
      ++lineNo;
      const std::string origin = name + ":" + std::to_string(lineNo);
      std::smatch m;
      if (top && !sawVersion && line.rfind("#version", 0) == 0) {
        sawVersion = true;
        emit(line, origin);
        for (const auto& [k, v] : defines) emit("#define " + k + " " + v, "<define " + k + ">");
        continue;
      }
      if (std::regex_match(line, m, includeRe)) {
        std::string target = directoryOf(name) + m[1].str();
        if (!hasShaderSource(target)) target = m[1].str();
        if (!hasShaderSource(target)) throw GlError("shader " + origin + ": cannot include '" + m[1].str() + "'");
        for (const auto& s : stack)
          if (s == target) throw GlError("shader " + origin + ": include cycle via " + target);
        if (included.insert(target).second) {
          stack.push_back(target);
          expand(target, false, defines);
          stack.pop_back();
        }
        continue;
      }
      emit(line, origin);
    }
    if (top && !sawVersion) throw GlError("shader " + name + ":1: the first line must be a #version directive");
  }
};

ShaderHandle compileStage(GLenum stage, const std::string& name, const Defines& defines,
                          std::unordered_set<std::string>& declared) {
  const PreprocessedSource src = preprocessShader(name, defines);
  for (const std::string& u : declaredUniforms(src.text)) declared.insert(u);
  ShaderHandle shader(glCreateShader(stage));
  const char* text = src.text.c_str();
  glShaderSource(shader.id(), 1, &text, nullptr);
  glCompileShader(shader.id());
  GLint ok = GL_FALSE;
  glGetShaderiv(shader.id(), GL_COMPILE_STATUS, &ok);
  if (!ok) {
    GLint len = 0;
    glGetShaderiv(shader.id(), GL_INFO_LOG_LENGTH, &len);
    std::string log(static_cast<size_t>(std::max(len, 1)), '\0');
    glGetShaderInfoLog(shader.id(), len, nullptr, log.data());
    throw GlError("shader compile failed: " + mapShaderLog(log, src.origins));
  }
  return shader;
}

ProgramHandle link(const std::vector<ShaderHandle>& shaders, const std::string& what) {
  ProgramHandle program(glCreateProgram());
  for (const auto& s : shaders) glAttachShader(program.id(), s.id());
  glLinkProgram(program.id());
  GLint ok = GL_FALSE;
  glGetProgramiv(program.id(), GL_LINK_STATUS, &ok);
  if (!ok) {
    GLint len = 0;
    glGetProgramiv(program.id(), GL_INFO_LOG_LENGTH, &len);
    std::string log(static_cast<size_t>(std::max(len, 1)), '\0');
    glGetProgramInfoLog(program.id(), len, nullptr, log.data());
    throw GlError("program link failed (" + what + "): " + mapShaderLog(log, {}));
  }
  for (const auto& s : shaders) glDetachShader(program.id(), s.id());
  return program;
}

}  // namespace

PreprocessedSource preprocessShader(const std::string& name, const Defines& defines) {
  Expander e;
  e.included.insert(name);
  e.stack.push_back(name);
  e.expand(name, true, defines);
  return e.out;
}

std::string mapShaderLog(const std::string& log, const std::vector<std::string>& origins) {
  // Keep the first line that reports an error (the log may hold many); user errors are one line.
  std::istringstream in(log);
  std::string line, first;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (first.empty()) first = line;
    if (line.find("error") != std::string::npos) {
      first = line;
      break;
    }
  }
  while (!first.empty() && (first.back() == '\r' || first.back() == '\0' || first.back() == ' ')) first.pop_back();
  static const std::regex mesaRe(R"re(^(\d+):(\d+)\(\d+\):\s*)re");  // Mesa: 0:12(5): error: ...
  static const std::regex nvRe(R"re(^(\d+)\((\d+)\)\s*:\s*)re");     // NVIDIA: 0(12) : error C...
  std::smatch m;
  if (std::regex_search(first, m, mesaRe) || std::regex_search(first, m, nvRe)) {
    const size_t lineNo = std::stoul(m[2].str());
    const std::string where = lineNo >= 1 && lineNo <= origins.size() ? origins[lineNo - 1] : "line " + m[2].str();
    return where + ": " + m.suffix().str();
  }
  return first;
}

Program Program::graphics(const std::string& vert, const std::string& frag, const Defines& defines) {
  std::vector<ShaderHandle> shaders;
  auto declared = std::make_shared<std::unordered_set<std::string>>();
  shaders.push_back(compileStage(GL_VERTEX_SHADER, vert, defines, *declared));
  shaders.push_back(compileStage(GL_FRAGMENT_SHADER, frag, defines, *declared));
  Program p;
  p.name_ = vert + " + " + frag;
  p.handle_ = link(shaders, p.name_);
  p.declared_ = std::move(declared);
  return p;
}

Program Program::graphics(const std::string& vert, const std::string& geom, const std::string& frag,
                          const Defines& defines) {
  std::vector<ShaderHandle> shaders;
  auto declared = std::make_shared<std::unordered_set<std::string>>();
  shaders.push_back(compileStage(GL_VERTEX_SHADER, vert, defines, *declared));
  shaders.push_back(compileStage(GL_GEOMETRY_SHADER, geom, defines, *declared));
  shaders.push_back(compileStage(GL_FRAGMENT_SHADER, frag, defines, *declared));
  Program p;
  p.name_ = vert + " + " + geom + " + " + frag;
  p.handle_ = link(shaders, p.name_);
  p.declared_ = std::move(declared);
  return p;
}

Program Program::compute(const std::string& comp, const Defines& defines) {
  std::vector<ShaderHandle> shaders;
  auto declared = std::make_shared<std::unordered_set<std::string>>();
  shaders.push_back(compileStage(GL_COMPUTE_SHADER, comp, defines, *declared));
  Program p;
  p.name_ = comp;
  p.handle_ = link(shaders, p.name_);
  p.declared_ = std::move(declared);
  return p;
}

GLint Program::location(const std::string& name) const {
  auto it = locations_.find(name);
  if (it != locations_.end()) return it->second;
  const GLint loc = glGetUniformLocation(handle_.id(), name.c_str());
  if (loc < 0 && declared_ && strictUniforms()) {
    const std::string base = name.substr(0, name.find_first_of("[."));
    if (!declared_->count(base))
      throw GlError("program " + name_ + ": sets the uniform '" + name + "', which no stage declares");
  }
  locations_.emplace(name, loc);
  return loc;
}

std::set<std::string> declaredUniforms(const std::string& source) {
  // Comments out, then each "uniform ... ;" statement that is not a block: the identifiers before '[', '=' or
  // ',' of each declarator.
  std::string text;
  text.reserve(source.size());
  for (size_t i = 0; i < source.size(); ++i) {
    if (source.compare(i, 2, "//") == 0) {
      i = source.find('\n', i);
      if (i == std::string::npos) break;
    } else if (source.compare(i, 2, "/*") == 0) {
      i = source.find("*/", i + 2);
      if (i == std::string::npos) break;
      ++i;
      continue;
    }
    text += source[i];
  }
  std::set<std::string> out;
  static const std::regex word(R"(\buniform\b)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), word); it != std::sregex_iterator(); ++it) {
    const size_t start = static_cast<size_t>(it->position() + it->length());
    const size_t end = text.find_first_of(";{", start);
    if (end == std::string::npos || text[end] == '{') continue;  // a uniform block
    std::string decl = text.substr(start, end - start);
    for (char& c : decl)
      if (c == '\n' || c == '\t') c = ' ';
    size_t from = 0;
    while (from <= decl.size()) {
      size_t comma = decl.find(',', from);
      if (comma == std::string::npos) comma = decl.size();
      std::string part = decl.substr(from, comma - from);
      part = part.substr(0, part.find_first_of("[="));
      while (!part.empty() && part.back() == ' ') part.pop_back();
      const size_t sp = part.find_last_of(' ');
      const std::string name = sp == std::string::npos ? part : part.substr(sp + 1);
      if (!name.empty()) out.insert(name);
      from = comma + 1;
    }
  }
  return out;
}

bool strictUniforms() {
  static const bool strict = [] {
    if (const char* e = std::getenv("MRGI_STRICT_UNIFORMS")) return std::string(e) != "0";
#ifndef NDEBUG
    return true;
#else
    return false;
#endif
  }();
  return strict;
}

}  // namespace mrgi::gl
