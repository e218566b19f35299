#include "gl/objects.h"

#include <algorithm>
#include <string>
#include <vector>

#include "gl/error.h"

namespace mrgi::gl {

Buffer::Buffer(GLsizeiptr size, const void* data, GLbitfield flags) : size_(size) {
  GLuint id = 0;
  glCreateBuffers(1, &id);
  handle_ = BufferHandle(id);
  glNamedBufferStorage(id, size, data, flags);
}

void Buffer::clear() const { glClearNamedBufferData(handle_.id(), GL_R8, GL_RED, GL_UNSIGNED_BYTE, nullptr); }

Buffer Buffer::storage(size_t bytes, const void* data) {
  if (data && bytes >= 16) return Buffer(static_cast<GLsizeiptr>(bytes), data);
  std::vector<uint8_t> bytesOut(std::max<size_t>(bytes, 16), 0);
  if (data) std::copy_n(static_cast<const uint8_t*>(data), bytes, bytesOut.begin());
  return Buffer(static_cast<GLsizeiptr>(bytesOut.size()), bytesOut.data());
}

void Buffer::upload(GLintptr offset, GLsizeiptr bytes, const void* data) {
  glNamedBufferSubData(handle_.id(), offset, bytes, data);
}

namespace {
thread_local uint64_t gReadbacks = 0;
}  // namespace

uint64_t synchronousReadbacks() { return gReadbacks; }
void countSynchronousReadback() { ++gReadbacks; }

void Buffer::download(GLintptr offset, GLsizeiptr bytes, void* out) const {
  countSynchronousReadback();
  glGetNamedBufferSubData(handle_.id(), offset, bytes, out);
}

size_t Texture::bytes() const {
  if (id() == 0) return 0;
  size_t texel = 0;
  switch (format_) {
    case GL_RGBA32F:
      texel = 16;
      break;
    case GL_RGB32F:
      texel = 12;
      break;
    case GL_RGBA16F:
    case GL_RG32F:
      texel = 8;
      break;
    case GL_RGBA8:
    case GL_R32F:
    case GL_DEPTH_COMPONENT32F:
    case GL_DEPTH_COMPONENT24:
    case GL_DEPTH24_STENCIL8:
      texel = 4;
      break;
    case GL_R8:
      texel = 1;
      break;
    default:
      throw GlError("Texture::bytes(): unknown internal format " + std::to_string(format_));
  }
  return texel * static_cast<size_t>(width_) * static_cast<size_t>(height_) * static_cast<size_t>(depth_);
}

Texture::Texture(GLenum target, GLenum internalFormat, int width, int height, int depth, int levels)
    : target_(target), format_(internalFormat), width_(width), height_(height), depth_(depth) {
  if (width <= 0 || height <= 0 || depth <= 0)
    throw GlError("Texture(): size " + std::to_string(width) + "x" + std::to_string(height) + "x" +
                  std::to_string(depth) + " is not positive");
  GLuint id = 0;
  glCreateTextures(target, 1, &id);
  handle_ = Handle<traits::Texture>(id);
  if (target == GL_TEXTURE_2D)
    glTextureStorage2D(id, levels, internalFormat, width, height);
  else
    glTextureStorage3D(id, levels, internalFormat, width, height, depth);
  setFilter(GL_LINEAR, GL_LINEAR);
  glTextureParameteri(id, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTextureParameteri(id, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glTextureParameteri(id, GL_TEXTURE_WRAP_R, GL_CLAMP_TO_EDGE);
}

void Texture::upload(GLenum format, GLenum type, const void* data, int rowAlignment) {
  glPixelStorei(GL_UNPACK_ALIGNMENT, rowAlignment);
  if (target_ == GL_TEXTURE_2D)
    glTextureSubImage2D(handle_.id(), 0, 0, 0, width_, height_, format, type, data);
  else
    glTextureSubImage3D(handle_.id(), 0, 0, 0, 0, width_, height_, depth_, format, type, data);
}

void Texture::uploadLevel(int level, GLenum format, GLenum type, const void* data, int rowAlignment) {
  if (target_ != GL_TEXTURE_2D || level < 0)
    throw GlError("Texture::uploadLevel(): level " + std::to_string(level) + " of a texture that is not 2D");
  glPixelStorei(GL_UNPACK_ALIGNMENT, rowAlignment);
  glTextureSubImage2D(handle_.id(), level, 0, 0, std::max(1, width_ >> level), std::max(1, height_ >> level), format,
                      type, data);
}

void Texture::download(GLenum format, GLenum type, void* out, GLsizei bufSize, int rowAlignment) const {
  countSynchronousReadback();
  glPixelStorei(GL_PACK_ALIGNMENT, rowAlignment);
  glGetTextureImage(handle_.id(), 0, format, type, bufSize, out);
}

void Texture::setFilter(GLenum minFilter, GLenum magFilter) {
  glTextureParameteri(handle_.id(), GL_TEXTURE_MIN_FILTER, static_cast<GLint>(minFilter));
  glTextureParameteri(handle_.id(), GL_TEXTURE_MAG_FILTER, static_cast<GLint>(magFilter));
}

void Texture::setWrap(GLenum wrap) {
  const auto w = static_cast<GLint>(wrap);
  glTextureParameteri(handle_.id(), GL_TEXTURE_WRAP_S, w);
  glTextureParameteri(handle_.id(), GL_TEXTURE_WRAP_T, w);
  glTextureParameteri(handle_.id(), GL_TEXTURE_WRAP_R, w);
  const float zero[4] = {0, 0, 0, 0};
  glTextureParameterfv(handle_.id(), GL_TEXTURE_BORDER_COLOR, zero);
}

void Texture::setWrap(GLenum wrapS, GLenum wrapT) {
  glTextureParameteri(handle_.id(), GL_TEXTURE_WRAP_S, static_cast<GLint>(wrapS));
  glTextureParameteri(handle_.id(), GL_TEXTURE_WRAP_T, static_cast<GLint>(wrapT));
}

void Texture::clear() {
  const float zero[4] = {0, 0, 0, 0};
  glClearTexImage(handle_.id(), 0, GL_RGBA, GL_FLOAT, zero);
}

Framebuffer::Framebuffer() {
  GLuint id = 0;
  glCreateFramebuffers(1, &id);
  handle_ = FramebufferHandle(id);
}

void Framebuffer::attachColour(int index, const Texture& texture, int level) {
  glNamedFramebufferTexture(handle_.id(), GL_COLOR_ATTACHMENT0 + index, texture.id(), level);
}

void Framebuffer::attachDepth(const Texture& texture) {
  glNamedFramebufferTexture(handle_.id(), GL_DEPTH_ATTACHMENT, texture.id(), 0);
}

void Framebuffer::finalise(int colourCount) {
  GLenum buffers[8];
  for (int i = 0; i < colourCount && i < 8; ++i) buffers[i] = GL_COLOR_ATTACHMENT0 + i;
  glNamedFramebufferDrawBuffers(handle_.id(), colourCount, buffers);
  const GLenum status = glCheckNamedFramebufferStatus(handle_.id(), GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "0x%04x", status);
    throw GlError(std::string("Framebuffer::finalise(): incomplete framebuffer, status ") + buf);
  }
}

VertexArray::VertexArray() {
  GLuint id = 0;
  glCreateVertexArrays(1, &id);
  handle_ = VertexArrayHandle(id);
}

void VertexArray::attribute(GLuint index, const Buffer& buffer, GLuint offset, GLsizei stride, GLint components) {
  glEnableVertexArrayAttrib(handle_.id(), index);
  glVertexArrayVertexBuffer(handle_.id(), index, buffer.id(), 0, stride);
  glVertexArrayAttribFormat(handle_.id(), index, components, GL_FLOAT, GL_FALSE, offset);
  glVertexArrayAttribBinding(handle_.id(), index, index);
}

}  // namespace mrgi::gl
