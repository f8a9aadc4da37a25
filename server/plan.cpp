#include "plan.h"

#include "error.h"
#include "tiles.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace dmmr {

FramePlanner::FramePlanner(const Scene& scene)
    : scene_(scene),
      drawn_in_(new std::atomic<uint32_t>[scene.objects.size()]),
      in_view_(new std::atomic<uint32_t>[scene.objects.size()]),
      entered_(new std::atomic<uint32_t>[scene.objects.size()]) {
  boxes_.reserve(scene.objects.size());
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    boxes_.push_back({tightBox(scene.objects[i]), scene.objects[i].weight});
    drawn_in_[i].store(0, std::memory_order_relaxed);
    in_view_[i].store(0, std::memory_order_relaxed);
    entered_[i].store(0, std::memory_order_relaxed);
  }
}

void FramePlanner::noteInView(const std::vector<uint32_t>& visible) const {
  const uint32_t now = frame_ + 1;
  if (now != last_planned_) {  // not the same frame planned again
    prev_planned_ = last_planned_;
    last_planned_ = now;
  }
  const uint32_t latest = latest_drawn_.load(std::memory_order_relaxed);
  if (unseen_ == Unseen::Learnt) {
    // Resolve the objects whose first frame in view has been reported on and
    // has a later frame reported too (so that every client's part of it is
    // in): drawn or not in that frame.
    unseen_drawn_count_ *= kUnseenMemory;
    unseen_count_ *= kUnseenMemory;
    size_t kept = 0;
    for (const auto& [o, entered] : unseen_pending_) {
      if (entered < latest) {
        unseen_count_ += 1;
        if (drawn_in_[o].load(std::memory_order_relaxed) >= entered) unseen_drawn_count_ += 1;
      } else {
        unseen_pending_[kept++] = {o, entered};
      }
    }
    unseen_pending_.resize(kept);
    if (unseen_count_ > 0) unseen_p_ = unseen_drawn_count_ / unseen_count_;
  }
  for (uint32_t o : visible) {
    uint32_t v = in_view_[o].load(std::memory_order_relaxed);
    if (v == now) continue;
    // In view in the previous plan too: the same run goes on.
    if (v == 0 || v != prev_planned_) {
      entered_[o].store(now, std::memory_order_relaxed);
      // Bounded: without reports (no feedback) nothing is ever resolved.
      if (unseen_ == Unseen::Learnt && unseen_pending_.size() < (size_t(1) << 22))
        unseen_pending_.push_back({o, now});
    }
    in_view_[o].store(now, std::memory_order_relaxed);
  }
}

double FramePlanner::drawnFraction(uint32_t o) const {
  if (drawnRecently(o)) return 1;
  // Came into view after the latest frame a client reported on: untested.
  if (unseen_ == Unseen::Hidden ||
      entered_[o].load(std::memory_order_relaxed) <= latest_drawn_.load(std::memory_order_relaxed))
    return 0;
  return unseen_ == Unseen::Drawn ? 1 : unseen_p_;
}

void FramePlanner::reportDrawn(uint32_t frame, const std::vector<uint32_t>& objects) {
  for (uint32_t o : objects)
    if (o < boxes_.size()) {
      uint32_t v = frame + 1, old = drawn_in_[o].load(std::memory_order_relaxed);
      while (old < v && !drawn_in_[o].compare_exchange_weak(old, v, std::memory_order_relaxed)) {
      }
    }
  uint32_t v = frame + 1, old = latest_drawn_.load(std::memory_order_relaxed);
  while (old < v && !latest_drawn_.compare_exchange_weak(old, v, std::memory_order_relaxed)) {
  }
  feedback_.store(true, std::memory_order_relaxed);
}

std::vector<uint32_t> FramePlanner::drawnLately(const std::vector<uint32_t>& objects) const {
  std::vector<uint32_t> out;
  uint32_t latest = latest_drawn_.load(std::memory_order_relaxed);
  if (latest == 0) return out;
  for (uint32_t o : objects) {
    uint32_t seen = o < boxes_.size() ? drawn_in_[o].load(std::memory_order_relaxed) : 0;
    if (seen != 0 && seen + kHintFrames > latest) out.push_back(o);
  }
  return out;
}

void FramePlanner::reportCosts(uint32_t frame, const std::vector<CostSample>& samples) {
  std::lock_guard<std::mutex> lock(cost_mu_);
  in_flight_.erase(in_flight_.begin(), in_flight_.upper_bound(frame));
  cost_frames_.push_back(samples);
  if (cost_frames_.size() > kCostFrames) cost_frames_.erase(cost_frames_.begin());
  std::vector<CostSample> all;
  int clients = 0;
  for (const auto& f : cost_frames_)
    for (const CostSample& s : f) {
      all.push_back(s);
      clients = std::max(clients, s.client + 1);
    }
  updateClientDebt(samples, &debt_, &frame_ms_);
  std::vector<double> speeds;
  CostModel m = fitCostsAndSpeeds(all, clients, &speeds);
  if (!m.fitted) return;  // keep the last good fit (or none)
  model_ = m;
  speeds_ = std::move(speeds);
}

CostModel FramePlanner::costModel() const {
  std::lock_guard<std::mutex> lock(cost_mu_);
  return model_;
}

std::vector<double> FramePlanner::shares(int clients) const {
  std::lock_guard<std::mutex> lock(cost_mu_);
  return sharesLocked(clients, nullptr);
}

std::vector<double> FramePlanner::sharesLocked(int clients, std::vector<double>* factors) const {
  if (factors) factors->clear();
  if (!model_.fitted || speeds_.size() != size_t(clients)) return {};
  if (!catch_up_) return speeds_;
  std::vector<std::vector<double>> planned;
  for (const auto& [frame, f] : in_flight_)
    if (frame < frame_) planned.push_back(f);  // a plan of this frame again: not ahead of it
  std::vector<double> f =
      clientDebtFactors(projectedDebt(debt_, planned, frame_ms_), frame_ms_, clients);
  if (factors) *factors = f;
  for (int k = 0; k < clients; ++k) f[size_t(k)] *= speeds_[size_t(k)];
  return f;
}

void FramePlanner::setCatchUp(bool on) {
  std::lock_guard<std::mutex> lock(cost_mu_);
  catch_up_ = on;
}

std::vector<double> FramePlanner::speeds() const {
  std::lock_guard<std::mutex> lock(cost_mu_);
  return speeds_;
}

void FramePlanner::enableCostGrid(int columns, int rows) {
  std::lock_guard<std::mutex> lock(cost_mu_);
  grid_ = CostGrid::uniform(columns, rows);
}

bool FramePlanner::costGridEnabled() const {
  std::lock_guard<std::mutex> lock(cost_mu_);
  return !grid_.factor.empty();
}

CostGrid FramePlanner::costGrid() const {
  std::lock_guard<std::mutex> lock(cost_mu_);
  return grid_;
}

void FramePlanner::reportRegionCosts(int width, int height, const std::vector<RegionCost>& regions,
                                     const CostGrid& planned_with) {
  std::lock_guard<std::mutex> lock(cost_mu_);
  if (grid_.factor.empty()) return;
  // A new frame size (a viewer resized) starts the grid over: its cells
  // would cover other pixels.
  if (width != grid_width_ || height != grid_height_) {
    grid_ = CostGrid::uniform(grid_.columns, grid_.rows);
    grid_width_ = width;
    grid_height_ = height;
  }
  const CostGrid& base =
      planned_with.factor.size() == grid_.factor.size() && planned_with.columns == grid_.columns
          ? planned_with
          : CostGrid::uniform(grid_.columns, grid_.rows);  // planned before the grid knew this size
  correctCostGrid(&grid_, base, Rect{0, 0, width, height}, regions);
}

CostGrid FramePlanner::gridFor(int width, int height) const {
  std::lock_guard<std::mutex> lock(cost_mu_);
  if (grid_.factor.empty()) return {};
  if (width != grid_width_ || height != grid_height_)  // not learnt for this size yet
    return CostGrid::uniform(grid_.columns, grid_.rows);
  return grid_;
}

namespace {
// Fitted weights are in units of 1 ns of a client's time.
constexpr double kUnitsPerMs = 1e6;
uint64_t units(double ms) {
  return uint64_t(std::max(1.0, std::round(ms * kUnitsPerMs)));
}
}  // namespace

bool FramePlanner::drawnRecently(uint32_t o) const {
  uint32_t seen = drawn_in_[o].load(std::memory_order_relaxed);  // frame + 1, or 0
  return seen != 0 && seen + kSeenFrames > frame_;
}

uint64_t FramePlanner::weightOf(uint32_t o, const CostModel& model) const {
  uint64_t tris = boxes_[o].weight;
  if (!feedback_.load(std::memory_order_relaxed)) return tris;
  const double q = drawnFraction(o);
  if (model.fitted)
    return units(model.per_tested + q * (model.per_drawn + model.per_triangle * double(tris)));
  if (q == 1) return tris;
  return std::max(std::min(tris, kHiddenWeight), uint64_t(std::llround(q * double(tris))));
}

std::vector<Footprint> FramePlanner::footprints(const std::vector<uint32_t>& visible,
                                                const Camera& camera, int width, int height,
                                                const CostGrid& grid,
                                                double* spawned_cpu_ms) const {
  FootprintProjector project(camera, width, height);
  CostModel model = costModel();
  const Rect frame{0, 0, width, height};
  // Fill per footprint pixel, in the fitted units (not rounded: a pixel is a
  // few nanoseconds).
  const bool fitted = model.fitted && feedback_.load(std::memory_order_relaxed);
  const double fill = fitted ? model.per_fill * kUnitsPerMs : 0.0;
  const double raster = fitted ? model.per_raster * kUnitsPerMs : 0.0;
  return projectInSlices(
      visible.size(), footprintThreads(visible.size()),
      [&](size_t k, Footprint* f) {
        uint32_t o = visible[k];
        if (!project(boxes_[o].box, weightOf(o, model), o, f)) return false;
        if (fill > 0 || raster > 0) {
          double per_pixel = fill;
          if (raster > 0)
            per_pixel += raster * rasterPerPixel(double(boxes_[o].weight), overlapArea(*f, frame));
          f->fill = per_pixel * drawnFraction(o);
        }
        if (!grid.factor.empty()) {
          double factor = costGridFactor(grid, frame, f->x0, f->x1, f->y0, f->y1);
          f->weight = uint64_t(std::llround(double(f->weight) * factor));
          f->fill *= factor;
        }
        return true;
      },
      spawned_cpu_ms);
}

DrawnCover FramePlanner::coverOf(const Camera& camera, int width, int height, Rect region,
                                 const std::vector<uint32_t>& drawn) const {
  FootprintProjector project(camera, width, height);
  DrawnCover cover;
  Footprint f;
  const Rect frame{0, 0, width, height};
  for (uint32_t o : drawn) {
    if (o < boxes_.size() && project(boxes_[o].box, 0, o, &f)) {
      const double inside = overlapArea(f, region);
      cover.fill += inside;
      cover.raster += inside * rasterPerPixel(double(boxes_[o].weight), overlapArea(f, frame));
    }
  }
  return cover;
}

RegionForecast FramePlanner::forecast(const Camera& camera, int width, int height,
                                      const Region& region) const {
  RegionForecast f;
  f.objects = region.objects.size();
  std::vector<uint32_t> lately;
  if (feedback_.load(std::memory_order_relaxed))
    for (uint32_t o : region.objects)
      if (o < boxes_.size() && drawnFraction(o) >= 0.5) {
        lately.push_back(o);
        f.triangles_lately += boxes_[o].weight;
      }
  f.drawn_lately = lately.size();
  f.fill_lately = coverOf(camera, width, height, region.rect, lately).fill;
  return f;
}

std::ostream& operator<<(std::ostream& os, const RegionForecast& f) {
  return os << "{objects " << f.objects << ", drawn lately " << f.drawn_lately << " ("
            << f.triangles_lately << " triangles, fill " << f.fill_lately << ")}";
}

FramePlan planFrame(const Scene& scene, const Camera& camera, int width, int height, int clients) {
  return FramePlanner(scene).plan(camera, width, height, clients);
}

std::vector<uint32_t> FramePlanner::cull(const Camera& camera, uint64_t* objects,
                                         uint64_t* triangles) const {
  std::vector<uint32_t> visible;
  CullStats cs;
  cullObjects(scene_.skeleton, scene_.objects, frustumPlanes(camera), &visible, &cs);
  *objects = cs.objects;
  *triangles = cs.triangles;
  return visible;
}

namespace {
double msBetween(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}
}  // namespace

FramePlan FramePlanner::plan(const Camera& camera, int width, int height, int clients,
                             int regions_per_client, double pool_share, int pool_parts) const {
  const bool pooled = pool_share > 0 && pool_parts > 0;
  DMMR_CHECK(!pooled || (pool_share < 1 && regions_per_client == 1));
  using Clock = std::chrono::steady_clock;
  FramePlan plan;
  // The CPU interval nested in the wall one (t0 first, t2 last), so that the
  // CPU time cannot exceed the wall time measured, even when a virtual
  // machine's host steals the core between two clock reads.
  auto t0 = Clock::now();
  const double c0 = threadCpuMs();
  std::vector<uint32_t> visible =
      cull(camera, &plan.objects_in_frustum, &plan.triangles_in_frustum);
  if (unseen_ != Unseen::Hidden) noteInView(visible);  // hidden: nothing reads it
  auto t1 = Clock::now();
  plan.grid = gridFor(width, height);
  double spawned = 0;
  std::vector<Footprint> items = footprints(visible, camera, width, height, plan.grid, &spawned);
  auto tp = Clock::now();
  DivisionCosts costs;
  {
    std::lock_guard<std::mutex> lock(cost_mu_);
    if (model_.fitted) costs.pixel_weight = model_.per_pixel * kUnitsPerMs;
    std::vector<double> factors;
    costs.speeds = sharesLocked(clients, &factors);  // empty before a fit: equal shares
    if (!costs.speeds.empty() && regions_per_client > 1) {
      // Each of a client's regions at its share: region j is client j % clients's.
      std::vector<double> per_region;
      for (int j = 0; j < clients * regions_per_client; ++j)
        per_region.push_back(costs.speeds[size_t(regionClient(size_t(j), clients))]);
      costs.speeds = std::move(per_region);
    }
    if (!factors.empty()) {
      in_flight_[frame_] = std::move(factors);
      while (in_flight_.size() > kMaxInFlight) in_flight_.erase(in_flight_.begin());
    }
  }
  const int regions = clients * regions_per_client;
  if (pooled) {  // the pool is one region more, its share of the speeds
    if (costs.speeds.empty()) costs.speeds.assign(size_t(regions), 1.0);
    double sum = 0;
    for (double sp : costs.speeds) sum += sp;
    costs.speeds.push_back(sum * pool_share / (1 - pool_share));
  }
  plan.regions = divideFrame(items, Rect{0, 0, width, height}, regions + (pooled ? 1 : 0), costs);
  if (pooled) {
    const Rect rest = plan.regions.back().rect;
    plan.regions.pop_back();
    plan.pool = divideFrame(items, rest, pool_parts, DivisionCosts{costs.pixel_weight, {}});
  }
  for (const Region& r : plan.regions)
    plan.planned.push_back(double(r.weight) + costs.pixel_weight * double(r.rect.area()));
  plan.plan_cpu_ms = threadCpuMs() - c0 + spawned;
  auto t2 = Clock::now();
  plan.project_ms = msBetween(t1, tp);
  plan.cull_ms = msBetween(t0, t1);
  plan.divide_ms = msBetween(t1, t2);
  return plan;
}

TilePlan FramePlanner::planTiles(const Camera& camera, int width, int height, int tile_w,
                                 int tile_h) const {
  using Clock = std::chrono::steady_clock;
  TilePlan plan;
  // The CPU interval nested in the wall one (t0 first, t2 last), so that the
  // CPU time cannot exceed the wall time measured, even when a virtual
  // machine's host steals the core between two clock reads.
  auto t0 = Clock::now();
  const double c0 = threadCpuMs();
  std::vector<uint32_t> visible =
      cull(camera, &plan.objects_in_frustum, &plan.triangles_in_frustum);
  auto t1 = Clock::now();
  Rect frame{0, 0, width, height};
  plan.tiles = makeTiles(frame, tile_w, tile_h);
  plan.columns = (width + tile_w - 1) / tile_w;
  double spawned = 0;
  plan.objects = objectsPerTile(footprints(visible, camera, width, height, {}, &spawned), frame,
                                tile_w, tile_h);
  plan.plan_cpu_ms = threadCpuMs() - c0 + spawned;
  auto t2 = Clock::now();
  plan.cull_ms = msBetween(t0, t1);
  plan.divide_ms = msBetween(t1, t2);
  return plan;
}

}  // namespace dmmr
