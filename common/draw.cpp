#include "draw.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <string>

#include "error.h"

namespace dmmr {

namespace {

// gl_Position is invariant here and in kBoxVertexShader, whose data flow
// for it is the same (u_proj * (u_mv * position)): GLSL then guarantees the
// position-only program (drawDepth, id frames) and the shading program put
// every vertex, so every fragment's depth, in the same place bit for bit,
// which the fused stage's tie query and EQUAL colour pass count on. Without
// it a compiler may contract the two programs' products differently (an
// FMA in one, not the other).
const char* kVertexShader = R"(#version 450 core
invariant gl_Position;
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_nrm;
layout(location = 2) in vec4 a_col;
layout(location = 3) in vec2 a_uv;
uniform mat4 u_mv;
uniform mat4 u_proj;
uniform mat3 u_nrm;
uniform int u_slot;
flat out int v_slot;
out vec3 v_eye;
out vec3 v_nrm;
out vec4 v_col;
out vec2 v_uv;
void main() {
  vec4 e = u_mv * vec4(a_pos, 1.0);
  v_eye = e.xyz;
  v_nrm = u_nrm * a_nrm;
  v_col = a_col;
  v_uv = a_uv;
  v_slot = u_slot;
  gl_Position = u_proj * e;
}
)";

// The entry-depth planes of the object's box (camera.h, entryDepthPlanes)
// reach the fragment shader as BOUND(i), the same floats bit for bit either
// way: in the shading program from the draw's slot (Renderer::DrawSlot, a
// texel buffer read through a slot index that a vertex shader uniform
// passes on flat, with the submesh's colour), in the position-only program
// (kBoxVertexShader) as a flat varying from a vertex shader uniform. Not a
// fragment shader uniform: on llvmpipe changing one between draws copies
// the whole rasteriser state, about 13 us of CPU a draw call against about
// 1 us for a vertex shader uniform (`hot_bench shade`, `hot_bench depth`).
// Not flat varyings in the shading program either: the planes and colour
// cost more per triangle there than they saved (15-25% more client CPU on
// monument4m and skulls25; docs/benchmarks.md, "The depth bound as a flat
// varying"). An SSBO instead of the texel buffer costs llvmpipe a scalar
// loop per fragment, and a UBO is copied when bound, not read at
// rasterisation ("Per-draw values in a texel buffer"). Each holds the
// #version line.
const char* kBoundSlot = R"(#version 450 core
flat in int v_slot;
uniform samplerBuffer u_slots;
#define BOUND(i) texelFetch(u_slots, 4 * v_slot + (i)).xyz
#define DIFFUSE texelFetch(u_slots, 4 * v_slot + 3)
#define HAS_TEXTURE (texelFetch(u_slots, 4 * v_slot).w != 0.0)
)";
const char* kBoundFlat = R"(#version 450 core
flat in vec3 v_bound[3];
#define BOUND(i) v_bound[i]
)";

// Fragment depth from the entry-depth planes: where the ray through the
// fragment's pixel centre enters the box. Shared by every fragment shader
// that draws geometry.
const char* kDepthPlanes = R"(
uniform vec2 u_ndc_scale;
float entryDepth() {
  vec3 p = vec3(gl_FragCoord.xy * u_ndc_scale - 1.0, 1.0);
  precise float d = min(min(dot(BOUND(0), p), dot(BOUND(1), p)), dot(BOUND(2), p));
  return d;
}
)";

// For the shaders that draw geometry (shading, depth and id): a fragment
// nearer than its object's bound box's entry depth is dropped. Rasterisers
// interpolate depth from plane equations that, for a sliver triangle seen
// almost edge-on, can put a covered pixel far nearer than any of the
// triangle's vertices (seen on llvmpipe: 14 m in front of its object's box
// at 200 m). Dropped, no fragment of an object lies in front of its box,
// which the occlusion tests' exactness rests on; every other fragment keeps
// its interpolated depth, as the bound box is wider than the object's. A ray
// that misses the box gives entry depth 0: its fragments are dropped too,
// as are those at depth 0 or behind (reversed-Z), which could never pass
// GL_GREATER against the cleared 0 but could tie with it under GL_EQUAL.
// Discarding rather than writing gl_FragDepth (a clamp, until 2026-12-04)
// keeps the depth test before the shader on llvmpipe, so hidden fragments
// are not shaded (docs/benchmarks.md, "Depth bound by discard").
const char* kBoundedDepth = R"(
bool outsideBound() {
  float z = gl_FragCoord.z;
  return !(z > 0.0 && z <= entryDepth());
}
)";

// Two-sided headlight shading. Without normals, the facet normal comes from
// screen-space derivatives of the eye position (flat shading).
const char* kFragmentShader = R"(
uniform sampler2D u_tex;
in vec3 v_eye;
in vec3 v_nrm;
in vec4 v_col;
in vec2 v_uv;
out vec4 o_color;
void main() {
  // Meshes without normals get (0,0,0) and fall back to the facet normal.
  vec3 n = dot(v_nrm, v_nrm) > 1e-12 ? v_nrm : cross(dFdx(v_eye), dFdy(v_eye));
  float ln = length(n);
  n = ln > 0.0 ? n / ln : vec3(0.0, 0.0, 1.0);
  float le = length(v_eye);
  vec3 v = le > 0.0 ? -v_eye / le : vec3(0.0, 0.0, 1.0);
  float lambert = abs(dot(n, v));
  vec4 base = DIFFUSE * v_col;
  if (HAS_TEXTURE) base *= texture(u_tex, v_uv);
  o_color = vec4(base.rgb * (0.3 + 0.7 * lambert), 1.0);
  // Last: the derivatives above (and the texture's) need the whole quad.
  if (outsideBound()) discard;
}
)";

const char* kBoxVertexShader = R"(#version 450 core
invariant gl_Position;
layout(location = 0) in vec3 a_pos;
uniform mat4 u_mv;
uniform mat4 u_proj;
uniform vec3 u_bound[3];
flat out vec3 v_bound[3];
void main() {
  vec4 e = u_mv * vec4(a_pos, 1.0);
  v_bound = u_bound;
  gl_Position = u_proj * e;
}
)";

const char* kIdFragmentShader = R"(
uniform vec4 u_color;
out vec4 o_color;
void main() {
  if (outsideBound()) discard;
  o_color = u_color;
}
)";

// Query boxes keep the interpolated depth: writing the planes' depth here
// too (robust even for a box face seen edge-on) made the visibility stage's
// query pass 1.5x slower on llvmpipe, where a shader that writes depth loses
// the early depth test (docs/benchmarks.md, "Depth bound").
const char* kBoxFragmentShader = R"(#version 450 core
out vec4 o_color;
void main() { o_color = vec4(1.0); }
)";

// `parts` are concatenated; the first holds the #version line.
GLuint compile(const GlApi& gl, GLenum type, std::initializer_list<const char*> parts) {
  GLuint s = gl.CreateShader(type);
  gl.ShaderSource(s, GLsizei(parts.size()), parts.begin(), nullptr);
  gl.CompileShader(s);
  GLint ok = 0;
  gl.GetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetShaderInfoLog(s, sizeof log, nullptr, log);
    gl.DeleteShader(s);
    throw Error(std::string("shader compile failed: ") + log);
  }
  return s;
}

GLuint link(const GlApi& gl, const char* vsSrc, std::initializer_list<const char*> fsParts) {
  GLuint vs = compile(gl, GL_VERTEX_SHADER, {vsSrc});
  GLuint fs = compile(gl, GL_FRAGMENT_SHADER, fsParts);
  GLuint program = gl.CreateProgram();
  gl.AttachShader(program, vs);
  gl.AttachShader(program, fs);
  gl.LinkProgram(program);
  gl.DeleteShader(vs);
  gl.DeleteShader(fs);
  GLint ok = 0;
  gl.GetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    gl.GetProgramInfoLog(program, sizeof log, nullptr, log);
    gl.DeleteProgram(program);
    throw Error(std::string("shader link failed: ") + log);
  }
  return program;
}

void toFloat(const Mat4d& m, float out[16]) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) out[c * 4 + r] = float(m.at(r, c));
}

}  // namespace

Renderer::Renderer(const GlApi& gl, int width, int height)
    : gl_(gl), width_(width), height_(height) {
  if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
    throw Error("image size " + std::to_string(width) + "x" + std::to_string(height) +
                " out of range (1 to 16384)");
  gl_.GenFramebuffers(1, &fbo_);
  gl_.GenRenderbuffers(1, &color_rb_);
  gl_.GenRenderbuffers(1, &depth_rb_);
  gl_.BindRenderbuffer(GL_RENDERBUFFER, color_rb_);
  gl_.RenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
  gl_.BindRenderbuffer(GL_RENDERBUFFER, depth_rb_);
  gl_.RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height);
  gl_.BindFramebuffer(GL_FRAMEBUFFER, fbo_);
  gl_.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_rb_);
  gl_.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_rb_);
  if (gl_.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw Error("the frame's framebuffer is incomplete");

  program_ = link(gl_, kVertexShader, {kBoundSlot, kDepthPlanes, kBoundedDepth, kFragmentShader});
  box_program_ = link(gl_, kBoxVertexShader, {kBoxFragmentShader});
  id_program_ =
      link(gl_, kBoxVertexShader, {kBoundFlat, kDepthPlanes, kBoundedDepth, kIdFragmentShader});
  u_slot_ = gl_.GetUniformLocation(program_, "u_slot");
  u_id_bound_ = gl_.GetUniformLocation(id_program_, "u_bound");
  for (GLuint p : {program_, id_program_}) {
    gl_.UseProgram(p);
    gl_.Uniform2f(gl_.GetUniformLocation(p, "u_ndc_scale"), 2.f / float(width),
                  2.f / float(height));
  }
  u_id_mv_ = gl_.GetUniformLocation(id_program_, "u_mv");
  u_id_proj_ = gl_.GetUniformLocation(id_program_, "u_proj");
  u_id_color_ = gl_.GetUniformLocation(id_program_, "u_color");
  u_box_mv_ = gl_.GetUniformLocation(box_program_, "u_mv");
  u_box_proj_ = gl_.GetUniformLocation(box_program_, "u_proj");
  // The unit cube [-1, 1]^3 that query boxes scale and place.
  const float corners[24] = {-1, -1, -1, 1, -1, -1, -1, 1, -1, 1, 1, -1,
                             -1, -1, 1,  1, -1, 1,  -1, 1, 1,  1, 1, 1};
  const GLuint faces[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                            2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  gl_.GenVertexArrays(1, &box_vao_);
  gl_.BindVertexArray(box_vao_);
  gl_.GenBuffers(2, box_buffers_);
  gl_.BindBuffer(GL_ARRAY_BUFFER, box_buffers_[0]);
  gl_.BufferData(GL_ARRAY_BUFFER, sizeof corners, corners, GL_STATIC_DRAW);
  gl_.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
  gl_.EnableVertexAttribArray(0);
  gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, box_buffers_[1]);
  gl_.BufferData(GL_ELEMENT_ARRAY_BUFFER, sizeof faces, faces, GL_STATIC_DRAW);
  // queryBoxes: the same faces over a stream of eye-space corners.
  gl_.GenVertexArrays(1, &batch_vao_);
  gl_.BindVertexArray(batch_vao_);
  gl_.GenBuffers(1, &batch_buffer_);
  gl_.BindBuffer(GL_ARRAY_BUFFER, batch_buffer_);
  gl_.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, nullptr);
  gl_.EnableVertexAttribArray(0);
  gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, box_buffers_[1]);
  gl_.BindVertexArray(0);
  u_mv_ = gl_.GetUniformLocation(program_, "u_mv");
  u_proj_ = gl_.GetUniformLocation(program_, "u_proj");
  u_nrm_ = gl_.GetUniformLocation(program_, "u_nrm");
  u_tex_ = gl_.GetUniformLocation(program_, "u_tex");

  gl_.GenBuffers(1, &slot_buffer_);
  gl_.BindBuffer(GL_TEXTURE_BUFFER, slot_buffer_);
  const GLbitfield map = GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  gl_.BufferStorage(GL_TEXTURE_BUFFER, GLsizeiptr(kDrawSlots * sizeof(DrawSlot)), nullptr, map);
  slots_ = static_cast<DrawSlot*>(
      gl_.MapBufferRange(GL_TEXTURE_BUFFER, 0, GLsizeiptr(kDrawSlots * sizeof(DrawSlot)), map));
  if (!slots_) throw Error("could not map the draw slots' buffer");
  gl_.GenTextures(1, &slot_texture_);
  gl_.ActiveTexture(GL_TEXTURE0 + kSlotUnit);
  gl_.BindTexture(GL_TEXTURE_BUFFER, slot_texture_);
  gl_.TexBuffer(GL_TEXTURE_BUFFER, GL_RGBA32F, slot_buffer_);
  gl_.ActiveTexture(GL_TEXTURE0);
  gl_.UseProgram(program_);
  gl_.Uniform1i(gl_.GetUniformLocation(program_, "u_slots"), kSlotUnit);
  gl_.ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  gl_.Enable(GL_DEPTH_TEST);
  gl_.DepthFunc(GL_GREATER);
  gl_.Enable(GL_SCISSOR_TEST);
  gl_.Viewport(0, 0, width_, height_);
  gl_.PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl_.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
  gl_.GetIntegerv(GL_SUBPIXEL_BITS, &subpixel_bits_);
  gl_.GenBuffers(1, &stream_);
  gl_.check("renderer setup");
}

Renderer::~Renderer() {
  gl_.DeleteTextures(1, &slot_texture_);
  gl_.BindBuffer(GL_TEXTURE_BUFFER, slot_buffer_);
  gl_.UnmapBuffer(GL_TEXTURE_BUFFER);
  gl_.DeleteBuffers(1, &slot_buffer_);
  gl_.DeleteProgram(program_);
  gl_.DeleteProgram(box_program_);
  gl_.DeleteProgram(id_program_);
  gl_.DeleteBuffers(2, box_buffers_);
  gl_.DeleteVertexArrays(1, &box_vao_);
  gl_.DeleteBuffers(1, &batch_buffer_);
  gl_.DeleteBuffers(1, &stream_);
  gl_.DeleteVertexArrays(1, &batch_vao_);
  gl_.DeleteRenderbuffers(1, &color_rb_);
  gl_.DeleteRenderbuffers(1, &depth_rb_);
  gl_.DeleteFramebuffers(1, &fbo_);
}

GpuMesh Renderer::upload(const GeometryData& g) {
  GpuMesh m;
  m.submeshes = g.submeshes;
  m.triangles = g.triangleCount();
  m.vertices = g.vertexCount();
  gl_.GenVertexArrays(1, &m.vao);
  gl_.BindVertexArray(m.vao);
  gl_.GenBuffers(5, m.buffers);
  auto attrib = [&](int slot, const void* data, size_t bytes, GLint comps, GLenum type,
                    GLboolean norm) {
    if (bytes == 0) return;
    gl_.BindBuffer(GL_ARRAY_BUFFER, m.buffers[slot]);
    gl_.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(bytes), data, GL_STATIC_DRAW);
    gl_.VertexAttribPointer(slot, comps, type, norm, 0, nullptr);
    gl_.EnableVertexAttribArray(slot);
    m.bytes += bytes;
  };
  attrib(0, g.positions.data(), g.positions.size() * 4, 3, GL_FLOAT, GL_FALSE);
  attrib(1, g.normals.data(), g.normals.size() * 4, 3, GL_FLOAT, GL_FALSE);
  attrib(2, g.colors.data(), g.colors.size(), 4, GL_UNSIGNED_BYTE, GL_TRUE);
  attrib(3, g.texcoords.data(), g.texcoords.size() * 4, 2, GL_FLOAT, GL_FALSE);
  // Full indices, then the occluder level of detail's, in one buffer.
  std::vector<uint32_t> all = g.indices;
  all.insert(all.end(), g.lod_indices.begin(), g.lod_indices.end());
  m.lod_first = uint32_t(g.indices.size());
  m.lod_count = uint32_t(g.lod_indices.size());
  gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.buffers[4]);
  gl_.BufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(all.size() * 4), all.data(), GL_STATIC_DRAW);
  m.bytes += all.size() * 4;
  gl_.BindVertexArray(0);
  gl_.check("geometry upload");
  DMMR_CHECK(m.bytes == gpuBytes(g));
  return m;
}

uint64_t gpuBytes(const GeometryData& g) {
  return (g.positions.size() + g.normals.size() + g.texcoords.size() + g.indices.size() +
          g.lod_indices.size()) *
             4 +
         g.colors.size();
}

uint64_t gpuBytes(const TextureData& t) {
  return uint64_t(t.width) * t.height * 4 * 4 / 3 + 4;
}

void Renderer::release(GpuMesh& m) {
  gl_.DeleteBuffers(5, m.buffers);
  gl_.DeleteVertexArrays(1, &m.vao);
  m = GpuMesh{};
}

GLuint Renderer::uploadTexture(const TextureData& t) {
  GLuint id = 0;
  gl_.GenTextures(1, &id);
  gl_.BindTexture(GL_TEXTURE_2D, id);
  gl_.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, GLsizei(t.width), GLsizei(t.height), 0, GL_RGBA,
                 GL_UNSIGNED_BYTE, t.rgba.data());
  gl_.GenerateMipmap(GL_TEXTURE_2D);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, t.repeat_s ? GL_REPEAT : GL_CLAMP_TO_EDGE);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, t.repeat_t ? GL_REPEAT : GL_CLAMP_TO_EDGE);
  gl_.check("texture upload");
  return id;
}

void Renderer::releaseTexture(GLuint id) {
  gl_.DeleteTextures(1, &id);
}

void Renderer::beginFrame(const Camera& camera, const Rect& region, Rgb bg) {
  drained();  // a new frame's first batch goes out early again
  camera_ = camera;
  view_rotation_ = viewRotation(camera);
  gl_.BindFramebuffer(GL_FRAMEBUFFER, fbo_);
  gl_.Viewport(0, 0, width_, height_);
  gl_.Scissor(region.x, region.y, region.w, region.h);
  scissor_ = region;
  gl_.DepthMask(GL_TRUE);
  gl_.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  gl_.DepthFunc(GL_GREATER);
  gl_.ClearColor(bg.r, bg.g, bg.b, 1.f);
  gl_.ClearDepth(0.0);
  gl_.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl_.UseProgram(program_);
  float proj[16];
  toFloat(projectionMatrix(camera), proj);
  gl_.UniformMatrix4fv(u_proj_, 1, GL_FALSE, proj);
  gl_.Uniform1i(u_tex_, 0);
  gl_.VertexAttrib4f(1, 0.f, 0.f, 0.f, 0.f);  // used when a mesh has no normals
  gl_.VertexAttrib4f(2, 1.f, 1.f, 1.f, 1.f);  // ... no colours
  gl_.VertexAttrib4f(3, 0.f, 0.f, 0.f, 1.f);  // ... no texture coordinates
  // Bound per frame, as another Renderer may share the context.
  gl_.ActiveTexture(GL_TEXTURE0 + kSlotUnit);
  gl_.BindTexture(GL_TEXTURE_BUFFER, slot_texture_);
  gl_.ActiveTexture(GL_TEXTURE0);
}

void Renderer::beginDepthFrame(const Camera& camera, const Rect& region) {
  beginFrame(camera, region);
  gl_.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
}

void Renderer::beginQueries() {
  gl_.UseProgram(box_program_);
  float proj[16];
  toFloat(projectionMatrix(camera_), proj);
  gl_.UniformMatrix4fv(u_box_proj_, 1, GL_FALSE, proj);
  gl_.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  gl_.DepthMask(GL_FALSE);
  gl_.DepthFunc(GL_GEQUAL);
  // Front faces only (GL's default cull state: back faces, counter-clockwise
  // front; the cube's faces wind outward): with the eye outside a box, any
  // fragment of its contents lies behind a front face of the box at that
  // pixel, so the back faces add fill and prove nothing. Halves the
  // rasteriser's work per query.
  gl_.Enable(GL_CULL_FACE);
  gl_.BindVertexArray(box_vao_);
}

namespace {
// `box` widened by `part` of queryBoxBounds' margin.
Box3d widened(const Box3d& box, const Camera& camera, int height, double part) {
  Vec3d c = box.center() - camera.eye, h = box.extent() * 0.5;
  double far = length(c) + length(h);
  double pixel = far * 2 * std::tan(camera.fovy_deg * M_PI / 360.0) / height;
  double slack = (1e-5 * far + 1e-9 + pixel / 8) * part;
  double scale = 1 + 0.001 * part;
  Vec3d half{h.x * scale + slack, h.y * scale + slack, h.z * scale + slack};
  return Box3d{box.center() - half, box.center() + half};
}
}  // namespace

Box3d queryBoxBounds(const Box3d& box, const Camera& camera, int height) {
  return widened(box, camera, height, 1.0);
}

Box3d queryPartBounds(const Box3d& part, const Box3d& box, const Box3d& query_box) {
  return Box3d{part.lo - (box.lo - query_box.lo), part.hi + (query_box.hi - box.hi)};
}

Box3d depthBoundBox(const Box3d& box, const Camera& camera, int height) {
  return widened(box, camera, height, 0.5);
}

void Renderer::depthBoundPlanes(const Box3d& box, float k[9]) const {
  for (int i = 0; i < 9; ++i) k[i] = i % 3 == 2 ? float(kNoDepthBound) : 0.f;
  if (box.valid()) {
    EntryDepthPlanes p = entryDepthPlanes(box, camera_);
    for (int i = 0; i < 9; ++i) k[i] = float(p.k[size_t(i / 3)][size_t(i % 3)]);
  }
}

void Renderer::setDepthBound(GLint location, const Box3d& box) {
  float k[9];
  depthBoundPlanes(box, k);
  gl_.Uniform3fv(location, 3, k);
}

GLint Renderer::nextSlot() {
  // A slot is written once the draws that read the ring's earlier use of it
  // are done: the ring starts over only after a wait (waited()).
  if (next_slot_ == kDrawSlots) finish();
  return GLint(next_slot_++);
}

void Renderer::queryBox(const Box3d& box, GLuint query, GLenum target) {
  // Camera-relative placement in double (see queryBoxBounds for the margin).
  Box3d q = queryBoxBounds(box, camera_, height_);
  Vec3d c = q.center() - camera_.eye, half = q.extent() * 0.5;
  Mat4d mv = view_rotation_ * Mat4d::translate(c) * Mat4d::scale(half);
  float mvf[16];
  toFloat(mv, mvf);
  gl_.UniformMatrix4fv(u_box_mv_, 1, GL_FALSE, mvf);
  // An eye inside the box sees only back faces: draw them all then.
  bool inside = std::abs(c.x) <= half.x && std::abs(c.y) <= half.y && std::abs(c.z) <= half.z;
  if (inside) gl_.Disable(GL_CULL_FACE);
  gl_.BeginQuery(target, query);
  gl_.DrawElements(GL_TRIANGLES, 36, GL_UNSIGNED_INT, nullptr);
  gl_.EndQuery(target);
  if (inside) gl_.Enable(GL_CULL_FACE);
}

void Renderer::queryBoxes(const std::vector<Box3d>& boxes, const GLuint* queries, GLenum target) {
  batch_.resize(boxes.size() * 24);
  std::vector<char> inside(boxes.size(), 0);
  for (size_t i = 0; i < boxes.size(); ++i) {
    Box3d q = queryBoxBounds(boxes[i], camera_, height_);
    Vec3d c = q.center() - camera_.eye, half = q.extent() * 0.5;
    inside[i] = std::abs(c.x) <= half.x && std::abs(c.y) <= half.y && std::abs(c.z) <= half.z;
    for (int k = 0; k < 8; ++k) {  // the unit cube's corner order (x fastest)
      Vec3d corner{k & 1 ? half.x : -half.x, k & 2 ? half.y : -half.y, k & 4 ? half.z : -half.z};
      Vec3d e = view_rotation_.transformVector(c + corner);
      for (int j = 0; j < 3; ++j) batch_[i * 24 + size_t(k) * 3 + size_t(j)] = float(e[j]);
    }
  }
  gl_.BindVertexArray(batch_vao_);
  gl_.BindBuffer(GL_ARRAY_BUFFER, batch_buffer_);
  gl_.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(batch_.size() * sizeof(float)), batch_.data(),
                 GL_STREAM_DRAW);
  float identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  gl_.UniformMatrix4fv(u_box_mv_, 1, GL_FALSE, identity);
  for (size_t i = 0; i < boxes.size(); ++i) {
    // An eye inside a box sees only back faces (never in the client, which
    // takes boxes near the eye without a query).
    if (inside[i]) gl_.Disable(GL_CULL_FACE);
    gl_.BeginQuery(target, queries[i]);
    gl_.DrawElementsBaseVertex(GL_TRIANGLES, 36, GL_UNSIGNED_INT, nullptr, GLint(i * 8));
    gl_.EndQuery(target);
    if (inside[i]) gl_.Enable(GL_CULL_FACE);
  }
}

void Renderer::endQueries() {
  gl_.Disable(GL_CULL_FACE);
  gl_.BindVertexArray(0);
  gl_.DepthMask(GL_TRUE);
  gl_.DepthFunc(GL_GREATER);
  gl_.UseProgram(program_);
}

Mat4d Renderer::cameraRelative(const Mat4d& object_to_world) const {
  // Camera-relative in double: subtract the eye from the object's translation
  // before anything becomes float, so far-away scenes keep their precision.
  Mat4d rel = object_to_world;
  for (int i = 0; i < 3; ++i) rel.at(i, 3) -= camera_.eye[i];
  return view_rotation_ * rel;
}

void Renderer::beginIdFrame(const Camera& camera, const Rect& region) {
  beginFrame(camera, region, Rgb{0, 0, 0});
  gl_.UseProgram(id_program_);
  float proj[16];
  toFloat(projectionMatrix(camera_), proj);
  gl_.UniformMatrix4fv(u_id_proj_, 1, GL_FALSE, proj);
}

void Renderer::drawId(const GpuMesh& mesh, const Mat4d& object_to_world, const Box3d& bounds,
                      uint32_t id) {
  float mvf[16];
  toFloat(cameraRelative(object_to_world), mvf);
  uint32_t v = id + 1;
  float color[4] = {float(v & 0xFF) / 255.f, float((v >> 8) & 0xFF) / 255.f,
                    float((v >> 16) & 0xFF) / 255.f, 1.f};
  gl_.UniformMatrix4fv(u_id_mv_, 1, GL_FALSE, mvf);
  gl_.Uniform4fv(u_id_color_, 1, color);
  setDepthBound(u_id_bound_, bounds.valid() ? depthBoundBox(bounds, camera_, height_) : bounds);
  gl_.BindVertexArray(mesh.vao);
  for (const SubMesh& s : mesh.submeshes)
    gl_.DrawElements(GL_TRIANGLES, GLsizei(s.index_count), GL_UNSIGNED_INT,
                     reinterpret_cast<const void*>(uintptr_t(s.first_index) * 4));
  gl_.BindVertexArray(0);
}

uint64_t Renderer::drawIndices(uint32_t first, uint32_t count) {
  gl_.DrawElements(GL_TRIANGLES, GLsizei(count), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(uintptr_t(first) * 4));
  submitted(count);
  return count;
}

bool partsMatch(const GeometryParts& parts, const GpuMesh& mesh) {
  if (!parts.ordered()) return true;
  size_t n = parts.parts.size();
  if (parts.triangles.size() != n * mesh.submeshes.size()) return false;
  for (size_t s = 0; s < mesh.submeshes.size(); ++s) {
    uint64_t sum = 0;
    for (size_t k = 0; k < n; ++k) sum += parts.triangles[s * n + k];
    if (3 * sum != mesh.submeshes[s].index_count) return false;
  }
  return true;
}

namespace {

// Calls f(first_index, index_count) for each run of consecutive selected
// parts of submesh `s` (number `si`), in index order; once for the whole
// submesh when everything is selected or the parts are not ordered.
template <typename F>
void forEachRange(const SubMesh& s, size_t si, const PartDraw& sel, F&& f) {
  const GeometryParts* p = sel.parts;
  size_t n = p ? p->parts.size() : 0;
  uint32_t all = (1u << n) - 1;
  if (!p || !p->ordered() || (sel.mask & all) == all) {
    f(s.first_index, s.index_count);
    return;
  }
  const uint32_t* counts = p->triangles.data() + si * n;
  uint32_t at = s.first_index, run_first = 0, run_count = 0;
  for (size_t k = 0; k < n; ++k) {
    uint32_t count = 3 * counts[k];
    if (sel.mask >> k & 1) {
      if (run_count == 0) run_first = at;
      run_count += count;
    } else if (run_count > 0) {
      f(run_first, run_count);
      run_count = 0;
    }
    at += count;
  }
  if (run_count > 0) f(run_first, run_count);
}

}  // namespace

uint64_t Renderer::drawDepth(const GpuMesh& mesh, const Mat4d& object_to_world, const Box3d& bounds,
                             bool lod, PartDraw parts) {
  // The position-only program: its vertex transform is the same expression as
  // the shading program's, with gl_Position invariant in both, so depth
  // matches the render pass, while the fragment work (lighting, derivatives)
  // is skipped.
  gl_.UseProgram(id_program_);
  float proj[16], mvf[16];
  toFloat(projectionMatrix(camera_), proj);
  toFloat(cameraRelative(object_to_world), mvf);
  gl_.UniformMatrix4fv(u_id_proj_, 1, GL_FALSE, proj);
  gl_.UniformMatrix4fv(u_id_mv_, 1, GL_FALSE, mvf);
  setDepthBound(u_id_bound_, bounds.valid() ? depthBoundBox(bounds, camera_, height_) : bounds);
  gl_.BindVertexArray(mesh.vao);
  ranges_.clear();
  if (lod && mesh.lod_count > 0)
    ranges_.push_back({0, mesh.lod_first, mesh.lod_count});
  else
    for (size_t i = 0; i < mesh.submeshes.size(); ++i)
      forEachRange(mesh.submeshes[i], i, parts, [&](uint32_t first, uint32_t count) {
        ranges_.push_back({i, first, count});
      });
  uint64_t indices = 0;
  for (const IndexRange& r : ranges_) indices += r.count;
  bool culled = cullRanges(mesh, object_to_world, bounds, &ranges_);
  for (const IndexRange& r : ranges_)
    if (r.count > 0) drawIndices(r.first, r.count);
  if (culled) restoreElements(mesh);
  gl_.BindVertexArray(0);
  return indices / 3;
}

uint64_t Renderer::draw(const GpuMesh& mesh, const Mat4d& object_to_world, const Box3d& bounds,
                        const std::vector<GLuint>& textures, PartDraw parts) {
  Mat4d mv = cameraRelative(object_to_world);
  Mat4d inv;
  float mvf[16], nrm[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  toFloat(mv, mvf);
  if (invertAffine(mv, &inv))  // normal matrix = inverse transpose of the 3x3
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) nrm[c * 3 + r] = float(inv.at(c, r));
  gl_.UniformMatrix4fv(u_mv_, 1, GL_FALSE, mvf);
  gl_.UniformMatrix3fv(u_nrm_, 1, GL_FALSE, nrm);
  float planes[9];
  depthBoundPlanes(bounds.valid() ? depthBoundBox(bounds, camera_, height_) : bounds, planes);
  gl_.BindVertexArray(mesh.vao);
  ranges_.clear();
  for (size_t i = 0; i < mesh.submeshes.size(); ++i)
    forEachRange(mesh.submeshes[i], i, parts, [&](uint32_t first, uint32_t count) {
      ranges_.push_back({i, first, count});
    });
  uint64_t indices = 0;
  for (const IndexRange& r : ranges_) indices += r.count;
  bool culled = cullRanges(mesh, object_to_world, bounds, &ranges_);
  size_t next = 0;  // ranges_ are in submesh order
  for (size_t i = 0; i < mesh.submeshes.size(); ++i) {
    const SubMesh& s = mesh.submeshes[i];
    bool tex = s.texture >= 0 && size_t(s.texture) < textures.size();
    GLint slot = nextSlot();
    DrawSlot& d = slots_[slot];
    for (int k = 0; k < 3; ++k) {
      std::memcpy(d.v[k], planes + 3 * k, 3 * sizeof(float));
      d.v[k][3] = k == 0 && tex ? 1.f : 0.f;
    }
    std::memcpy(d.v[3], s.diffuse, sizeof d.v[3]);
    gl_.Uniform1i(u_slot_, slot);
    if (tex) {
      gl_.ActiveTexture(GL_TEXTURE0);
      gl_.BindTexture(GL_TEXTURE_2D, textures[size_t(s.texture)]);
    }
    for (; next < ranges_.size() && ranges_[next].submesh == i; ++next)
      if (ranges_[next].count > 0) drawIndices(ranges_[next].first, ranges_[next].count);
  }
  if (culled) restoreElements(mesh);
  gl_.BindVertexArray(0);
  return indices / 3;
}

bool Renderer::cullRanges(const GpuMesh& mesh, const Mat4d& object_to_world, const Box3d& bounds,
                          std::vector<IndexRange>* ranges) {
  if (!triangle_cull_ || mesh.vertices == 0) return false;
  uint64_t selected = 0;
  for (const IndexRange& r : *ranges) selected += r.count / 3;
  if (selected < kCullMinTriangles) return false;
  const Mat4d mv = cameraRelative(object_to_world);
  const Mat4d proj = projectionMatrix(camera_);
  // Worth it only where triangles are small: the box's window rectangle
  // (within the scissor) per selected triangle. A box reaching behind the
  // eye is near, so its triangles are not small.
  if (bounds.valid()) {
    const Mat4d to_clip = proj * viewRotation(camera_);
    double lx = 1e300, ly = 1e300, hx = -1e300, hy = -1e300;
    for (int k = 0; k < 8; ++k) {
      Vec3d c{(k & 1 ? bounds.hi : bounds.lo).x - camera_.eye.x,
              (k & 2 ? bounds.hi : bounds.lo).y - camera_.eye.y,
              (k & 4 ? bounds.hi : bounds.lo).z - camera_.eye.z};
      double w = to_clip.at(3, 0) * c.x + to_clip.at(3, 1) * c.y + to_clip.at(3, 2) * c.z;
      if (!(w > 0)) return false;
      double x = (to_clip.at(0, 0) * c.x + to_clip.at(0, 1) * c.y + to_clip.at(0, 2) * c.z) / w;
      double y = (to_clip.at(1, 0) * c.x + to_clip.at(1, 1) * c.y + to_clip.at(1, 2) * c.z) / w;
      x = (x + 1) * 0.5 * width_;
      y = (y + 1) * 0.5 * height_;
      lx = std::min(lx, x), hx = std::max(hx, x), ly = std::min(ly, y), hy = std::max(hy, y);
    }
    double w = std::min(hx, double(scissor_.x1())) - std::max(lx, double(scissor_.x));
    double h = std::min(hy, double(scissor_.y1())) - std::max(ly, double(scissor_.y));
    double area = std::max(0.0, w) * std::max(0.0, h);
    if (area > kCullPixelsPerTriangle * double(selected)) return false;
  }
  // The vertices as the draw will place them.
  gl_.BindBuffer(GL_COPY_READ_BUFFER, mesh.buffers[0]);
  const auto* positions = static_cast<const float*>(
      gl_.MapBufferRange(GL_COPY_READ_BUFFER, 0, GLsizeiptr(mesh.vertices * 12), GL_MAP_READ_BIT));
  if (!positions) {
    gl_.check("mapping positions for triangle culling");
    return false;
  }
  WindowTransform t{mv, proj, width_, height_, subpixel_bits_};
  projectVertices(positions, mesh.vertices, t, &window_);
  gl_.UnmapBuffer(GL_COPY_READ_BUFFER);
  // The kept triangles of every range, appended to the stream.
  const size_t bytes = size_t(selected) * 12;
  if (stream_at_ + bytes > stream_capacity_) {
    stream_capacity_ = std::max(stream_capacity_, std::max<size_t>(bytes, size_t(4) << 20));
    gl_.BindBuffer(GL_COPY_WRITE_BUFFER, stream_);
    gl_.BufferData(GL_COPY_WRITE_BUFFER, GLsizeiptr(stream_capacity_), nullptr, GL_STREAM_DRAW);
    stream_at_ = 0;
  }
  gl_.BindBuffer(GL_COPY_READ_BUFFER, mesh.buffers[4]);
  const auto* indices = static_cast<const uint32_t*>(gl_.MapBufferRange(
      GL_COPY_READ_BUFFER, 0, GLsizeiptr((mesh.lod_first + mesh.lod_count) * 4), GL_MAP_READ_BIT));
  gl_.BindBuffer(GL_COPY_WRITE_BUFFER, stream_);
  // Unsynchronised: this range of the stream was never drawn from since it
  // was last orphaned.
  auto* out = static_cast<uint32_t*>(gl_.MapBufferRange(
      GL_COPY_WRITE_BUFFER, GLintptr(stream_at_), GLsizeiptr(bytes),
      GL_MAP_WRITE_BIT | GL_MAP_INVALIDATE_RANGE_BIT | GL_MAP_UNSYNCHRONIZED_BIT));
  if (!indices || !out) {
    if (indices) gl_.UnmapBuffer(GL_COPY_READ_BUFFER);
    if (out) gl_.UnmapBuffer(GL_COPY_WRITE_BUFFER);
    gl_.check("mapping indices for triangle culling");
    return false;
  }
  size_t at = 0;
  for (IndexRange& r : *ranges) {
    size_t kept = keepCoveringTriangles(indices + r.first, r.count, window_, scissor_, out + at);
    triangles_culled_ += (r.count - kept) / 3;
    r.first = uint32_t(stream_at_ / 4 + at);
    r.count = uint32_t(kept);
    at += kept;
  }
  gl_.UnmapBuffer(GL_COPY_WRITE_BUFFER);
  gl_.UnmapBuffer(GL_COPY_READ_BUFFER);
  stream_at_ += at * 4;
  gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, stream_);  // the bound VAO's
  gl_.check("triangle culling");
  return true;
}

void Renderer::restoreElements(const GpuMesh& mesh) {
  gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, mesh.buffers[4]);
}

void Renderer::readPixels(const Rect& region, std::vector<uint8_t>* rgba) {
  rgba->resize(size_t(region.area()) * 4);
  gl_.BindFramebuffer(GL_FRAMEBUFFER, fbo_);
  gl_.ReadPixels(region.x, region.y, region.w, region.h, GL_RGBA, GL_UNSIGNED_BYTE, rgba->data());
  waited();
  gl_.check("readPixels");
}

void Renderer::readDepth(const Rect& region, std::vector<float>* depth) {
  depth->resize(size_t(region.area()));
  gl_.BindFramebuffer(GL_FRAMEBUFFER, fbo_);
  gl_.ReadPixels(region.x, region.y, region.w, region.h, GL_DEPTH_COMPONENT, GL_FLOAT,
                 depth->data());
  waited();
  gl_.check("readDepth");
}

void Renderer::beginRedraw(const Rect& rect, Rgb bg) {
  gl_.Scissor(rect.x, rect.y, rect.w, rect.h);
  scissor_ = rect;
  gl_.DepthMask(GL_TRUE);
  gl_.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  gl_.ClearColor(bg.r, bg.g, bg.b, 1.f);
  gl_.ClearDepth(0.0);
  gl_.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl_.UseProgram(program_);
}

void Renderer::beginEqualPass(bool color, GLenum target, GLuint query) {
  GLboolean c = color ? GL_TRUE : GL_FALSE;
  if (color) gl_.UseProgram(program_);  // draw() shades with it
  gl_.ColorMask(c, c, c, c);
  gl_.DepthMask(GL_FALSE);
  gl_.DepthFunc(GL_EQUAL);
  gl_.BeginQuery(target, query);
}

void Renderer::endEqualPass(GLenum target) {
  gl_.EndQuery(target);
  gl_.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  gl_.DepthMask(GL_TRUE);
  gl_.DepthFunc(GL_GREATER);
  gl_.UseProgram(program_);
}

void Renderer::beginDepthEqualQuery(GLuint query) {
  beginEqualPass(false, GL_ANY_SAMPLES_PASSED, query);
}
void Renderer::endDepthEqualQuery() {
  endEqualPass(GL_ANY_SAMPLES_PASSED);
}
void Renderer::beginEqualColorPass(GLuint query) {
  beginEqualPass(true, GL_SAMPLES_PASSED, query);
}
void Renderer::endEqualColorPass() {
  endEqualPass(GL_SAMPLES_PASSED);
}

void Renderer::maskColor(bool masked) {
  GLboolean on = masked ? GL_FALSE : GL_TRUE;
  gl_.ColorMask(on, on, on, on);
  if (!masked) gl_.UseProgram(program_);
}

namespace {
bool cpuRasteriser(const GlApi& gl) {
  const char* name = reinterpret_cast<const char*>(gl.GetString(GL_RENDERER));
  return name && (std::strstr(name, "llvmpipe") || std::strstr(name, "softpipe"));
}
}  // namespace

uint64_t defaultFlushTriangles(const GlApi& gl) {
  return cpuRasteriser(gl) ? kFlushTrianglesCpu : 0;
}

bool defaultTriangleCull(const GlApi& gl) {
  return cpuRasteriser(gl);
}

void Renderer::submitted(uint64_t indices) {
  unflushed_ += indices / 3;
  triangles_submitted_ += indices / 3;
  if (flush_every_ && unflushed_ >= next_flush_) {
    gl_.Flush();
    unflushed_ = 0;
    next_flush_ = std::min(next_flush_ * 2, 4 * flush_every_);
    ++flushes_;
  }
}

void Renderer::finish() {
  gl_.Finish();
  waited();
}

}  // namespace dmmr
