// Which triangles can cover a pixel centre: exact triangle culling for
// dense meshes, over plain data (no GL).
//
// A GL rasteriser writes a fragment only at a sample point (here the pixel
// centre, no multisampling) inside a triangle, so a triangle whose window
// bounding box holds no pixel centre of the scissor rectangle writes
// nothing: no colour, no depth, no sample counted by a query. Dropping it
// before the draw changes no pixel. A scanned mesh seen whole has most of
// its triangles under a pixel; a CPU rasteriser (llvmpipe) still transforms,
// sets up and bins each one, which costs more than this test.
//
// The test must hold for the rasteriser's own arithmetic, which is float: a
// vertex's window position is known here only within an error radius,
// bounded from the magnitudes of the products the GPU sums (each float
// dot product is off by at most a few units in the last place of the sum
// of the magnitudes of its terms), plus one sub-pixel snapping step
// (GL_SUBPIXEL_BITS). A triangle is dropped only when its box widened by
// its vertices' radii still holds no pixel centre, or, for a box of a few
// centres, when no centre lies within its edges widened likewise. A vertex
// not safely in front of the eye (w near or below 0, where the projected
// box says nothing about the clipped triangle) keeps every triangle that
// uses it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "math.h"

namespace dmmr {

// How a draw places an object's vertices in the frame: the object-to-eye
// matrix as composed in double (the GPU gets it rounded to float), the
// projection, and the viewport, which is the whole frame at (0, 0).
struct WindowTransform {
  Mat4d object_to_eye;
  Mat4d projection;
  int width = 0, height = 0;
  int subpixel_bits = 4;  // GL_SUBPIXEL_BITS (the GL minimum is 4; llvmpipe has 8)
};

// A vertex's window position (pixels, origin at the frame's bottom left)
// and a radius within which the rasteriser's snapped position lies (the
// floats' own rounding included); +inf where the vertex is not safely in
// front of the eye.
struct WindowVertex {
  float x = 0, y = 0, radius = 0, unused = 0;  // 16 bytes: one load a vertex
};
using WindowVertices = std::vector<WindowVertex>;

// Projects `count` vertices (`positions`: x, y, z floats each) into `out`
// (resized; its storage is reused between calls).
void projectVertices(const float* positions, size_t count, const WindowTransform& t,
                     WindowVertices* out);

// A triangle whose box (widened by its vertices' radii) holds at most this
// many pixel centres of the scissor is tested centre by centre against its
// edges, widened likewise; a larger box is kept on the box test alone.
inline constexpr int64_t kExactCentres = 4;

// Copies to `out` the triangles of the list `indices[0, count)` (count a
// multiple of 3) that can cover a pixel centre inside `scissor`, in their
// order; returns how many indices it wrote. `out` holds `count` indices; it
// may not overlap `indices`. A triangle with an index past the vertices or
// a vertex of infinite radius (projectVertices gives non-finite positions
// one) is kept. The scissor lies within 2^29 pixels of the origin.
size_t keepCoveringTriangles(const uint32_t* indices, size_t count, const WindowVertices& v,
                             Rect scissor, uint32_t* out);

namespace detail {
// The implementations projectVertices and keepCoveringTriangles choose
// between, for tests and benchmarks: the portable loops, and, on x86-64 CPUs
// with AVX2 (haveAvx2), four vertices or eight triangles at a time with the
// same floats and doubles in the same operations, so that both give the
// same vertices and keep the same triangles, bit for bit.
size_t keepCoveringTrianglesScalar(const uint32_t* indices, size_t count, const WindowVertices& v,
                                   Rect scissor, uint32_t* out);
bool haveAvx2();  // false where the build has no AVX2 path
void projectVerticesScalar(const float* positions, size_t count, const WindowTransform& t,
                           WindowVertices* out);
void projectVerticesAvx2(const float* positions, size_t count, const WindowTransform& t,
                         WindowVertices* out);  // only where haveAvx2()
size_t keepCoveringTrianglesAvx2(const uint32_t* indices, size_t count, const WindowVertices& v,
                                 Rect scissor, uint32_t* out);  // only where haveAvx2()
}  // namespace detail

}  // namespace dmmr
