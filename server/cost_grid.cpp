#include "cost_grid.h"

#include <algorithm>
#include <cmath>

#include "error.h"

namespace dmmr {

namespace {

// Pixel span of cell k of n over [origin, origin + size).
int cellStart(int origin, int size, int n, int k) {
  return origin + int(int64_t(size) * k / n);
}

// Cells [first, last) of n over [origin, origin + size) that [lo, hi) touches.
void cellsOver(int origin, int size, int n, int lo, int hi, int* first, int* last) {
  // The first cell whose end passes lo, and one past the last cell starting before hi.
  int a = int(int64_t(lo - origin) * n / size);
  while (a > 0 && cellStart(origin, size, n, a) > lo) --a;
  while (a < n - 1 && cellStart(origin, size, n, a + 1) <= lo) ++a;
  int b = int((int64_t(hi - origin) * n + size - 1) / size);
  b = std::clamp(b, a + 1, n);
  while (b < n && cellStart(origin, size, n, b) < hi) ++b;
  while (b > a + 1 && cellStart(origin, size, n, b - 1) >= hi) --b;
  *first = a;
  *last = b;
}

int64_t overlap(int a0, int a1, int b0, int b1) {
  return std::max(0, std::min(a1, b1) - std::max(a0, b0));
}

}  // namespace

CostGrid CostGrid::uniform(int columns, int rows) {
  DMMR_CHECK(columns >= 1 && rows >= 1);
  return CostGrid{columns, rows, std::vector<double>(size_t(columns) * size_t(rows), 1.0)};
}

std::ostream& operator<<(std::ostream& os, const CostGrid& g) {
  os << "grid[" << g.columns << "x" << g.rows;
  double lo = 0, hi = 0;
  if (!g.factor.empty()) {
    auto [a, b] = std::minmax_element(g.factor.begin(), g.factor.end());
    lo = *a;
    hi = *b;
  }
  return os << " factors " << lo << ".." << hi << "]";
}

void correctCostGrid(CostGrid* grid, const CostGrid& planned_with, Rect frame,
                     const std::vector<RegionCost>& regions, const CostGridGain& g) {
  DMMR_CHECK(grid && grid->columns >= 1 && grid->rows >= 1 &&
             grid->factor.size() == size_t(grid->columns) * size_t(grid->rows));
  DMMR_CHECK(planned_with.columns == grid->columns && planned_with.rows == grid->rows &&
             planned_with.factor.size() == grid->factor.size());
  DMMR_CHECK(g.gain > 0 && g.gain <= 1 && g.forget >= 0 && g.forget < 1 && g.step >= 1 &&
             g.limit >= 1);
  if (frame.empty()) return;
  double planned = 0, measured = 0;
  int n = 0;
  for (const RegionCost& r : regions) {
    DMMR_CHECK(std::isfinite(r.planned) && r.planned >= 0);
    DMMR_CHECK(std::isfinite(r.measured) && r.measured >= 0);
    if (r.rect.empty()) continue;
    planned += r.planned;
    measured += r.measured;
    ++n;
  }
  if (n < 2 || planned <= 0 || measured <= 0) return;
  // Smoothing: a region planned at 0 gets a share of 1/(2n) of the mean,
  // so its ratio is large but finite (then clamped to the step).
  const double ep = planned / n / (2.0 * n), em = measured / n / (2.0 * n);
  std::vector<double> logRatio;
  std::vector<const RegionCost*> live;
  const double maxStep = std::log(g.step);
  for (const RegionCost& r : regions) {
    if (r.rect.empty()) continue;
    double shareM = (r.measured + em) / (measured + n * em);
    double shareP = (r.planned + ep) / (planned + n * ep);
    logRatio.push_back(std::clamp(std::log(shareM / shareP), -maxStep, maxStep));
    live.push_back(&r);
  }
  // Per cell: area-weighted mean of the log ratios of the regions over it.
  const int C = grid->columns, R = grid->rows;
  std::vector<double> sum(grid->factor.size(), 0.0), area(grid->factor.size(), 0.0);
  for (size_t k = 0; k < live.size(); ++k) {
    Rect r = live[k]->rect;
    int x0 = std::max(r.x, frame.x), x1 = std::min(r.x1(), frame.x1());
    int y0 = std::max(r.y, frame.y), y1 = std::min(r.y1(), frame.y1());
    if (x0 >= x1 || y0 >= y1) continue;
    int c0, c1, r0, r1;
    cellsOver(frame.x, frame.w, C, x0, x1, &c0, &c1);
    cellsOver(frame.y, frame.h, R, y0, y1, &r0, &r1);
    for (int j = r0; j < r1; ++j) {
      int64_t h =
          overlap(cellStart(frame.y, frame.h, R, j), cellStart(frame.y, frame.h, R, j + 1), y0, y1);
      for (int i = c0; i < c1; ++i) {
        int64_t w = overlap(cellStart(frame.x, frame.w, C, i),
                            cellStart(frame.x, frame.w, C, i + 1), x0, x1);
        double a = double(w * h);
        size_t c = size_t(j) * size_t(C) + size_t(i);
        sum[c] += a * logRatio[k];
        area[c] += a;
      }
    }
  }
  const double maxLog = std::log(g.limit);
  double meanLog = 0;
  std::vector<double> lf(grid->factor.size());
  for (size_t c = 0; c < lf.size(); ++c) {
    // The frame's target: the factor it was planned with, corrected by its
    // ratio; the grid moves a `gain` of the way there. Measured against the
    // factors the frame was planned with, not the current ones, so that
    // corrections made while it was in flight are not applied twice (an
    // integral step on late feedback overshoots and oscillates).
    double current = std::log(grid->factor[c]);
    double target = std::log(planned_with.factor[c]) + (area[c] > 0 ? sum[c] / area[c] : 0.0);
    double l = ((1 - g.gain) * current + g.gain * target) * (1 - g.forget);
    lf[c] = std::clamp(l, -maxLog, maxLog);
    meanLog += lf[c];
  }
  meanLog /= double(lf.size());
  for (size_t c = 0; c < lf.size(); ++c)
    grid->factor[c] = std::exp(std::clamp(lf[c] - meanLog, -maxLog, maxLog));
}

double costGridFactor(const CostGrid& grid, Rect frame, int x0, int x1, int y0, int y1) {
  x0 = std::max(x0, frame.x);
  x1 = std::min(x1, frame.x1());
  y0 = std::max(y0, frame.y);
  y1 = std::min(y1, frame.y1());
  if (x0 >= x1 || y0 >= y1 || grid.factor.empty()) return 1.0;
  const int C = grid.columns, R = grid.rows;
  int c0, c1, r0, r1;
  cellsOver(frame.x, frame.w, C, x0, x1, &c0, &c1);
  cellsOver(frame.y, frame.h, R, y0, y1, &r0, &r1);
  if (c1 - c0 == 1 && r1 - r0 == 1) return grid.factor[size_t(r0) * size_t(C) + size_t(c0)];
  double sum = 0, area = 0;
  for (int j = r0; j < r1; ++j) {
    int64_t h =
        overlap(cellStart(frame.y, frame.h, R, j), cellStart(frame.y, frame.h, R, j + 1), y0, y1);
    for (int i = c0; i < c1; ++i) {
      int64_t w =
          overlap(cellStart(frame.x, frame.w, C, i), cellStart(frame.x, frame.w, C, i + 1), x0, x1);
      double a = double(w * h);
      sum += a * grid.factor[size_t(j) * size_t(C) + size_t(i)];
      area += a;
    }
  }
  return area > 0 ? sum / area : 1.0;
}

}  // namespace dmmr
