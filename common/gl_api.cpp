#include "gl_api.h"

#include "error.h"

namespace dmmr {

void GlApi::load(const std::function<void*(const char*)>& getProcAddress) {
#define DMMR_GL_LOAD(ret, name, params)                                       \
  name = reinterpret_cast<ret(APIENTRY*) params>(getProcAddress("gl" #name)); \
  if (!name) throw Error("OpenGL entry point gl" #name " is missing (needs OpenGL 4.5)");
  DMMR_GL_FUNCTIONS(DMMR_GL_LOAD)
#undef DMMR_GL_LOAD
}

void GlApi::check(const char* where) const {
  GLenum e = GetError();
  if (e == GL_NO_ERROR) return;
  const char* name = "unknown";
  switch (e) {
    case GL_INVALID_ENUM:
      name = "GL_INVALID_ENUM";
      break;
    case GL_INVALID_VALUE:
      name = "GL_INVALID_VALUE";
      break;
    case GL_INVALID_OPERATION:
      name = "GL_INVALID_OPERATION";
      break;
    case GL_OUT_OF_MEMORY:
      name = "GL_OUT_OF_MEMORY";
      break;
    case GL_INVALID_FRAMEBUFFER_OPERATION:
      name = "GL_INVALID_FRAMEBUFFER_OPERATION";
      break;
  }
  throw Error(std::string("OpenGL error ") + name + " in " + where);
}

}  // namespace dmmr
