#include <GL/osmesa.h>

#include <vector>

#include "error.h"
#include "gl_context.h"

namespace dmmr {
namespace {

class OSMesaContextImpl : public GlContext {
 public:
  OSMesaContextImpl() {
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           4,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           5,
                           0};
    ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
    if (!ctx_) throw Error("osmesa: cannot create an OpenGL 4.5 core context");
    makeCurrent();
    loadApi();
  }
  ~OSMesaContextImpl() override {
    if (ctx_) OSMesaDestroyContext(ctx_);
  }
  void makeCurrent() override {
    // The default framebuffer is a token 1x1 buffer: all drawing goes to FBOs.
    if (!OSMesaMakeCurrent(ctx_, buffer_.data(), GL_UNSIGNED_BYTE, 1, 1))
      throw Error("osmesa: cannot make the context current");
  }
  void releaseCurrent() override { OSMesaMakeCurrent(nullptr, nullptr, GL_UNSIGNED_BYTE, 0, 0); }
  void* getProcAddress(const char* name) const override {
    return reinterpret_cast<void*>(OSMesaGetProcAddress(name));
  }
  std::string description() const override {
    return std::string("osmesa: ") + reinterpret_cast<const char*>(gl_.GetString(GL_RENDERER)) +
           ", " + reinterpret_cast<const char*>(gl_.GetString(GL_VERSION));
  }

 private:
  OSMesaContext ctx_ = nullptr;
  std::vector<unsigned char> buffer_ = std::vector<unsigned char>(4);
};

}  // namespace

std::unique_ptr<GlContext> createOSMesaContext() {
  return std::make_unique<OSMesaContextImpl>();
}

}  // namespace dmmr
