// A client's cost as a function of its work, fitted from what clients report
// (`--weights fitted`), and each client's relative speed. Pure code over
// plain data: no MPI, no GL.
//
// A client's work on a frame is modelled as
//   ms = per_drawn * objects drawn + per_triangle * triangles drawn
//      + per_tested * objects tested + per_pixel * pixels of its region
//      + per_fill * fill + per_raster * raster,
// where fill is the pixels of the drawn objects' footprints inside its
// region (overdraw counted: where a software rasteriser spends its time),
// and raster the triangles the rasteriser is expected to set up: each drawn
// object's triangles per footprint pixel, at most kRasterCap, times its
// footprint's pixels inside the region. With the triangle cull (draw.h) an
// object of many small triangles hands the GL only those that cover a pixel
// centre, about one per pixel; an object of large triangles hands them all,
// and only where its footprint meets the region (docs/benchmarks.md,
// "Triangles the rasteriser sets up"). All of it divided by the client's
// speed (1 for a typical client, 0.5 for one that takes twice as long on the
// same work). The division then weighs an object drawn lately per_drawn +
// per_triangle * triangles + per_tested, one hidden lately per_tested, and
// every pixel per_pixel; a drawn object's fill and raster weigh per_fill +
// per_raster * min(triangles / footprint pixels, kRasterCap) per pixel of its
// footprint, spread over it (divide.h), so that balanced weights mean
// balanced time, not only balanced triangles.
#pragma once

#include <algorithm>
#include <cstdint>
#include <ostream>
#include <vector>

namespace dmmr {

// One client's frame: its work and the milliseconds it took.
struct CostSample {
  int client = 0;  // 0-based
  double drawn = 0, triangles = 0, tested = 0, pixels = 0, fill = 0, raster = 0;
  double ms = 0;
  friend bool operator==(const CostSample&, const CostSample&) = default;
};

struct CostModel {
  double per_drawn = 0, per_triangle = 0, per_tested = 0, per_pixel = 0, per_fill = 0,
         per_raster = 0;  // ms each
  bool fitted = false;    // false: too little or degenerate data; use triangles
  friend bool operator==(const CostModel&, const CostModel&) = default;
};
std::ostream& operator<<(std::ostream& os, const CostModel& m);

// The most triangles per footprint pixel a drawn object is expected to hand
// the rasteriser (CostSample::raster): a pixel centre is covered by about one
// front and one back triangle of a closed surface, and the box's footprint
// is larger than the surface's, so 1 (fitted against the clients' submitted
// triangles on skullmesh4: slope 1.03; docs/benchmarks.md).
constexpr double kRasterCap = 1;
// An object's expected rasterised triangles per pixel of its footprint.
inline double rasterPerPixel(double triangles, double footprint_pixels) {
  return footprint_pixels > 0 ? std::min(triangles / footprint_pixels, kRasterCap) : 0.0;
}

// The model's milliseconds for a sample's work at speed 1.
double predictMs(const CostModel& m, const CostSample& s);

// Least squares with every coefficient >= 0 (the best over the subsets of
// coefficients whose unconstrained fit is non-negative), over samples whose
// ms are first multiplied by their client's speed (`speeds` indexed by
// client; empty: all 1). Samples with a non-finite or negative time are left
// out. Unfitted when fewer than 4 samples remain or no subset fits.
CostModel fitCostModel(const std::vector<CostSample>& samples,
                       const std::vector<double>& speeds = {});

// A client's speed: the model's time for its samples' work over the time they
// took, normalised so that the clients' speeds average 1 and clamped to
// [1/8, 8]; when every speed lies within [1/kSpeedDeadband, kSpeedDeadband]
// all are taken as 1.
// Clients without samples get 1. Returns `clients` values.
constexpr double kSpeedDeadband = 1.25;
std::vector<double> clientSpeeds(const CostModel& m, const std::vector<CostSample>& samples,
                                 int clients);

// Fits the model and the speeds together: speeds from the model, the model
// again on speed-normalised times, a few rounds. `speeds` out: `clients`
// values (all 1 when the model cannot be fitted).
CostModel fitCostsAndSpeeds(const std::vector<CostSample>& samples, int clients,
                            std::vector<double>* speeds);

// Catching up (--catch-up): frames in flight let a client that was slowest on
// one frame catch up on the next, so the frame rate is set by the busiest
// client's mean time, not by each frame's slowest (docs/benchmarks.md: the
// scheduled frame time); the debt steers the next shares to even the means
// out. kDebtMemory and kDebtFrames were chosen by an A/B on the medium scenes
// (faster payback evened the means more but unbalanced single frames).
// A client's debt is how far its time runs ahead of the clients' mean: each
// frame `debt = kDebtMemory * debt + (ms - mean ms)` (samples of one frame; a
// client without a finite time keeps its debt), and `frame_ms` a smoothed
// mean client time. `debt` is resized to the samples' client count.
constexpr double kDebtMemory = 0.9;
void updateClientDebt(const std::vector<CostSample>& frame, std::vector<double>* debt,
                      double* frame_ms);
// Per client, the factor its share of the next frame is multiplied by, to pay
// its debt back over about kDebtFrames frames: 1 - debt / (kDebtFrames *
// frame_ms), clamped to [1/2, 2]; all 1 without debts or a mean time.
constexpr double kDebtFrames = 2;
std::vector<double> clientDebtFactors(const std::vector<double>& debt, double frame_ms,
                                      int clients);
// The debt each client will have once the frames planned but not yet
// measured are, if each goes as planned: its debt less, for every such
// frame, what that frame's factor f (clientDebtFactors) takes off its time,
// frame_ms * (1 - f). `in_flight`: those frames' factors, per frame and
// client (a missing or non-finite factor counts as 1). Catching up plans
// on this, not on the measured debt: the measured debt is as old as the
// frames in flight, and paying it again in each frame planned before the
// first payment shows is a loop that rings, the clients taking turns at
// being the slowest (per-frame max/mean 1.32-1.43 with 4 clients against
// 1.27-1.35 without catching up, docs/benchmarks.md "Catching up").
std::vector<double> projectedDebt(const std::vector<double>& debt,
                                  const std::vector<std::vector<double>>& in_flight,
                                  double frame_ms);

}  // namespace dmmr
