#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdio>
#include <cstring>
#include <vector>

#include "error.h"
#include "gl_context.h"

namespace dmmr {
namespace {

std::string eglErrorName(EGLint e) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "EGL error 0x%04x", unsigned(e));
  return buf;
}

template <typename F>
F eglProc(const char* name) {
  return reinterpret_cast<F>(eglGetProcAddress(name));
}

bool hasExtension(const char* list, const char* ext) {
  if (!list) return false;
  size_t n = std::strlen(ext);
  for (const char* p = list; (p = std::strstr(p, ext)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

EGLDisplay deviceDisplay(int index) {
  auto queryDevices = eglProc<PFNEGLQUERYDEVICESEXTPROC>("eglQueryDevicesEXT");
  auto getPlatformDisplay = eglProc<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
  if (!queryDevices || !getPlatformDisplay)
    throw Error("egl: EGL_EXT_device_enumeration / platform_device are not available");
  EGLDeviceEXT devices[32];
  EGLint count = 0;
  if (!queryDevices(32, devices, &count) || count == 0) throw Error("egl: no EGL devices found");
  if (index >= count)
    throw Error("egl: device " + std::to_string(index) + " requested but only " +
                std::to_string(count) + " found");
  return getPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[index], nullptr);
}

EGLDisplay openDisplay(int device) {
  if (device >= 0) return deviceDisplay(device);
  const char* clientExt = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (hasExtension(clientExt, "EGL_MESA_platform_surfaceless")) {
    auto getPlatformDisplay = eglProc<PFNEGLGETPLATFORMDISPLAYEXTPROC>("eglGetPlatformDisplayEXT");
    EGLDisplay d = getPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (d != EGL_NO_DISPLAY) return d;
  }
  return deviceDisplay(0);
}

class EglContextImpl : public GlContext {
 public:
  explicit EglContextImpl(int device) {
    dpy_ = openDisplay(device);
    if (dpy_ == EGL_NO_DISPLAY) throw Error("egl: cannot open a display");
    EGLint major = 0, minor = 0;
    if (!eglInitialize(dpy_, &major, &minor))
      throw Error("egl: eglInitialize failed: " + eglErrorName(eglGetError()));
    if (!eglBindAPI(EGL_OPENGL_API)) throw Error("egl: desktop OpenGL API is not available");
    EGLConfig config = nullptr;
    const char* ext = eglQueryString(dpy_, EGL_EXTENSIONS);
    if (!hasExtension(ext, "EGL_KHR_no_config_context")) {
      const EGLint cfgAttribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
      EGLint n = 0;
      if (!eglChooseConfig(dpy_, cfgAttribs, &config, 1, &n) || n == 0)
        throw Error("egl: no OpenGL-capable config");
    }
    const EGLint ctxAttribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                 4,
                                 EGL_CONTEXT_MINOR_VERSION,
                                 5,
                                 EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                 EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                 EGL_NONE};
    ctx_ = eglCreateContext(dpy_, config, EGL_NO_CONTEXT, ctxAttribs);
    if (ctx_ == EGL_NO_CONTEXT)
      throw Error("egl: cannot create an OpenGL 4.5 core context: " + eglErrorName(eglGetError()));
    makeCurrent();
    loadApi();
  }
  ~EglContextImpl() override {
    if (ctx_ != EGL_NO_CONTEXT) {
      if (eglGetCurrentContext() == ctx_)
        eglMakeCurrent(dpy_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(dpy_, ctx_);
    }
    // The display is shared by every context of the process: never terminated.
  }
  void makeCurrent() override {
    // The bound API is per-thread EGL state, so bind it on every thread.
    if (!eglBindAPI(EGL_OPENGL_API) || !eglMakeCurrent(dpy_, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx_))
      throw Error("egl: cannot make the context current: " + eglErrorName(eglGetError()));
  }
  void releaseCurrent() override {
    eglMakeCurrent(dpy_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  }
  void* getProcAddress(const char* name) const override {
    return reinterpret_cast<void*>(eglGetProcAddress(name));
  }
  std::string description() const override {
    return std::string("egl: ") + reinterpret_cast<const char*>(gl_.GetString(GL_RENDERER)) + ", " +
           reinterpret_cast<const char*>(gl_.GetString(GL_VERSION));
  }

 private:
  EGLDisplay dpy_ = EGL_NO_DISPLAY;
  EGLContext ctx_ = EGL_NO_CONTEXT;
};

}  // namespace

std::unique_ptr<GlContext> createEglContext(int device) {
  return std::make_unique<EglContextImpl>(device);
}

}  // namespace dmmr
