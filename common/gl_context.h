// One small interface over headless OpenGL 4.5 core contexts. Backends:
// OSMesa (Mesa's software rasteriser) and EGL (Mesa's surfaceless platform on
// CPU machines, or a chosen device through EGL_EXT_platform_device on GPUs).
// A context owns no default framebuffer that dmmr uses: drawing goes to an FBO.
#pragma once

#include <memory>
#include <string>

#include "gl_api.h"

namespace dmmr {

enum class Backend { OSMesa, EGL };
// "osmesa" or "egl"; throws Error for anything else.
Backend parseBackend(const std::string& name);
const char* backendName(Backend b);

struct ContextOptions {
  Backend backend = Backend::OSMesa;
  // EGL only: -1 uses the surfaceless platform (falling back to device 0 when
  // it is missing); k >= 0 uses the k-th device from eglQueryDevicesEXT.
  int egl_device = -1;
};

class GlContext {
 public:
  virtual ~GlContext() = default;
  // Binds the context to the calling thread (EGL also binds the GL API, which
  // is per-thread state). Throws Error on failure.
  virtual void makeCurrent() = 0;
  virtual void releaseCurrent() = 0;
  virtual void* getProcAddress(const char* name) const = 0;
  // Human-readable renderer and version, for logs and reports.
  virtual std::string description() const = 0;
  const GlApi& gl() const { return gl_; }

 protected:
  // Called by backends once current: loads the entry points.
  void loadApi();
  GlApi gl_;
};

// Creates a GL 4.5 core context and makes it current on the calling thread.
// Throws Error saying which backend failed and why.
std::unique_ptr<GlContext> createContext(const ContextOptions& opts);
std::unique_ptr<GlContext> createOSMesaContext();
std::unique_ptr<GlContext> createEglContext(int device);

}  // namespace dmmr
