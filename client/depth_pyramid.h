// The depth-pyramid visibility test (`--visibility pyramid`): occluders are
// drawn into depth on the GPU, the region's depth is read back once, and
// every candidate box is tested on the CPU against a farthest-depth pyramid
// built from it. Pure code over plain arrays: no GL in here.
//
// Depth is reversed-Z (draw.h): larger is nearer, the cleared buffer is 0,
// so the farthest depth of a block of pixels is its minimum and each
// pyramid texel holds the minimum of the (up to) four below it.
//
// Why it is exact (docs/architecture.md, "Depth-pyramid test"): no fragment
// of an object lies in front of its depth-bound box or outside the pixel
// footprint of its (wider) query box; a box is culled only when every pixel
// of that footprint inside the region holds depth strictly nearer than the
// box's nearest point. Then every fragment the object could make there fails
// GL_GREATER against geometry the render stage draws too.
#pragma once

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "camera.h"
#include "math.h"

namespace dmmr {

// A box's conservative footprint in a width x height frame (GL pixel
// coordinates, origin bottom-left): every pixel whose centre lies within the
// span of the box's projected corners (so every pixel centre anything inside
// the box can cover), clipped to the frame, and an upper bound of the depth
// (near / distance) anything inside can have.
struct ScreenBound {
  // Some corner of the box is not beyond the near plane: no bound; the box
  // must be taken as visible.
  bool reaches_near = false;
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // inclusive; empty when x1 < x0 or y1 < y0
  double nearest = 0;                    // depth of the box's nearest point, rounded up
  // Where the ray through pixel (x, y)'s centre enters the box, as in the
  // shaders' depth bound (camera.h, entryDepthPlanes), in pixel indices:
  // min over i of planes[i][0] x + planes[i][1] y + planes[i][2], a tighter
  // bound than `nearest` at each pixel for boxes that recede in depth.
  // Absent (has_planes false) for united bounds.
  bool has_planes = false;
  std::array<std::array<double, 3>, 3> planes{};
  bool empty() const { return x1 < x0 || y1 < y0; }
  // The largest depth anything inside can have at the pixels [x0, x1] x
  // [y0, y1] (inclusive): min(nearest, over i the planes' maximum there).
  double bound(int bx0, int by0, int bx1, int by1) const;
  friend bool operator==(const ScreenBound&, const ScreenBound&) = default;
};
std::ostream& operator<<(std::ostream& os, const ScreenBound& b);

// `box` valid. Callers pass the query box (queryBoxBounds) of an object's box,
// which encloses its depth-bound box and, after the rasteriser's rounding,
// every pixel centre its geometry covers. Off-frame boxes give an empty
// bound (never reaches_near unless a corner is at or before the near plane).
ScreenBound screenBound(const Box3d& box, const Camera& camera, int width, int height);
// The same without the entry-depth planes (has_planes false): the rectangle
// and `nearest` only, for callers that need no more (partBound).
ScreenBound screenRect(const Box3d& box, const Camera& camera, int width, int height);

// screenBound and screenRect for many boxes under one camera, with the same
// results: the camera's rotations and projection scales worked out once.
class ScreenProjector {
 public:
  ScreenProjector(const Camera& camera, int width, int height);
  ScreenBound bound(const Box3d& box) const;
  ScreenBound rect(const Box3d& box) const;

 private:
  Camera camera_;
  Mat4d view_, camera_to_world_;
  double tan_half_fovy_, f_, fx_;
  int width_, height_;
};

// What of `object` (an object's bound) a part of it can reach: `part`'s
// rectangle (the bound of a part's query box, queryPartBounds) within
// `object`'s, with `object`'s depth bound, which the shaders' depth clamp
// guarantees for every fragment (a part's own depth is not: a sliver's
// fragment can lie in front of its part). reaches_near if either does.
ScreenBound partBound(const ScreenBound& object, const ScreenBound& part);

// The smallest bound covering both: the union of the rectangles, the nearer
// depth, and reaches_near if either does.
ScreenBound unite(const ScreenBound& a, const ScreenBound& b);

// Whether two rectangles share a pixel.
bool overlaps(const Rect& a, const Rect& b);
// The pixels both hold (an empty Rect{} when none).
Rect intersection(const Rect& a, const Rect& b);
// The smallest rectangle holding both (an empty one counts as nothing).
Rect boundingRect(const Rect& a, const Rect& b);
// At most `max` (>= 1) rectangles covering every pixel of `rects`: where
// there are more, the pair whose bounding rectangle adds the fewest pixels
// is merged, and overlapping ones are merged always (so that no pixel is
// redrawn twice). Empty rectangles are dropped.
std::vector<Rect> coverRects(std::vector<Rect> rects, size_t max);

// Which cells (2^shift x 2^shift pixels) of a region the marked rectangles
// touch, and whether a rectangle shares a cell with any of them: O(1) per
// mark and per question, O(cells) to finish. Conservative: a shared cell
// counts as meeting, though the pixels may not.
class CellCoverage {
 public:
  CellCoverage(const Rect& region, int shift);
  // `r` in frame pixels (clipped to the region; empty ones ignored). Only
  // before finish().
  void mark(const Rect& r);
  // After the last mark, before the first meets().
  void finish();
  bool meets(const Rect& r) const;

 private:
  // Clips `r` to the region; false when nothing is left. Cells inclusive.
  bool cells(const Rect& r, int* cx0, int* cy0, int* cx1, int* cy1) const;
  Rect region_;
  int shift_, w_, h_;
  // A difference array while marking; after finish(), per (x, y) the number
  // of marked cells in [0, x) x [0, y): (w_ + 1) x (h_ + 1).
  std::vector<int32_t> sums_;
};

class DepthPyramid {
 public:
  // `depth`: region.w * region.h floats, rows bottom first (glReadPixels'
  // order), the depth of `region` of the frame. region non-empty.
  void build(const float* depth, const Rect& region);
  // After build(), with `depth` (the whole region, as for build) changed
  // only inside `dirty` (frame pixels): brings every level up to date,
  // recomputing only the texels over `dirty`. The result equals build()'s.
  void update(const float* depth, const Rect& dirty);

  // True when nothing inside the bound can show in the region: every pixel
  // of `b`'s rectangle inside the region holds a depth strictly greater than
  // b.bound at that pixel (a rectangle outside the region is hidden;
  // reaches_near is never). Exact per pixel; the coarse levels only prune. When the test
  // would visit more than `budget` texels it answers false (visible), so the
  // answer is always conservative.
  // When the answer is false because of a pixel at or behind the bound (not
  // the budget), that pixel (frame coordinates) goes to *witness, if given;
  // otherwise *witness is left as it was.
  bool hides(const ScreenBound& b, int budget = kDefaultBudget,
             std::pair<int, int>* witness = nullptr) const;
  static constexpr int kDefaultBudget = 4096;

  int levels() const { return int(levels_.size()); }
  const Rect& region() const { return region_; }
  // Level `level`'s size and its texel (x, y), region-relative; level 0 is
  // the depth itself.
  int width(int level) const { return dims_[size_t(level)].first; }
  int height(int level) const { return dims_[size_t(level)].second; }
  float texel(int level, int x, int y) const {
    return levels_[size_t(level)][size_t(y) * size_t(width(level)) + size_t(x)];
  }

 private:
  // Whether every pixel of the (region-relative, inclusive) rectangle inside
  // texel (x, y) of `level` is nearer than anything inside `b` can be there.
  bool refine(int level, int x, int y, const int rect[4], const ScreenBound& b, int* budget,
              std::pair<int, int>* witness) const;
  Rect region_;
  std::vector<std::vector<float>> levels_;
  std::vector<std::pair<int, int>> dims_;
};

// Last frame's depth as this frame's camera would see it, on texels of
// 2^level x 2^level pixels: a guess at which objects show, made before anything is drawn
// (the fused stage's first step). Nothing exact rests on it; a wrong guess
// costs time only.
struct PredictedDepth {
  Rect region;    // of the frame, in pixels
  int level = 1;  // a texel stands for 2^level x 2^level pixels of the region
  int width = 0;  // texels: region.w / 2^level x region.h / 2^level, rounded up
  int height = 0;
  std::vector<float> texels;  // rows bottom first; 0: nothing (known far, or unknown)
  float texel(int x, int y) const { return texels[size_t(y) * size_t(width) + size_t(x)]; }
};

// Each texel of `level` of `from` (the farthest depth of its block of pixels,
// drawn under `from_cam`) stands for one point at its block's centre. The point is
// moved to where `to_cam` sees it and written into the texel of `out` there
// where nearer (larger) than what that texel holds. Cleared texels (0:
// nothing drawn) move as directions, at depth 0. Points at or before the
// near plane are dropped. Rounding and a camera coming nearer leave texels
// unreached between points: twice over, an unreached texel with a reached
// one among its 8 neighbours takes the farthest of them; texels still
// unreached hold 0. `width` x `height` is the frame both cameras draw;
// `out` has texels of the same size (level); 1 <= level < from.levels().
void reprojectDepth(const DepthPyramid& from, int level, const Camera& from_cam,
                    const Camera& to_cam, int width, int height, const Rect& to_region,
                    PredictedDepth* out);

// The share of the texels of `b`'s rectangle within p's region where
// something inside `b` may show: the predicted depth is not strictly nearer
// than `b`'s bound over the texel's pixels. Sampled on a grid of at most
// about `max_samples` texels. 1 when `b` reaches the near plane, 0 when its
// rectangle misses the region.
double shownFraction(const PredictedDepth& p, const ScreenBound& b, int max_samples = 256);

}  // namespace dmmr
