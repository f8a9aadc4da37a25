// The OpenGL entry points dmmr uses, loaded through the owning context's
// getProcAddress. Keeping a table per context (instead of linking libGL) lets
// the OSMesa and EGL backends live in one process without symbol clashes.
#pragma once

#define GL_GLEXT_PROTOTYPES 0
#include <GL/glcorearb.h>

#include <functional>
#include <string>

namespace dmmr {

// X(return, name, params)
#define DMMR_GL_FUNCTIONS(X)                                                             \
  X(GLenum, GetError, (void))                                                            \
  X(const GLubyte*, GetString, (GLenum))                                                 \
  X(void, GetIntegerv, (GLenum, GLint*))                                                 \
  X(void, Viewport, (GLint, GLint, GLsizei, GLsizei))                                    \
  X(void, Scissor, (GLint, GLint, GLsizei, GLsizei))                                     \
  X(void, Enable, (GLenum))                                                              \
  X(void, Disable, (GLenum))                                                             \
  X(void, ClearColor, (GLfloat, GLfloat, GLfloat, GLfloat))                              \
  X(void, ClearDepth, (GLdouble))                                                        \
  X(void, Clear, (GLbitfield))                                                           \
  X(void, DepthFunc, (GLenum))                                                           \
  X(void, DepthMask, (GLboolean))                                                        \
  X(void, ColorMask, (GLboolean, GLboolean, GLboolean, GLboolean))                       \
  X(void, ClipControl, (GLenum, GLenum))                                                 \
  X(void, ReadPixels, (GLint, GLint, GLsizei, GLsizei, GLenum, GLenum, void*))           \
  X(void, PixelStorei, (GLenum, GLint))                                                  \
  X(void, Finish, (void))                                                                \
  X(void, Flush, (void))                                                                 \
  X(void, GenFramebuffers, (GLsizei, GLuint*))                                           \
  X(void, DeleteFramebuffers, (GLsizei, const GLuint*))                                  \
  X(void, BindFramebuffer, (GLenum, GLuint))                                             \
  X(void, FramebufferRenderbuffer, (GLenum, GLenum, GLenum, GLuint))                     \
  X(GLenum, CheckFramebufferStatus, (GLenum))                                            \
  X(void, GenRenderbuffers, (GLsizei, GLuint*))                                          \
  X(void, DeleteRenderbuffers, (GLsizei, const GLuint*))                                 \
  X(void, BindRenderbuffer, (GLenum, GLuint))                                            \
  X(void, RenderbufferStorage, (GLenum, GLenum, GLsizei, GLsizei))                       \
  X(GLuint, CreateShader, (GLenum))                                                      \
  X(void, ShaderSource, (GLuint, GLsizei, const GLchar* const*, const GLint*))           \
  X(void, CompileShader, (GLuint))                                                       \
  X(void, GetShaderiv, (GLuint, GLenum, GLint*))                                         \
  X(void, GetShaderInfoLog, (GLuint, GLsizei, GLsizei*, GLchar*))                        \
  X(void, DeleteShader, (GLuint))                                                        \
  X(GLuint, CreateProgram, (void))                                                       \
  X(void, AttachShader, (GLuint, GLuint))                                                \
  X(void, BindAttribLocation, (GLuint, GLuint, const GLchar*))                           \
  X(void, LinkProgram, (GLuint))                                                         \
  X(void, GetProgramiv, (GLuint, GLenum, GLint*))                                        \
  X(void, GetProgramInfoLog, (GLuint, GLsizei, GLsizei*, GLchar*))                       \
  X(void, UseProgram, (GLuint))                                                          \
  X(void, DeleteProgram, (GLuint))                                                       \
  X(GLint, GetUniformLocation, (GLuint, const GLchar*))                                  \
  X(void, Uniform1i, (GLint, GLint))                                                     \
  X(void, Uniform2f, (GLint, GLfloat, GLfloat))                                          \
  X(void, Uniform3fv, (GLint, GLsizei, const GLfloat*))                                  \
  X(void, Uniform4fv, (GLint, GLsizei, const GLfloat*))                                  \
  X(void, UniformMatrix3fv, (GLint, GLsizei, GLboolean, const GLfloat*))                 \
  X(void, UniformMatrix4fv, (GLint, GLsizei, GLboolean, const GLfloat*))                 \
  X(void, GenVertexArrays, (GLsizei, GLuint*))                                           \
  X(void, DeleteVertexArrays, (GLsizei, const GLuint*))                                  \
  X(void, BindVertexArray, (GLuint))                                                     \
  X(void, GenBuffers, (GLsizei, GLuint*))                                                \
  X(void, DeleteBuffers, (GLsizei, const GLuint*))                                       \
  X(void, BindBuffer, (GLenum, GLuint))                                                  \
  X(void, BufferData, (GLenum, GLsizeiptr, const void*, GLenum))                         \
  X(void, BufferStorage, (GLenum, GLsizeiptr, const void*, GLbitfield))                  \
  X(void*, MapBufferRange, (GLenum, GLintptr, GLsizeiptr, GLbitfield))                   \
  X(GLboolean, UnmapBuffer, (GLenum))                                                    \
  X(void, TexBuffer, (GLenum, GLenum, GLuint))                                           \
  X(void, VertexAttribPointer, (GLuint, GLint, GLenum, GLboolean, GLsizei, const void*)) \
  X(void, EnableVertexAttribArray, (GLuint))                                             \
  X(void, DisableVertexAttribArray, (GLuint))                                            \
  X(void, VertexAttrib4f, (GLuint, GLfloat, GLfloat, GLfloat, GLfloat))                  \
  X(void, DrawElements, (GLenum, GLsizei, GLenum, const void*))                          \
  X(void, DrawElementsBaseVertex, (GLenum, GLsizei, GLenum, const void*, GLint))         \
  X(void, DrawArrays, (GLenum, GLint, GLsizei))                                          \
  X(void, GenTextures, (GLsizei, GLuint*))                                               \
  X(void, DeleteTextures, (GLsizei, const GLuint*))                                      \
  X(void, BindTexture, (GLenum, GLuint))                                                 \
  X(void, ActiveTexture, (GLenum))                                                       \
  X(void, TexImage2D,                                                                    \
    (GLenum, GLint, GLint, GLsizei, GLsizei, GLint, GLenum, GLenum, const void*))        \
  X(void, TexParameteri, (GLenum, GLenum, GLint))                                        \
  X(void, GenerateMipmap, (GLenum))                                                      \
  X(void, GenQueries, (GLsizei, GLuint*))                                                \
  X(void, DeleteQueries, (GLsizei, const GLuint*))                                       \
  X(void, BeginQuery, (GLenum, GLuint))                                                  \
  X(void, EndQuery, (GLenum))                                                            \
  X(void, GetQueryObjectuiv, (GLuint, GLenum, GLuint*))

struct GlApi {
#define DMMR_GL_MEMBER(ret, name, params) ret(APIENTRY* name) params = nullptr;
  DMMR_GL_FUNCTIONS(DMMR_GL_MEMBER)
#undef DMMR_GL_MEMBER

  // Loads every entry point; throws Error naming the first one missing.
  void load(const std::function<void*(const char*)>& getProcAddress);
  // Throws Error with `where` and the GL error name when glGetError reports one.
  void check(const char* where) const;
};

}  // namespace dmmr
