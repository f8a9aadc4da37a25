// A screen-space correction of the division's weights from measured client
// time, over plain data (no MPI, no GL).
//
// The division balances weights (triangles drawn lately, or a fitted cost
// model); a client's time follows them only roughly: objects tested and
// hidden, overdraw and the depth pyramid cost what no weight says, and not
// evenly over the screen. After each frame the server compares each client's
// share of the measured time with its region's share of the planned weight;
// the cells under a region that cost more than planned weigh more from then
// on, those that cost less weigh less (a multiplicative, damped integral
// controller, in the spirit of Equalizer's load equalizer, which keeps cost
// per screen area from past frames). The factors only move split lines:
// every object still goes to every region its footprint overlaps, so frames
// stay exact.
#pragma once

#include <ostream>
#include <vector>

#include "math.h"

namespace dmmr {

// columns x rows cells over a frame, each a factor multiplying the weights of
// the footprints over it. Cell (i, j) covers pixel columns
// [x + i*w/columns, x + (i+1)*w/columns) and rows likewise (integer division).
struct CostGrid {
  int columns = 0, rows = 0;
  std::vector<double> factor;  // row-major from the bottom row, columns*rows values, each > 0
  static CostGrid uniform(int columns, int rows);  // every factor 1; requires both >= 1
  friend bool operator==(const CostGrid&, const CostGrid&) = default;
};
std::ostream& operator<<(std::ostream& os, const CostGrid& g);

// One client's region of a finished frame: what the division planned for it
// (its weight, in the division's units) and what it measured (its time,
// divided by nothing: a slower client's time should be scaled to a typical
// client's by the caller, so that the grid learns the screen, not the client).
struct RegionCost {
  Rect rect;
  double planned = 0;   // >= 0
  double measured = 0;  // >= 0
  friend bool operator==(const RegionCost&, const RegionCost&) = default;
};

struct CostGridGain {
  double gain = 0.5;     // fraction of the way to a frame's target taken, in (0, 1]
  double forget = 0.02;  // fraction of every log factor dropped per frame (stale cells drift to 1)
  double step = 4;       // one frame's ratio clamped to [1/step, step]
  double limit = 64;     // factors clamped to [1/limit, limit]
};

// Updates `grid` from one frame's regions, which tile `frame`, the frame
// having been planned with the factors `planned_with` (the grid as it was
// then: frames are in flight while the grid moves). A region's ratio is (its
// share of the measured time) / (its share of the planned weight), each
// share smoothed by 1/(2n) of the mean so that an empty region gives a finite
// ratio, clamped to the step; a cell's target is its planned-with factor
// times the area-weighted geometric mean of the ratios of the regions over
// it, and its factor moves `gain` of the way there in log space, then loses
// `forget` of its log. Last, every factor is scaled so that their geometric
// mean is 1 (only ratios matter to the division). Does nothing when fewer
// than two regions have an area, or nothing was measured or planned.
void correctCostGrid(CostGrid* grid, const CostGrid& planned_with, Rect frame,
                     const std::vector<RegionCost>& regions, const CostGridGain& gain = {});

// The area-weighted mean factor of the cells under pixel columns [x0, x1) and
// rows [y0, y1) of `frame` (clipped to it; 1 when nothing is left).
double costGridFactor(const CostGrid& grid, Rect frame, int x0, int x1, int y0, int y1);

}  // namespace dmmr
