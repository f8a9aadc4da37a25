#include "gl_context.h"

#include "error.h"

namespace dmmr {

Backend parseBackend(const std::string& name) {
  if (name == "osmesa") return Backend::OSMesa;
  if (name == "egl") return Backend::EGL;
  throw Error("unknown backend '" + name + "' (expected osmesa or egl)");
}

const char* backendName(Backend b) {
  return b == Backend::OSMesa ? "osmesa" : "egl";
}

void GlContext::loadApi() {
  gl_.load([this](const char* n) { return getProcAddress(n); });
}

std::unique_ptr<GlContext> createContext(const ContextOptions& opts) {
  if (opts.backend == Backend::OSMesa) return createOSMesaContext();
  return createEglContext(opts.egl_device);
}

}  // namespace dmmr
