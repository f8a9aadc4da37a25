// One frame's work on the server, without MPI: frustum culling, footprints,
// division into one region and object list per client.
#pragma once

#include <algorithm>
#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <ostream>
#include <thread>
#include <vector>

#include "cost_grid.h"
#include "cost_model.h"
#include "cpu_time.h"
#include "cull.h"
#include "divide.h"
#include "scene.h"

namespace dmmr {

struct FramePlan {
  // `regions_per_client` per client, tiling the frame; region j goes to
  // client j % clients (regionClient).
  std::vector<Region> regions;
  // With a pool (plan's pool_share > 0): the rest of the frame, in parts
  // handed out on demand (FrameJob to whichever client is free first); the
  // regions and these parts tile the frame together.
  std::vector<Region> pool;
  uint64_t objects_in_frustum = 0;
  uint64_t triangles_in_frustum = 0;
  double cull_ms = 0;
  double divide_ms = 0;   // footprints and division
  double project_ms = 0;  // the footprints alone (part of divide_ms)
  // CPU time of culling, footprints and division, summed over the threads
  // that did them: the server's cost, which unlike the wall times above does
  // not count waiting for a core.
  double plan_cpu_ms = 0;
  // Per region: the weight the division balanced (its objects' weights and
  // fill, plus its pixels' weight), for FramePlanner::reportRegionCosts.
  std::vector<double> planned;
  CostGrid grid;  // the cost grid the footprints were weighed with (empty: none)
};

// What a client's drawn objects cover of its region (FramePlanner::coverOf).
struct DrawnCover {
  double fill = 0, raster = 0;
};

// The 0-based client region j of a FramePlan goes to.
inline int regionClient(size_t j, int clients) {
  return int(j % size_t(clients));
}

// What the server expects of one region at plan time, from what it knows
// (FramePlanner::forecast): set beside what the client then reports, it shows
// how well the division's inputs predict a client's work (--division-log).
struct RegionForecast {
  uint64_t objects = 0;           // in the region's list
  uint64_t drawn_lately = 0;      // of them, drawn in the last kSeenFrames frames
  uint64_t triangles_lately = 0;  // their triangles
  double fill_lately = 0;         // pixels of their footprints inside the region
  friend bool operator==(const RegionForecast&, const RegionForecast&) = default;
  RegionForecast& operator+=(const RegionForecast& o) {  // two regions' together
    objects += o.objects;
    drawn_lately += o.drawn_lately;
    triangles_lately += o.triangles_lately;
    fill_lately += o.fill_lately;
    return *this;
  }
};
std::ostream& operator<<(std::ostream& os, const RegionForecast& f);

// A frame as tiles (--balance tiles-*): the tiles in makeTiles order and, per
// tile, the objects whose footprint overlaps it.
struct TilePlan {
  std::vector<Rect> tiles;
  std::vector<std::vector<uint32_t>> objects;
  int columns = 0;  // of the tile grid
  uint64_t objects_in_frustum = 0;
  uint64_t triangles_in_frustum = 0;
  double cull_ms = 0;
  double divide_ms = 0;    // footprints and the per-tile lists
  double plan_cpu_ms = 0;  // as FramePlan's
};

// Threads for projecting `n` footprints: projection is independent per
// object, so large frames use the server's cores, one thread per 16384
// objects (below that a thread's start costs more than it saves), at most 8.
inline size_t footprintThreads(size_t n) {
  return std::min<size_t>({std::max(1u, std::thread::hardware_concurrency()), 8, n / 16384 + 1});
}

// The footprints of items 0..n-1, in item order: `project(k, &f)` fills f
// and says whether item k has one. Slices 1..threads-1 run on threads
// spawned for the call, slice 0 on the caller's. Requires threads >= 1.
// `spawned_cpu_ms` (optional): gets the spawned threads' CPU time added (the
// caller's own is on its thread's clock).
template <typename Project>
std::vector<Footprint> projectInSlices(size_t n, size_t threads, const Project& project,
                                       double* spawned_cpu_ms = nullptr) {
  std::vector<std::vector<Footprint>> parts(threads);
  std::vector<double> cpu(threads, 0.0);
  auto work = [&](size_t t) {
    double c0 = t > 0 ? threadCpuMs() : 0.0;
    size_t begin = n * t / threads, end = n * (t + 1) / threads;
    parts[t].reserve(end - begin);
    Footprint f;
    for (size_t k = begin; k < end; ++k)
      if (project(k, &f)) parts[t].push_back(f);
    if (t > 0) cpu[t] = threadCpuMs() - c0;
  };
  std::vector<std::thread> pool;
  for (size_t t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (auto& th : pool) th.join();
  if (spawned_cpu_ms)
    for (double c : cpu) *spawned_cpu_ms += c;
  std::vector<Footprint> items = std::move(parts[0]);
  for (size_t t = 1; t < threads; ++t) items.insert(items.end(), parts[t].begin(), parts[t].end());
  return items;
}

// Plans frames of one scene. Keeps a compact copy of what projection needs
// (each object's tight box and weight, 56 bytes instead of the whole bounds
// record), because projecting 10^5 objects a frame is bound by memory traffic.
class FramePlanner {
 public:
  explicit FramePlanner(const Scene& scene);
  // Divides the frame into clients * regions_per_client regions. With more
  // than one region a client (--regions-per-client), the division's leaves
  // are dealt round-robin: it splits the count in half at each level, so
  // each run of `clients` consecutive leaves is one part of the frame, and
  // every client gets one region of each such part. What a stale forecast
  // gets wrong in one part of the frame (a copy that came near, a hidden
  // area that opened) is then shared by all clients instead of falling on
  // the one whose region it is; the price is more straddling objects.
  //
  // A pool (`pool_share` in (0, 1), `pool_parts` >= 1; one region a client):
  // the division makes one region more, whose share of the weight is
  // `pool_share` of the whole (the clients share the rest by their speeds),
  // and splits it into `pool_parts` parts of about equal weight
  // (FramePlan::pool). Dealt on demand, the parts go to the clients that
  // finish their regions first, so the part of a frame's work that the
  // forecast got wrong is shared out when it shows, not three frames later.
  FramePlan plan(const Camera& camera, int width, int height, int clients,
                 int regions_per_client = 1, double pool_share = 0, int pool_parts = 0) const;
  TilePlan planTiles(const Camera& camera, int width, int height, int tile_w, int tile_h) const;

  // Division weights from what the clients drew: an object drawn in one of
  // the last kSeenFrames frames weighs its triangles; one not drawn lately
  // (hidden by occlusion culling) weighs what testing it costs, at most
  // kHiddenWeight. Before any feedback every object weighs its triangles.
  // Weights only move the split lines: every object still goes to every
  // region it overlaps, so frames stay exact. Thread-safe: the assembler
  // reports while the planner plans.
  void reportDrawn(uint32_t frame, const std::vector<uint32_t>& objects);
  void planningFrame(uint32_t frame) { frame_ = frame; }
  // Of `objects` (ascending): those drawn in the last kHintFrames frames
  // reported (FrameJob::hints). Empty before any report.
  std::vector<uint32_t> drawnLately(const std::vector<uint32_t>& objects) const;
  static constexpr uint32_t kHintFrames = 2;
  static constexpr uint32_t kSeenFrames = 8;
  static constexpr uint64_t kHiddenWeight = 1;
  // Objects no client has reported on since they came into view (they came
  // into view in the frames in flight): nobody has tested them yet.
  //   Hidden: they weigh as hidden (culled lately), as before any prior.
  //   Drawn:  they weigh as if drawn lately.
  //   Learnt: they weigh as drawn times the fraction of the objects that came
  //           into view lately and were drawn once reported on
  //           (unseenDrawnFraction).
  // Moves split lines only: never changes a pixel.
  enum class Unseen { Hidden, Drawn, Learnt };
  void setUnseen(Unseen u) { unseen_ = u; }
  // Learnt: of the objects that came into view, the fraction drawn in the
  // frame they came into view, once that frame was reported; each plan
  // decays the counts by kUnseenMemory. 1 before any such object is reported.
  double unseenDrawnFraction() const { return unseen_p_; }
  static constexpr double kUnseenMemory = 0.9;

  // Fitted weights (--weights fitted): each finished frame's per-client work
  // and time; the planner keeps the last kCostFrames frames' samples, fits
  // the cost model and the clients' speeds to them (cost_model.h), and from
  // then on weighs objects and pixels in fitted nanoseconds and gives each
  // client a share in proportion to its speed. Thread-safe, like reportDrawn.
  // `frame`: the frame the samples are of (frames reported in any order);
  // frames up to it are no longer in flight for catching up.
  void reportCosts(uint32_t frame, const std::vector<CostSample>& samples);
  static constexpr size_t kCostFrames = 24;
  // The model and speeds the next plan uses (for logs and tests).
  CostModel costModel() const;
  std::vector<double> speeds() const;
  // Each client's share of the next frame (DivisionCosts::speeds): its
  // speed, times its debt correction when catching up is on
  // (clientDebtFactors of its projectedDebt: the debt less what the frames
  // planned but not yet reported will pay). Empty before a fit.
  std::vector<double> shares(int clients) const;
  // Frames planned and not yet reported whose catching-up factors are kept
  // (older ones are dropped: a frame never reported must not steer forever).
  static constexpr size_t kMaxInFlight = 16;
  // Catching up (cost_model.h; on by default): a client whose measured time
  // ran above the clients' mean gets smaller shares until it has caught up.
  // Moves split lines only: never changes a pixel.
  void setCatchUp(bool on);
  // Measured cost correction (--cost-grid, cost_grid.h): from then on each
  // footprint's weight is multiplied by the grid's mean factor under it, and
  // each finished frame's regions (planned weight, measured time) correct the
  // grid. Off until enabled. Thread-safe, like reportDrawn.
  void enableCostGrid(int columns, int rows);
  // `planned_with`: the frame's FramePlan::grid.
  void reportRegionCosts(int width, int height, const std::vector<RegionCost>& regions,
                         const CostGrid& planned_with);
  bool costGridEnabled() const;
  CostGrid costGrid() const;  // a copy, for logs and tests
  static constexpr int kGridColumns = 32, kGridRows = 24;
  // A client's fill and raster for CostSample, from one projection of
  // `drawn` (object indices): fill, the pixels of their footprints inside
  // `region`, overlaps counted once per object; raster, each footprint's
  // pixels inside `region` times rasterPerPixel(its triangles, its pixels in
  // the frame).
  DrawnCover coverOf(const Camera& camera, int width, int height, Rect region,
                     const std::vector<uint32_t>& drawn) const;
  // The forecast for `region` of the frame being planned (planningFrame),
  // by the rule the weights use (drawn in the last kSeenFrames frames; an
  // object not yet reported on since it came into view counts when the
  // Unseen setting gives it at least half a drawn object's weight).
  RegionForecast forecast(const Camera& camera, int width, int height, const Region& region) const;

 private:
  // Footprints of the `visible` objects, in the same order (those covering no
  // pixel left out); computed on up to 8 threads for large lists.
  // `grid`: the cost grid's factors to weigh by (empty: none).
  // `spawned_cpu_ms` as for projectInSlices.
  std::vector<Footprint> footprints(const std::vector<uint32_t>& visible, const Camera& camera,
                                    int width, int height, const CostGrid& grid = {},
                                    double* spawned_cpu_ms = nullptr) const;
  CostGrid gridFor(int width, int height) const;  // the grid to plan with (empty: none)
  // shares() with cost_mu_ held; `factors` (if given) gets the catching-up
  // factors used (empty when none).
  std::vector<double> sharesLocked(int clients, std::vector<double>* factors) const;
  struct Projected {
    Box3d box;
    uint64_t weight;
  };
  uint64_t weightOf(uint32_t object, const CostModel& model) const;
  bool drawnRecently(uint32_t object) const;  // in the last kSeenFrames frames
  // How much of a drawn object's weight an object gets: 1 if drawnRecently;
  // for one in view only since after the latest reported frame, by the
  // Unseen setting (0, 1 or the learnt fraction); otherwise 0.
  double drawnFraction(uint32_t object) const;
  // Records which objects are in view in the frame being planned (frame_);
  // plan() calls it unless the Unseen setting is Hidden.
  void noteInView(const std::vector<uint32_t>& visible) const;
  // Frustum culling: the objects in view, ascending; fills the counts.
  std::vector<uint32_t> cull(const Camera& camera, uint64_t* objects, uint64_t* triangles) const;
  const Scene& scene_;
  std::vector<Projected> boxes_;
  // Per object: 1 + the last frame a client drew it (0: never). Relaxed
  // atomics: these are hints, read while the assembler writes them.
  std::unique_ptr<std::atomic<uint32_t>[]> drawn_in_;
  // Per object: 1 + the latest frame planned with it in the frustum, and 1 +
  // the first frame of that run of consecutive plans (0: never). Written by
  // the planning thread in plan(), read by the footprint threads it starts.
  std::unique_ptr<std::atomic<uint32_t>[]> in_view_, entered_;
  mutable uint32_t last_planned_ = 0, prev_planned_ = 0;  // 1 + frame: the latest two plans
  Unseen unseen_ = Unseen::Hidden;
  // Learnt: objects that came into view, not yet reported on (object, 1 +
  // the frame it came into view), and the decayed counts of those resolved.
  mutable std::vector<std::pair<uint32_t, uint32_t>> unseen_pending_;
  mutable double unseen_drawn_count_ = 0, unseen_count_ = 0, unseen_p_ = 1;
  std::atomic<bool> feedback_{false};
  std::atomic<uint32_t> latest_drawn_{0};  // 1 + the latest frame reported
  uint32_t frame_ = 0;
  mutable std::mutex cost_mu_;                        // guards the fields below
  std::vector<std::vector<CostSample>> cost_frames_;  // the last kCostFrames frames' samples
  CostModel model_;
  std::vector<double> speeds_;
  std::vector<double> debt_;  // per client: ms behind the clients' mean (updateClientDebt)
  // Per frame planned (planningFrame) and not yet reported: the catching-up
  // factors its plan used. Written by plan(), which is const to its callers
  // but hands out these factors: mutable, under cost_mu_.
  mutable std::map<uint32_t, std::vector<double>> in_flight_;
  double frame_ms_ = 0;  // the clients' mean time per frame, smoothed
  bool catch_up_ = true;
  CostGrid grid_;                         // empty: no correction
  int grid_width_ = 0, grid_height_ = 0;  // the frame the grid was last corrected for
};

// One-off convenience: builds a planner and plans one frame.
FramePlan planFrame(const Scene& scene, const Camera& camera, int width, int height, int clients);

}  // namespace dmmr
