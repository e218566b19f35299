#include <GL/osmesa.h>

#include <vector>

#include "gl/backends.h"
#include "gl/error.h"

namespace mrgi::gl::detail {
namespace {

void* osmesaProc(const char* name) { return reinterpret_cast<void*>(OSMesaGetProcAddress(name)); }

class OsmesaContext final : public BackendContext {
 public:
  explicit OsmesaContext(const ContextConfig& config) : width_(config.width), height_(config.height) {
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           24,
                           OSMESA_STENCIL_BITS,
                           8,
                           OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           4,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           5,
                           0};
    ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
    if (!ctx_) throw GlError("osmesa: cannot create a GL 4.5 core context (Mesa too old or OSMesa missing)");
    buffer_.resize(static_cast<size_t>(width_) * height_ * 4);
    makeCurrent();
    detail_ = "OSMesa";
  }
  ~OsmesaContext() override { OSMesaDestroyContext(ctx_); }

  Backend backend() const override { return Backend::OSMesa; }
  void makeCurrent() override {
    if (!OSMesaMakeCurrent(ctx_, buffer_.data(), GL_UNSIGNED_BYTE, width_, height_))
      throw GlError("osmesa: OSMesaMakeCurrent failed");
  }
  int width() const override { return width_; }
  int height() const override { return height_; }
  ProcAddress procAddress() const override { return &osmesaProc; }

 private:
  OSMesaContext ctx_ = nullptr;
  int width_, height_;
  std::vector<unsigned char> buffer_;
};

}  // namespace

std::unique_ptr<BackendContext> createOsmesa(const ContextConfig& config) {
  return std::make_unique<OsmesaContext>(config);
}

}  // namespace mrgi::gl::detail
