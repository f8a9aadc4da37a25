// The drawing code shared by dmmr-reference and the clients, so that both
// produce the same pixels for the same objects.
//
// Every frame is drawn with the full frame's viewport and projection; a
// region is restricted with a scissor rectangle only. On llvmpipe this
// reproduces the full render exactly, where an off-axis sub-frustum does not.
// Depth is reversed-Z into a 32-bit float buffer (GL_GREATER, cleared to 0),
// with an infinite far plane. Object transforms are composed with the camera
// in double precision and made camera-relative before the float conversion.
// Objects are drawn in ascending object index by callers so that depth ties
// resolve the same way whatever subset a renderer draws.
#pragma once

#include <cstdint>
#include <vector>

#include "camera.h"
#include "coverage.h"
#include "formats.h"
#include "gl_api.h"

namespace dmmr {

struct GpuMesh {
  GLuint vao = 0;
  GLuint buffers[5] = {};  // positions, normals, colors, texcoords, indices
  std::vector<SubMesh> submeshes;
  // The occluder level of detail's range in the index buffer (count 0: none).
  uint32_t lod_first = 0, lod_count = 0;
  uint64_t bytes = 0;  // GPU memory held (buffers only)
  uint64_t triangles = 0;
  uint64_t vertices = 0;
};

// GPU memory Renderer::upload takes for `g` (its buffers), known before the
// upload so a cache can make room first.
uint64_t gpuBytes(const GeometryData& g);
// ... and uploadTexture for `t` (RGBA8 with its mipmap chain, at most 4/3).
uint64_t gpuBytes(const TextureData& t);

// The box an occlusion query on `box` draws: `box` widened so that, after
// float rounding and the rasteriser snapping vertices to its sub-pixel grid,
// its front faces still lie in front of everything inside it and its
// outline still covers every pixel centre the contents can cover: half
// extents * 1.001, plus 1e-5 of the distance to its far side (depth
// rounding), plus an eighth of a pixel at that distance for a frame
// `height` pixels high (llvmpipe snaps to 1/256 pixel; a sub-pixel object
// widened by 0.1% alone could cover a pixel centre its box missed).
Box3d queryBoxBounds(const Box3d& box, const Camera& camera, int height);
// A part of an object (a box within its box `box` holding some of its
// triangles whole) widened by the margins that `query_box`
// (queryBoxBounds(box, ...)) adds to `box` on each side: the rounding those
// margins cover is that of the object's vertices, so the part's outline
// covers every pixel centre its triangles can cover.
Box3d queryPartBounds(const Box3d& part, const Box3d& box, const Box3d& query_box);
// The box whose entry depth bounds every fragment of an object (the shaders'
// outsideBound drops the rest): `box` widened by half of queryBoxBounds' margin, so that it
// still encloses the object after rounding, while the query box's rasterised
// front faces stay in front of it by the other half.
Box3d depthBoundBox(const Box3d& box, const Camera& camera, int height);

// Which of a mesh's triangles a draw takes: every one, or, where its
// geometry's triangles are grouped by part (GeometryParts::ordered), only
// those of the parts in `mask` (bit k: part k). `parts` must match the mesh
// (partsMatch); the caller checks, since only it knows the files.
inline constexpr uint8_t kAllParts = 0xFF;
struct PartDraw {
  const GeometryParts* parts = nullptr;
  uint8_t mask = kAllParts;
};
// Whether `parts` describes `mesh`'s submeshes: one row of part triangle
// counts per submesh, each row summing to the submesh's triangles. True when
// `parts` is not ordered (it is then never used to select).
bool partsMatch(const GeometryParts& parts, const GpuMesh& mesh);

struct Rgb {
  float r = 0.2f, g = 0.22f, b = 0.26f;
};

// The flush interval setFlushEvery should get for this context's driver by
// default: kFlushTrianglesCpu on a CPU rasteriser (llvmpipe, softpipe),
// whose binning and rasterisation then overlap; 0 elsewhere (a GPU driver
// batches its own submissions).
inline constexpr uint64_t kFlushTrianglesCpu = 4096;
uint64_t defaultFlushTriangles(const GlApi& gl);
// Whether triangle culling (Renderer::setTriangleCull) is on by default for
// this context's driver: on a CPU rasteriser (llvmpipe, softpipe), which
// sets up and bins every triangle, even those covering no pixel centre, at
// a cost above the test's; off elsewhere (a GPU discards them in hardware).
bool defaultTriangleCull(const GlApi& gl);
// A --triangle-cull setting (-1: auto, 0: off, 1: on) as setTriangleCull takes it.
inline bool triangleCullFor(const GlApi& gl, int option) {
  return option < 0 ? defaultTriangleCull(gl) : option != 0;
}
// A --flush-triangles setting (-1: auto) as setFlushEvery takes it.
inline uint64_t flushTrianglesFor(const GlApi& gl, int64_t option) {
  return option < 0 ? defaultFlushTriangles(gl) : uint64_t(option);
}

class Renderer {
 public:
  // Needs a current GL 4.5 context; creates the frame's FBO and the program.
  Renderer(const GlApi& gl, int width, int height);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  int width() const { return width_; }
  int height() const { return height_; }

  GpuMesh upload(const GeometryData& g);
  void release(GpuMesh& m);
  GLuint uploadTexture(const TextureData& t);
  void releaseTexture(GLuint id);

  // Clears `region` (colour and depth) and sets the camera for the draws that
  // follow. The viewport is always the full frame; `region` is the scissor.
  void beginFrame(const Camera& camera, const Rect& region, Rgb background = {});
  // Like beginFrame, but only depth is written (colour masked): the
  // visibility stage's occluder pass, drawn with draw() so that its depth
  // equals the render pass's bit for bit.
  void beginDepthFrame(const Camera& camera, const Rect& region);

  // Occlusion queries of boxes against the depth drawn so far, within the
  // frame's region: depth test GEQUAL (a tie counts as visible), no colour or
  // depth writes. Each box is widened slightly so that it stays in front of
  // what it encloses despite rounding. `target` is GL_ANY_SAMPLES_PASSED or
  // GL_SAMPLES_PASSED.
  void beginQueries();
  void queryBox(const Box3d& world_box, GLuint query, GLenum target);
  // The same for many boxes, `queries[i]` for `boxes[i]`, with no state
  // change between queries: every box's corners go into one buffer, placed
  // relative to the camera in double first, and each query draws its 8 with
  // a base vertex. Between beginQueries and endQueries.
  void queryBoxes(const std::vector<Box3d>& world_boxes, const GLuint* queries, GLenum target);
  void endQueries();

  // Object-id frames: each object drawn flat in the colour id + 1 (24 bits,
  // 0 is background) with the same vertex transform and depth test as draw(),
  // so that the id buffer says which object owns each pixel of the frame.
  void beginIdFrame(const Camera& camera, const Rect& region);
  void drawId(const GpuMesh& mesh, const Mat4d& object_to_world, const Box3d& bounds, uint32_t id);

  // Draws an object into depth only (beginDepthFrame passes), the parts
  // `parts` selects or, with `lod`, its occluder level of detail where it has
  // one (an approximation, always whole). Returns the triangles submitted.
  uint64_t drawDepth(const GpuMesh& mesh, const Mat4d& object_to_world, const Box3d& bounds,
                     bool lod, PartDraw parts = {});

  // Draws one object, the parts `parts` selects (in the stored order, so a
  // subset draws its triangles in the order the whole draws them);
  // `textures` maps texture file indices to GL names. `bounds`: the object's
  // world box (ObjectBounds::box); no fragment is drawn in front of it
  // (depthBoundBox). An invalid box sets no bound. The same box must be
  // passed by every draw of the object for depth to agree. Returns the
  // triangles submitted.
  uint64_t draw(const GpuMesh& mesh, const Mat4d& object_to_world, const Box3d& bounds,
                const std::vector<GLuint>& textures, PartDraw parts = {});
  // Reads `region` as RGBA8, bottom row first (GL order).
  void readPixels(const Rect& region, std::vector<uint8_t>* rgba);
  // Reads `region`'s depth (reversed-Z floats, exactly as stored), bottom row
  // first: the depth-pyramid test's input.
  void readDepth(const Rect& region, std::vector<float>* depth);
  // Clears `rect` (colour and depth) and restricts the draws that follow to
  // it, keeping the camera and program of the frame: the fused stage's
  // redraw of the pixels newly visible objects may reach.
  void beginRedraw(const Rect& rect, Rgb background = {});
  // Counts, into `query` (GL_ANY_SAMPLES_PASSED), the fragments drawn with
  // drawDepth until endDepthEqualQuery whose depth equals the depth already
  // at their pixel; nothing is written. The frame's state comes back after.
  void beginDepthEqualQuery(GLuint query);
  void endDepthEqualQuery();
  // The draws that follow (draw()) write colour, and no depth, only where
  // their depth equals the depth already at the pixel, and count the
  // fragments that pass into `query` (GL_SAMPLES_PASSED): the fused stage's
  // colour pass over a depth the same objects drew with drawDepth. The
  // frame's state comes back after.
  void beginEqualColorPass(GLuint query);
  void endEqualColorPass();
  // Masks colour writes (drawDepth into a colour frame) or unmasks them.
  void maskColor(bool masked);
  void finish();
  // Flushes after the first `triangles` submitted by draw and drawDepth
  // since the frame began or the last wait (finish, a readback), then after
  // twice as many, then every four times as many (0: never; the caller's
  // finish or readback flushes). llvmpipe transforms and bins triangles on
  // the calling thread and rasterises them on its own threads only once
  // they are flushed, so without this the two alternate; flushed early, one
  // batch is rasterised while the next is binned. The batches grow because
  // each flush costs llvmpipe a new scene: a flush every 4096 triangles made
  // a brute-force frame of 10M triangles 40% slower, and batches doubling
  // without end left 1.5M triangles a frame mostly unoverlapped (36%
  // slower); capped at 4x, neither loses (docs/benchmarks.md, "Flushing
  // while drawing"). GL runs commands in order either way, so no pixel
  // changes.
  void setFlushEvery(uint64_t triangles) {
    flush_every_ = triangles;
    next_flush_ = triangles;
  }
  uint64_t flushEvery() const { return flush_every_; }

  // Exact triangle culling (coverage.h): with it on, draw() and drawDepth()
  // drop, before the draw, the triangles of a dense object that cover no
  // pixel centre of the scissor rectangle, which changes no pixel, depth or
  // query count. An object is culled so when its selected triangles are at
  // least kCullMinTriangles and its box covers under
  // kCullPixelsPerTriangle pixels of the rectangle per triangle; others are
  // drawn as they are. The meshes' positions and indices are read back from
  // their buffers (a mapping, no copy on a CPU rasteriser). The draws'
  // returned triangle counts stay those selected; trianglesCulled() counts
  // what the test dropped.
  static constexpr uint64_t kCullMinTriangles = 256;
  static constexpr double kCullPixelsPerTriangle = 4;
  void setTriangleCull(bool on) { triangle_cull_ = on; }
  bool triangleCull() const { return triangle_cull_; }
  uint64_t trianglesCulled() const { return triangles_culled_; }  // since construction
  // Triangles handed to the GL by every draw (depth and colour passes, after
  // the triangle cull), since construction: what the rasteriser set up.
  uint64_t trianglesSubmitted() const { return triangles_submitted_; }
  uint64_t flushes() const { return flushes_; }  // setFlushEvery's, since construction

  // draw() calls (one a submesh) a frame takes before it waits for the
  // draws in flight (a glFinish) to reuse their per-draw slots; a readback
  // or finish() frees them all.
  static constexpr size_t kDrawSlots = 16384;

 private:
  const GlApi& gl_;
  int width_, height_;
  GLuint fbo_ = 0, color_rb_ = 0, depth_rb_ = 0, program_ = 0;
  GLuint box_program_ = 0, box_vao_ = 0, box_buffers_[2] = {};
  GLuint batch_vao_ = 0, batch_buffer_ = 0;  // queryBoxes' corners
  std::vector<float> batch_;
  GLint u_box_mv_ = -1, u_box_proj_ = -1;
  GLuint id_program_ = 0;
  GLint u_id_mv_ = -1, u_id_proj_ = -1, u_id_color_ = -1;
  GLint u_mv_ = -1, u_proj_ = -1, u_nrm_ = -1, u_tex_ = -1, u_slot_ = -1;
  Camera camera_;
  Mat4d view_rotation_;
  GLint u_id_bound_ = -1;
  // The shading program's per-draw values, one slot a draw call, in a
  // persistently mapped ring that the fragment shader reads as a texel
  // buffer (texture unit kSlotUnit) at the slot a vertex shader uniform
  // passes on flat (why not uniforms: kBoundSlot in draw.cpp).
  struct DrawSlot {
    float v[4][4];  // entry-depth planes (xyz; v[0][3]: textured), diffuse
  };
  static constexpr int kSlotUnit = 1;
  GLuint slot_buffer_ = 0, slot_texture_ = 0;
  DrawSlot* slots_ = nullptr;  // persistently mapped
  size_t next_slot_ = 0;
  uint64_t unflushed_ = 0, flush_every_ = 0, next_flush_ = 0, flushes_ = 0;
  // Triangle culling: the current scissor rectangle, the rasteriser's
  // sub-pixel bits, a stream of culled index lists (appended to, orphaned
  // when full) and the projected vertices of the object being culled.
  bool triangle_cull_ = false;
  uint64_t triangles_culled_ = 0, triangles_submitted_ = 0;
  Rect scissor_;
  int subpixel_bits_ = 4;
  GLuint stream_ = 0;
  size_t stream_capacity_ = 0, stream_at_ = 0;  // bytes
  WindowVertices window_;
  // One draw call's index range: `count` indices from `first` of submesh
  // `submesh` (or of the bound element buffer).
  struct IndexRange {
    size_t submesh;
    uint32_t first, count;
  };
  // Replaces `ranges` of `mesh` (drawn with `object_to_world`, bounded by
  // `bounds`) by their culled copies in the stream and binds the stream as
  // the bound VAO's element buffer, returning true; returns false, changing
  // nothing, when the object is not worth culling. After the draws,
  // restoreElements(mesh) rebinds the mesh's own indices.
  bool cullRanges(const GpuMesh& mesh, const Mat4d& object_to_world, const Box3d& bounds,
                  std::vector<IndexRange>* ranges);
  void restoreElements(const GpuMesh& mesh);
  std::vector<IndexRange> ranges_;
  // A wait drained llvmpipe: the next flush comes after flush_every_ again.
  void drained() {
    unflushed_ = 0;
    next_flush_ = flush_every_;
  }
  // Every draw so far is done (finish, a readback): the slots are free.
  void waited() {
    drained();
    next_slot_ = 0;
  }
  // The next free draw slot; waits for the draws in flight when none is.
  GLint nextSlot();
  // Counts a draw call's triangles and flushes when flush_every_ are due.
  void submitted(uint64_t indices);
  // Draws `count` indices from `first` of the bound VAO (submitted() too);
  // returns count.
  uint64_t drawIndices(uint32_t first, uint32_t count);
  Mat4d cameraRelative(const Mat4d& object_to_world) const;
  // Depth test EQUAL, no depth writes, colour written or masked, counting
  // into `query` (`target`); the end restores the frame's state.
  void beginEqualPass(bool color, GLenum target, GLuint query);
  void endEqualPass(GLenum target);
  // Uploads `box`'s entry-depth planes for the current camera (an invalid
  // box: no bound) to the current program's u_bound.
  void setDepthBound(GLint location, const Box3d& box);
  // `box`'s entry-depth planes for the current camera, 3 by 3 (an invalid
  // box: no bound).
  void depthBoundPlanes(const Box3d& box, float k[9]) const;
};

}  // namespace dmmr
