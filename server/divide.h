// Load-balanced frustum division (Algorithm 1 of the DMMR paper), over plain
// data: objects' pixel footprints and weights in, one screen region and object
// list per client out. No MPI, no GL.
#pragma once

#include <cstdint>
#include <ostream>
#include <vector>

#include "camera.h"
#include "formats.h"

namespace dmmr {

// Pixel columns [x0, x1) and rows [y0, y1) (GL order, row 0 at the bottom)
// that an object may touch.
struct Footprint {
  uint32_t object = 0;
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  uint64_t weight = 0;  // counted whole on every side the footprint reaches
  // Weight per pixel of the footprint, spread evenly over its rectangle (an
  // object's fill: each side of a split gets the part it overlaps). >= 0.
  double fill = 0;
  friend bool operator==(const Footprint&, const Footprint&) = default;
};
std::ostream& operator<<(std::ostream& os, const Footprint& f);

// Pixels of the footprint's rectangle inside `rect` (0 when they do not meet).
double overlapArea(const Footprint& f, Rect rect);

// The conservative footprint of an object's bounds (its box, clipped to the
// sphere's box where that is tighter, clipped at the near plane) for a
// width x height frame: every pixel the object can cover, plus a one-pixel
// margin against rounding. Returns false when it covers no pixel.
bool footprint(const ObjectBounds& o, uint32_t index, const Camera& camera, int width, int height,
               Footprint* out);

// The smallest axis-aligned box the object's bounds give: its box, clipped to
// the sphere's box (both enclose the object).
Box3d tightBox(const ObjectBounds& o);

// The same for many objects under one camera: the view transform and the
// projection scales are computed once.
class FootprintProjector {
 public:
  FootprintProjector(const Camera& camera, int width, int height);
  bool operator()(const ObjectBounds& o, uint32_t index, Footprint* out) const;
  // `box` must enclose the object (see tightBox).
  bool operator()(const Box3d& box, uint64_t weight, uint32_t index, Footprint* out) const;

 private:
  Mat4d view_;
  double near_, sx_, sy_;  // pixels per unit of x/depth and y/depth
  int width_, height_;
};

struct Region {
  Rect rect;
  std::vector<uint32_t> objects;  // ascending object indices
  uint64_t weight = 0;            // the objects' weights and fill inside rect, rounded
  friend bool operator==(const Region&, const Region&) = default;
};
std::ostream& operator<<(std::ostream& os, const Region& r);

// Splits `frame` into exactly `clients` regions that tile it (no gap, no
// overlap). Each split is a pixel line chosen, from prefix sums of the weights
// of footprints starting left of it and suffix sums of those ending right of
// it, to minimise |l - l*| + |r - r*| + min(nl, nr) |l/nl - r/nr|, where nl
// and nr are the client counts of the two sides (the count is split in half,
// odd counts unevenly) and l*, r* their share of the total. For two clients
// this is the paper's |l-h| + |r-h| + |l-r|. Splits alternate between
// vertical and horizontal lines, starting across the longer side; a side of
// one pixel forces the other direction. Ties go to the line nearest the
// area-proportional one. An object whose footprint straddles a split goes to
// both sides. A footprint's fill is spread over its rectangle: each side
// gets fill times the pixels of the footprint inside it. When the frame has
// fewer pixels than clients, the extra clients get empty rectangles and no
// objects.
std::vector<Region> divideFrame(const std::vector<Footprint>& items, Rect frame, int clients);

// What the division balances besides the objects' weights.
struct DivisionCosts {
  // Weight of each pixel of a region (work that grows with its area: clears,
  // readbacks, compression, the depth pyramid, fill the objects' weights miss),
  // in the objects' weight units. 0: objects alone.
  double pixel_weight = 0;
  // Relative speed of each client (the regions come back in client order):
  // a side of a split is given a share of the weight in proportion to the sum
  // of its clients' speeds. Empty: all equal. Each must be finite and > 0.
  std::vector<double> speeds;
  friend bool operator==(const DivisionCosts&, const DivisionCosts&) = default;
};

// The same, balancing `costs` too. With pixel_weight 0 and equal speeds it
// returns exactly what the overload above does.
std::vector<Region> divideFrame(const std::vector<Footprint>& items, Rect frame, int clients,
                                const DivisionCosts& costs);

}  // namespace dmmr
