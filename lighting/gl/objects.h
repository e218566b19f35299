#pragma once
/// Move-only RAII owners of GL object names. Raw GL names appear only inside these wrappers; every
/// constructor uses direct state access (GL 4.5), so creating an object never changes a binding.
#include <utility>

#include "gl/glapi.h"

namespace mrgi::gl {

template <typename Traits>
class Handle {
 public:
  Handle() = default;
  explicit Handle(GLuint id) : id_(id) {}
  ~Handle() { reset(); }
  Handle(Handle&& o) noexcept : id_(std::exchange(o.id_, 0)) {}
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, 0);
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;

  GLuint id() const { return id_; }
  explicit operator bool() const { return id_ != 0; }
  void reset() {
    if (id_) Traits::destroy(id_);
    id_ = 0;
  }

 private:
  GLuint id_ = 0;
};

namespace traits {
struct Buffer {
  static void destroy(GLuint id) { glDeleteBuffers(1, &id); }
};
struct Texture {
  static void destroy(GLuint id) { glDeleteTextures(1, &id); }
};
struct Framebuffer {
  static void destroy(GLuint id) { glDeleteFramebuffers(1, &id); }
};
struct Renderbuffer {
  static void destroy(GLuint id) { glDeleteRenderbuffers(1, &id); }
};
struct VertexArray {
  static void destroy(GLuint id) { glDeleteVertexArrays(1, &id); }
};
struct Query {
  static void destroy(GLuint id) { glDeleteQueries(1, &id); }
};
struct Shader {
  static void destroy(GLuint id) { glDeleteShader(id); }
};
struct Program {
  static void destroy(GLuint id) { glDeleteProgram(id); }
};
}  // namespace traits

using BufferHandle = Handle<traits::Buffer>;
using FramebufferHandle = Handle<traits::Framebuffer>;
using RenderbufferHandle = Handle<traits::Renderbuffer>;
using VertexArrayHandle = Handle<traits::VertexArray>;
using QueryHandle = Handle<traits::Query>;
using ShaderHandle = Handle<traits::Shader>;
using ProgramHandle = Handle<traits::Program>;

/// Synchronous GPU -> CPU transfers so far on this thread's contexts: every Buffer/Texture download, pixel
/// read into client memory and blocking query read counts one. The CPU waits for the GPU at each, so the
/// frame path's count is held at zero by a test where no output needs a result on the CPU.
uint64_t synchronousReadbacks();
/// Counts one (for code that calls GL's read functions itself).
void countSynchronousReadback();

/// A buffer object with immutable storage (glNamedBufferStorage).
class Buffer {
 public:
  Buffer() = default;
  /// size in bytes; data may be null; flags as for glNamedBufferStorage (GL_DYNAMIC_STORAGE_BIT, ...).
  Buffer(GLsizeiptr size, const void* data, GLbitfield flags = GL_DYNAMIC_STORAGE_BIT);
  GLuint id() const { return handle_.id(); }
  GLsizeiptr size() const { return size_; }
  void upload(GLintptr offset, GLsizeiptr bytes, const void* data);
  void download(GLintptr offset, GLsizeiptr bytes, void* out) const;
  /// Sets every byte to zero (glClearNamedBufferData; the contents change, the object does not).
  void clear() const;
  /// A storage buffer of at least 16 bytes (an SSBO binding needs a non-empty one): the first `bytes` from
  /// `data`, zeros where data is null and beyond.
  static Buffer storage(size_t bytes, const void* data = nullptr);

 private:
  BufferHandle handle_;
  GLsizeiptr size_ = 0;
};

/// A 2D, 2D-array or 3D texture with immutable storage. Filtering defaults to linear, clamp to edge.
class Texture {
 public:
  Texture() = default;
  /// target: GL_TEXTURE_2D | GL_TEXTURE_2D_ARRAY | GL_TEXTURE_3D; depth = layers / slices (1 for 2D).
  Texture(GLenum target, GLenum internalFormat, int width, int height, int depth = 1, int levels = 1);
  GLuint id() const { return handle_.id(); }
  GLenum target() const { return target_; }
  GLenum internalFormat() const { return format_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int depth() const { return depth_; }
  /// GPU memory of level 0 (0 for an empty texture); throws GlError for a format it does not know.
  size_t bytes() const;
  /// Uploads a whole level-0 image (all layers/slices). format/type as for glTextureSubImage*.
  void upload(GLenum format, GLenum type, const void* data, int rowAlignment = 1);
  /// Uploads the whole image of one level of a 2D texture made with that many levels (width and height halved per
  /// level, at least 1).
  void uploadLevel(int level, GLenum format, GLenum type, const void* data, int rowAlignment = 1);
  /// Reads the whole level-0 image back into out (caller sizes it).
  void download(GLenum format, GLenum type, void* out, GLsizei bufSize, int rowAlignment = 1) const;
  void setFilter(GLenum minFilter, GLenum magFilter);
  /// Wrap mode for all axes (GL_CLAMP_TO_EDGE by default; GL_CLAMP_TO_BORDER uses a zero border).
  void setWrap(GLenum wrap);
  /// Wrap modes along s and t apart (a lat-long map: its azimuth repeats, its polar angle clamps).
  void setWrap(GLenum wrapS, GLenum wrapT);
  /// Sets every texel of level 0 to zero (glClearTexImage).
  void clear();
  void bind(GLuint unit) const { glBindTextureUnit(unit, handle_.id()); }

 private:
  Handle<traits::Texture> handle_;
  GLenum target_ = 0, format_ = 0;
  int width_ = 0, height_ = 0, depth_ = 0;
};

/// A framebuffer object with colour attachments and an optional depth attachment.
class Framebuffer {
 public:
  Framebuffer();
  GLuint id() const { return handle_.id(); }
  void attachColour(int index, const Texture& texture, int level = 0);
  void attachDepth(const Texture& texture);
  /// Enables draw buffers 0..count-1 and throws GlError if the framebuffer is incomplete.
  void finalise(int colourCount);
  void bind() const { glBindFramebuffer(GL_FRAMEBUFFER, handle_.id()); }

 private:
  FramebufferHandle handle_;
};

/// A vertex array. Empty, it serves full-screen passes that generate vertices from gl_VertexID.
class VertexArray {
 public:
  VertexArray();
  GLuint id() const { return handle_.id(); }
  /// Float attribute `index` read from buffer at byte offset within each stride-byte vertex (binding = index).
  void attribute(GLuint index, const Buffer& buffer, GLuint offset, GLsizei stride, GLint components);
  void elements(const Buffer& buffer) { glVertexArrayElementBuffer(handle_.id(), buffer.id()); }
  void bind() const { glBindVertexArray(handle_.id()); }

 private:
  VertexArrayHandle handle_;
};

}  // namespace mrgi::gl
