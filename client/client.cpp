#include "client.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <future>
#include <iterator>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <string>
#include <thread>

#include "affinity.h"
#include "cpu_time.h"
#include "cull.h"
#include "depth_pyramid.h"
#include "draw.h"
#include "effects.h"
#include "error.h"
#include "gpu_cache.h"
#include "guarded.h"
#include "host_cache.h"
#include "image.h"
#include "memory_policy.h"
#include "protocol.h"
#include "queue.h"
#include "rt_cache.h"
#include "scene.h"
#include "stage_turns.h"

namespace dmmr {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// A job with what the visibility stage decided about it.
struct VisibleJob {
  FrameJob job;
  std::vector<uint32_t> visible;
  ClientStats stats;
  Clock::time_point ready;  // when the visibility stage finished it
  bool culled = false;      // the visibility stage culled `visible` from the job's list
  bool fused = false;       // the render stage culls (fused stages)
};

// Test hook: DMMR_INJECT_FAULT=STAGE:FRAME[:HOW] (STAGE visibility, render,
// or start, which is before the client says Hello, with FRAME 0; HOW throw,
// the default, foreign (throws an int, as a library might: no
// std::exception), kill or hang) makes that stage of client 1 fail at that
// frame (its first job at or after it), so tests reach the failure paths
// mid-run.
void injectFault(const char* stage, uint32_t frame) {
  const char* spec = std::getenv("DMMR_INJECT_FAULT");
  const char* rank = std::getenv("OMPI_COMM_WORLD_RANK");
  if (!spec || (rank && std::strcmp(rank, "1") != 0)) return;
  size_t n = std::strlen(stage);
  if (std::strncmp(spec, stage, n) != 0 || spec[n] != ':') return;
  char* rest = nullptr;
  // The first job at or after FRAME: under dynamic tiles, client 1 may be
  // dealt no tile of FRAME itself.
  unsigned long at = std::strtoul(spec + n + 1, &rest, 10);
  if (at > frame) return;
  if (std::strcmp(rest, ":kill") == 0) std::raise(SIGKILL);
  if (std::strcmp(rest, ":hang") == 0)
    for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
  if (std::strcmp(rest, ":foreign") == 0) throw int(frame);
  throw Error("fault injected by DMMR_INJECT_FAULT at frame " + std::to_string(at));
}

// Test and benchmark hook: DMMR_SLOW_CLIENT=RANK:FACTOR (FACTOR > 1) makes
// client RANK's render stage take FACTOR times its CPU time on each job, by
// spinning, as a CPU that much slower would (heterogeneous clients; with
// LP_NUM_THREADS=0 the stage's CPU time is its whole work). Returns 1 for
// every other client.
double slowFactor(int rank) {
  const char* spec = std::getenv("DMMR_SLOW_CLIENT");
  if (!spec) return 1;
  char* rest = nullptr;
  long r = std::strtol(spec, &rest, 10);
  if (r != rank || *rest != ':') return 1;
  double f = std::strtod(rest + 1, nullptr);
  return std::isfinite(f) && f > 1 ? f : 1;
}

void addGpuStats(ClientStats& st, const GpuCacheStats& before, const GpuCacheStats& after) {
  st.gpu_hits += after.hits - before.hits;
  st.gpu_misses += after.misses - before.misses;
  st.uncached += after.uncached - before.uncached;
  st.gpu_resident += after.resident;
}

// One GL context with the shared drawing code and its GPU cache level.
struct GlStage {
  GlStage(const Scene& scene, HostCache& host, const ContextOptions& ctx, const ViewOptions& view,
          const CacheOptions& cache, int64_t flush_triangles, int triangle_cull)
      : context(createContext(ctx)),
        renderer(context->gl(), view.width, view.height),
        backend(renderer),
        meshes(scene, host, backend, cache.gpu_budget, cache.eviction) {
    renderer.setFlushEvery(flushTrianglesFor(context->gl(), flush_triangles));
    renderer.setTriangleCull(triangleCullFor(context->gl(), triangle_cull));
  }
  std::unique_ptr<GlContext> context;
  Renderer renderer;
  RendererBackend backend;
  GpuCache meshes;
};

// Triangles of `objects` (the preprocessor's weights).
uint64_t regionTriangles(const Scene& scene, const std::vector<uint32_t>& objects) {
  uint64_t n = 0;
  for (uint32_t o : objects) n += scene.objects[o].weight;
  return n;
}

// What culling decided for one job, and what the deciding cost.
struct Decision {
  std::vector<uint32_t> visible;  // ascending: the render stage draws these
  size_t occluders = 0, tested = 0;
  double prepare_ms = 0;   // occluder pass, tests (queries issued, or boxes on the CPU)
  double retrieve_ms = 0;  // query results, or the depth read back
  double redraw_ms = 0;    // fused: the pixels newly visible objects may reach, drawn again
  // Fused: CPU time of drawing (step 1 and the new objects drawn on top, each
  // with its rasterisation); the rest of drawFused's CPU time is deciding.
  double draw_cpu_ms = 0;
  uint64_t triangles = 0;  // fused: of the objects drawn, each counted once
};

// Draws the parts `parts` selects of one object, returns the triangles drawn
// (0: unreadable, skipped).
using DrawFn = std::function<uint64_t(uint32_t, PartDraw)>;

// `sel` for `mesh`, geometry `geometry`'s, checked against its geometry file:
// a parts.bin from another preprocessing run would otherwise select the
// wrong triangles.
PartDraw checkedParts(const Scene& scene, uint32_t geometry, const GpuMesh& mesh, PartDraw sel) {
  if (sel.parts && !partsMatch(*sel.parts, mesh))
    throw Error(fileError(scene.dir + "/parts.bin",
                          "geometry " + std::to_string(geometry) +
                              ": its part triangle counts do not match the submeshes of " +
                              geometryFileName(geometry)));
  return sel;
}

// The visibility state of one client over a walkthrough, and the tests, on
// the GL stage it is given: the visibility stage's context (split stages) or
// the render stage's (fused).
class Culler {
 public:
  Culler(const Scene& scene, const VisibilityOptions& opts, GlStage& gl)
      : scene_(scene),
        opts_(opts),
        gl_(gl),
        marked_until_(scene.objects.size(), 0),
        part_draws_(opts.part_draws && !scene.parts.empty()) {
    if (part_draws_) {
      mask_.assign(scene.objects.size(), kAllParts);
      mask_stamp_.assign(scene.objects.size(), 0);
      frozen_stamp_.assign(scene.objects.size(), 0);
    }
    // Test hook: DMMR_FUSED_REDRAW=always takes the fused stage's redraw
    // path (the one a possible depth tie takes) in every frame.
    // DMMR_FUSED_REDRAW=equal takes the EQUAL colour pass whenever there are
    // new objects, and =equal-fails also, then redraws as if it found a tie.
    const char* redraw = std::getenv("DMMR_FUSED_REDRAW");
    std::string hook = redraw ? redraw : "";
    if (hook == "always") redraw_hook_ = RedrawHook::Always;
    if (hook == "equal") redraw_hook_ = RedrawHook::EqualAlways;
    if (hook == "equal-fails") redraw_hook_ = RedrawHook::EqualFails;
    // DMMR_PREDICT=hide-all: step 1's guess hides everything it may.
    const char* predict = std::getenv("DMMR_PREDICT");
    hide_all_ = predict && std::strcmp(predict, "hide-all") == 0;
  }

  // Split stages: occluders into depth, every candidate tested against it,
  // a second pass where objects passed that were not occluders.
  Decision decide(const FrameJob& job) {
    Decision d;
    auto t0 = Clock::now();
    newJob(job);
    startFrame(job);
    VisibilityPlan plan = planFor(job);
    Renderer& r = gl_.renderer;
    r.beginDepthFrame(job.camera, job.region);
    for (uint32_t o : plan.occluders) drawDepth(o);
    // Every object not marked is tested, occluders included (an occluder
    // hidden by other occluders need not be drawn; one that shows passes
    // against its own depth, since its widened box lies in front of it).
    // Occluders still marked from an earlier pass are taken untested, like
    // every marked object: the paper's n frames.
    std::vector<uint32_t> candidates, taken;  // taken: the marked occluders
    for (uint32_t o : mergeSorted({plan.occluders, plan.queried}))
      (job.frame < marked_until_[o] ? taken : candidates).push_back(o);
    std::vector<uint32_t> passed = test(candidates, job, &d, plan.occluders);
    // Second pass, for frames where the previous list was a poor occluder set
    // (the camera went through a wall): draw what passed and was not yet in
    // depth, and test it again against that fuller depth. Each object still
    // passes wherever it is the front-most, so exactness is unchanged.
    std::vector<uint32_t> fresh, kept;
    for (uint32_t o : passed)
      (std::binary_search(plan.occluders.begin(), plan.occluders.end(), o) ? kept : fresh)
          .push_back(o);
    if (!fresh.empty() && fresh.size() >= opts_.second_pass_min) {
      std::sort(fresh.begin(), fresh.end());
      for (uint32_t o : fresh) drawDepth(o);
      passed = test(fresh, job, &d, fresh);
      passed.insert(passed.end(), kept.begin(), kept.end());
    }
    gl_.context->gl().check("visibility tests");
    d.prepare_ms = msSince(t0) - d.retrieve_ms;
    std::sort(passed.begin(), passed.end());
    passed_now_.insert(passed_now_.end(), passed.begin(), passed.end());
    d.visible = mergeSorted({plan.marked, taken, passed});
    visible_now_.insert(visible_now_.end(), d.visible.begin(), d.visible.end());
    d.occluders = plan.occluders.size();
    return d;
  }

  // Fused stage, on the render stage's context, the frame begun by the
  // caller: draws the previous visible set (and the marked) in colour, reads
  // that depth back, tests the rest of the region against it, and draws what
  // is newly visible. Newly visible objects are drawn after objects of higher
  // index, so where they may reach (their footprints) the pixels are cleared
  // and drawn again in ascending order, which resolves depth ties as the
  // reference does. `draw` draws one object. Returns what was drawn.
  Decision drawFused(const FrameJob& job, const DrawFn& draw) {
    Decision d;
    newJob(job);
    startFrame(job);
    VisibilityPlan plan = planFor(job);
    std::vector<uint32_t> first = mergeSorted({plan.occluders, plan.marked});
    if (opts_.predict) predictFirst(job, &first, &d);
    double c1 = threadCpuMs();
    for (uint32_t o : first) d.triangles += draw(o, partsToDraw(o));
    d.draw_cpu_ms += threadCpuMs() - c1;
    // The candidates' bounds need no depth: worked out while llvmpipe's
    // threads still rasterise step 1.
    auto t0 = Clock::now();
    std::vector<uint32_t> candidates = unmarked(job);
    for (uint32_t o : candidates) bound(o, job.camera);
    d.prepare_ms += msSince(t0);
    c1 = threadCpuMs();
    gl_.renderer.finish();  // its rasterisation is drawing time
    d.draw_cpu_ms += threadCpuMs() - c1;
    t0 = Clock::now();
    std::vector<uint32_t> passed = testPyramid(candidates, job, &d);
    std::sort(passed.begin(), passed.end());
    auto newOnes = [&] {
      std::vector<uint32_t> fresh;
      std::set_difference(passed.begin(), passed.end(), first.begin(), first.end(),
                          std::back_inserter(fresh));
      return fresh;
    };
    std::vector<uint32_t> fresh = newOnes();
    double late_ms = 0;  // drawing the new objects: drawing, not deciding
    // Drawn after objects of higher index, a new object shows what the
    // reference shows wherever its depth differs from theirs; only an exact
    // tie with what is drawn already could resolve the other way. One query
    // (depth test EQUAL, nothing written) tells whether any fragment of the
    // new objects ties with the depth drawn so far; when none does (the
    // common case), they are drawn on top in ascending order, and a last
    // readback prunes the next frame's list.
    // Drawing the new objects on top also draws those that others among
    // them hide; when they are many (more triangles than a quarter of the
    // step-1 set), the second pass below, which leaves those out, is
    // cheaper.
    uint64_t fresh_tris = regionTriangles(scene_, fresh),
             first_tris = regionTriangles(scene_, first);
    bool few = fresh_tris * 4 <= first_tris + kFewNewTriangles;
    if (!fresh.empty() && few && redraw_hook_ == RedrawHook::None && !tiesWithDrawn(fresh)) {
      auto tl = Clock::now();
      double cl = threadCpuMs();
      for (uint32_t o : fresh) d.triangles += draw(o, partsToDraw(o));
      gl_.renderer.finish();
      late_ms = msSince(tl);
      d.draw_cpu_ms += threadCpuMs() - cl;
      if (fresh.size() >= opts_.second_pass_min) passed = retestWhereDrawn(passed, fresh, job, &d);
      d.prepare_ms += msSince(t0) - d.retrieve_ms - late_ms;
      return fusedDecision(std::move(d), plan, first, fresh, passed);
    }
    // A tie is possible: the new objects are tested again with a second
    // pass, as the split stages' is: they go into depth only (colour masked)
    // and everything that passed is tested against that fuller depth, so
    // that objects hidden by other new ones are neither drawn nor kept for
    // the next frame. The depth they leave outside the redrawn footprints is
    // only ever that of objects that pass (at each pixel the front-most
    // passes), which are redrawn there.
    // `objects` into depth only (colour masked), then what passed is tested
    // again against that fuller depth.
    auto depthPassAndRetest = [&](const std::vector<uint32_t>& objects) {
      gl_.renderer.maskColor(true);
      for (uint32_t o : objects) drawDepth(o);
      gl_.renderer.maskColor(false);
      passed = retestWhereDrawn(passed, objects, job, &d);
      fresh = newOnes();
    };
    // Many new objects: after their depth pass, try drawing them in colour
    // where their depth is the final one (colorWhereEqual) before redrawing
    // their footprints. Few with a tie: that would fail; redraw at once.
    bool try_equal =
        redraw_hook_ != RedrawHook::Always && (!few || redraw_hook_ != RedrawHook::None);
    bool depth_passed = false;
    if (!fresh.empty() && fresh.size() >= opts_.second_pass_min) {
      if (try_equal) step1_depth_ = depth_;
      // Nearest first, in batches: each batch of `among` (ascending) that
      // still passes and is not in depth yet goes into depth, and
      // everything that passed is tested again, so that what the nearer new
      // objects hide is not drawn (monuments25: 15% less client CPU than
      // one pass, docs/benchmarks.md). A batch is the nearest third of what
      // is left, by triangles, or `cap` triangles if fewer (0: no cap).
      std::vector<uint32_t> in_depth;
      auto nearestFirst = [&](const std::vector<uint32_t>& among, uint64_t cap) {
        for (;;) {
          std::vector<uint32_t> left, pending;
          std::set_intersection(fresh.begin(), fresh.end(), among.begin(), among.end(),
                                std::back_inserter(left));
          std::set_difference(left.begin(), left.end(), in_depth.begin(), in_depth.end(),
                              std::back_inserter(pending));
          if (pending.empty()) return;
          std::vector<uint32_t> batch = nearestBatch(pending, job, cap);
          depthPassAndRetest(batch);
          in_depth = mergeSorted({in_depth, batch});
        }
      };
      // When step 1 drew next to nothing (last frame's visible set left the
      // region: the camera turned or passed a wall), nearly the whole region
      // is new, and drawing all of it into depth is a brute-force pass. The
      // preprocessor's potential occluders among the new objects (big and
      // cheap) go first, an eighth of their triangles at a time, and only
      // what still passes after them is drawn. They are new objects too, so
      // the argument above holds for them.
      if (fresh_tris > kOccludersFirstRatio * first_tris + kFewNewTriangles) {
        std::vector<uint32_t> occluders;
        std::set_intersection(fresh.begin(), fresh.end(), scene_.occluders.begin(),
                              scene_.occluders.end(), std::back_inserter(occluders));
        if (!occluders.empty() && occluders.size() < fresh.size())
          nearestFirst(occluders, regionTriangles(scene_, occluders) / 8);
      }
      nearestFirst(fresh, 0);  // every new object still passing is now in depth
      depth_passed = true;
    }
    d.prepare_ms += msSince(t0) - d.retrieve_ms;
    if (!fresh.empty() && try_equal && depth_passed) {
      auto tr = Clock::now();
      uint64_t triangles = 0;
      bool done = colorWhereEqual(fresh, draw, &triangles);
      d.redraw_ms = msSince(tr);
      if (done) {
        d.triangles += triangles;
        return fusedDecision(std::move(d), plan, first, fresh, passed);
      }
    }
    if (!fresh.empty()) {
      auto tr = Clock::now();
      std::vector<uint32_t> drawn = mergeSorted({first, fresh});
      std::vector<Rect> footprints(drawn.size()), rects;
      for (size_t i = 0; i < drawn.size(); ++i) footprints[i] = footprint(drawn[i], job);
      for (size_t i = 0; i < drawn.size(); ++i)
        if (std::binary_search(fresh.begin(), fresh.end(), drawn[i]))
          rects.push_back(footprints[i]);
      std::vector<char> counted(drawn.size(), 0);  // new objects' triangles, once each
      for (const Rect& rect : coverRects(std::move(rects), kMaxRedrawRects)) {
        gl_.renderer.beginRedraw(rect);
        for (size_t i = 0; i < drawn.size(); ++i) {
          if (!overlaps(footprints[i], rect)) continue;
          uint64_t t = draw(drawn[i], partsToDraw(drawn[i]));
          if (!counted[i]++ && std::binary_search(fresh.begin(), fresh.end(), drawn[i]))
            d.triangles += t;
        }
      }
      d.redraw_ms += msSince(tr);
    }
    return fusedDecision(std::move(d), plan, first, fresh, passed);
  }

  // The cost model turned culling off for this job: everything is drawn,
  // and the region's objects are the next frame's occluders.
  void skip(const FrameJob& job) {
    adopt(job, job.objects);
    skipped_now_ = true;
  }

  // Instead of skip, on a job the cost model probes: after everything was
  // drawn, tests the region's objects against that depth (the finished
  // frame's), so that the cost model learns what culling would leave, and
  // the next frame starts from what passed rather than from everything.
  // Returns what passed, ascending.
  std::vector<uint32_t> probe(const FrameJob& job, Decision* d) {
    newJob(job);
    std::vector<uint32_t> passed = testPyramid(unmarked(job), job, d);
    std::sort(passed.begin(), passed.end());
    adopt(job, passed);
    return passed;
  }

  // Another culler decided this job (--stages auto runs split frames
  // between fused ones): its visible list (ascending) is this one's next
  // occluder set, so that a switch finds the list current.
  void adopt(const FrameJob& job, const std::vector<uint32_t>& visible) {
    startFrame(job);
    visible_now_.insert(visible_now_.end(), visible.begin(), visible.end());
  }

 private:
  static constexpr size_t kMaxRedrawRects = 16;
  // Cells of 16 x 16 pixels for retestWhereDrawn.
  static constexpr int kCoverageShift = 4;
  // The prediction works on texels of 4x4 pixels (0.5 ms a 512x512 frame,
  // against 1.6 ms at 2x2 for the same triangles drawn on plant10m), and
  // leaves out of step 1 an object whose box shows at no more than this
  // share of them: the reprojected depth is a little off at silhouettes and
  // where texels were filled, so "nowhere" would keep nearly every object
  // (docs/benchmarks.md, "Step 1 predicted").
  static constexpr int kPredictLevel = 2;
  static constexpr double kPredictShown = 0.03;
  // New objects of up to this many triangles are always few enough to draw
  // on top.
  static constexpr uint64_t kFewNewTriangles = 4096;
  // New objects of more than this many times step 1's triangles make the
  // second pass draw the potential occluders among them first.
  static constexpr uint64_t kOccludersFirstRatio = 8;

  // Leaves out of `first` (step 1's set) the objects that last frame's depth,
  // as this frame's camera sees it, all but hides: last frame's visible
  // objects that the camera's move put behind others. Those that do show
  // pass the test after step 1 and are drawn as new ones, so this changes
  // what is drawn first, never a pixel. Needs last frame's depth (the
  // culler's latest readback); without it `first` is kept.
  void predictFirst(const FrameJob& job, std::vector<uint32_t>* first, Decision* d) {
    if (pyramid_.levels() <= kPredictLevel || pyramid_frame_ == UINT32_MAX ||
        pyramid_frame_ + 1 != job.frame)
      return;
    auto t0 = Clock::now();
    reprojectDepth(pyramid_, kPredictLevel, pyramid_camera_, job.camera, gl_.renderer.width(),
                   gl_.renderer.height(), job.region, &predicted_);
    std::erase_if(*first, [&](uint32_t o) {
      return hide_all_ || shownFraction(predicted_, bound(o, job.camera)) <= kPredictShown;
    });
    d->prepare_ms += msSince(t0);
  }

  // A fused frame's bookkeeping: it drew `first` and `fresh`; what
  // `passed` (ascending) is marked and, with the marked, the next frame's
  // occluder set.
  Decision fusedDecision(Decision d, const VisibilityPlan& plan, const std::vector<uint32_t>& first,
                         const std::vector<uint32_t>& fresh, const std::vector<uint32_t>& passed) {
    d.visible = mergeSorted({first, fresh});
    passed_now_.insert(passed_now_.end(), passed.begin(), passed.end());
    std::vector<uint32_t> visible = mergeSorted({plan.marked, passed});
    visible_now_.insert(visible_now_.end(), visible.begin(), visible.end());
    d.occluders = first.size();
    return d;
  }

  VisibilityPlan planFor(const FrameJob& job) const {
    static const std::vector<uint32_t> kNone;
    const auto& potential =
        opts_.potential_every_frame || previous_.empty() ? scene_.occluders : kNone;
    // Last frame's visible list, and what the server says others drew among
    // objects that were not in this client's region last frame (a split
    // line moved): without it those would all be new, tested against a
    // depth that lacks them and, with fused stages, redrawn.
    std::vector<uint32_t> arrived;
    std::set_difference(job.hints.begin(), job.hints.end(), last_region_.begin(),
                        last_region_.end(), std::back_inserter(arrived));
    // A list from a frame drawn in full (skip) is the whole region, not
    // what was visible: no guess to fall back on.
    if (!before_skipped_ &&
        guessCollapsed(regionTriangles(scene_, previous_), regionTriangles(scene_, before_)))
      arrived = mergeSorted({arrived, before_});
    if (arrived.empty())
      return planVisibility(job.objects, previous_, potential, marked_until_, job.frame);
    return planVisibility(job.objects, mergeSorted({previous_, arrived}), potential, marked_until_,
                          job.frame);
  }

  // A frame can come as several jobs (tiles): what they found visible is the
  // next frame's occluder set, and what passed a test is marked from the next
  // frame on, so a frame's later tiles are not handed its earlier tiles'
  // objects untested. The jobs' objects make the region the next frame's
  // hints are taken against.
  void startFrame(const FrameJob& job) {
    if (job.frame != frame_) {
      for (uint32_t o : passed_now_) marked_until_[o] = frame_ + 1 + opts_.keep_frames;
      sortUnique(&visible_now_);  // the jobs' lists, each ascending, one after another
      before_.swap(previous_);
      previous_.swap(visible_now_);
      before_skipped_ = previous_skipped_;
      previous_skipped_ = skipped_now_;
      skipped_now_ = false;
      sortUnique(&region_now_);
      last_region_.swap(region_now_);
      passed_now_.clear();
      visible_now_.clear();
      region_now_.clear();
      frame_ = job.frame;
    }
    region_now_.insert(region_now_.end(), job.objects.begin(), job.objects.end());
  }

  static void sortUnique(std::vector<uint32_t>* v) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  }

  // The nearest of `objects` (ascending) by their boxes' nearest depth, at
  // least a third of their triangles or `cap`, whichever is fewer (cap 0:
  // none), and at least kFewNewTriangles (all of them when that leaves
  // few), ascending.
  std::vector<uint32_t> nearestBatch(const std::vector<uint32_t>& objects, const FrameJob& job,
                                     uint64_t cap) {
    uint64_t total = regionTriangles(scene_, objects);
    uint64_t third = total / 3;
    if (cap > 0) third = std::min(third, cap);
    uint64_t want = std::max<uint64_t>(third, kFewNewTriangles);
    if (total <= want + kFewNewTriangles) return objects;
    std::vector<std::pair<double, uint32_t>> by_depth;
    for (uint32_t o : objects) {
      ScreenBound b = bound(o, job.camera);
      by_depth.push_back({b.reaches_near ? INFINITY : b.nearest, o});
    }
    std::sort(by_depth.begin(), by_depth.end(), std::greater<>());
    std::vector<uint32_t> batch;
    uint64_t tris = 0;
    for (const auto& [depth, o] : by_depth) {
      if (tris >= want) break;
      batch.push_back(o);
      tris += scene_.objects[o].weight;
    }
    std::sort(batch.begin(), batch.end());
    return batch;
  }

  // The new objects' colour without redrawing what step 1 drew: `fresh`
  // (ascending, every one drawn into depth since step 1's readback, which
  // step1_depth_ holds; depth_ holds the readback after them) drawn in colour
  // with depth test EQUAL and no depth writes, counting the fragments that
  // pass. At every pixel whose depth the new objects changed, one of their
  // fragments has that depth (the nearest there: unique, it is the one the
  // reference shows); elsewhere the depth is step 1's. So the count equals the number of
  // changed pixels exactly when no other fragment ties: with none of step
  // 1's depth and none of another new fragment's. Then every pixel holds
  // what the reference shows, and true is returned. Otherwise (a tie: the
  // colour there may be the wrong object's) false, and the caller redraws the
  // new objects' footprints, which covers every pixel this pass wrote. The
  // count assumes drawDepth and draw make the same depth, as the tie query
  // does (draw.h). `*triangles`: the new objects' triangles drawn.
  bool colorWhereEqual(const std::vector<uint32_t>& fresh, const DrawFn& draw,
                       uint64_t* triangles) {
    uint64_t changed = 0;
    for (size_t i = 0; i < depth_.size(); ++i) changed += depth_[i] != step1_depth_[i];
    // Its own query object: a query's target is fixed by its first use, and
    // queries_[0] counts GL_ANY_SAMPLES_PASSED for the tie check.
    if (count_query_ == 0) gl_.context->gl().GenQueries(1, &count_query_);
    gl_.renderer.beginEqualColorPass(count_query_);
    for (uint32_t o : fresh) *triangles += draw(o, partsToDraw(o));
    gl_.renderer.endEqualColorPass();
    GLuint fragments = 0;
    gl_.context->gl().GetQueryObjectuiv(count_query_, GL_QUERY_RESULT, &fragments);
    return fragments == changed && redraw_hook_ != RedrawHook::EqualFails;
  }

  // Whether any fragment of `objects` has exactly the depth already in the
  // buffer at its pixel (one GL_ANY_SAMPLES_PASSED query, depth test EQUAL,
  // nothing written).
  bool tiesWithDrawn(const std::vector<uint32_t>& objects) {
    if (queries_.empty()) growQueries(1);
    Renderer& r = gl_.renderer;
    r.beginDepthEqualQuery(queries_[0]);
    for (uint32_t o : objects) drawDepth(o);
    r.endDepthEqualQuery();
    GLuint any = 1;
    gl_.context->gl().GetQueryObjectuiv(queries_[0], GL_QUERY_RESULT, &any);
    return any != 0;
  }

  void drawDepth(uint32_t object) {
    const ObjectBounds& o = scene_.objects[object];
    if (const GpuMesh* mesh = gl_.meshes.acquire(o.geometry))  // null: skipped, counted
      gl_.renderer.drawDepth(*mesh, o.transform, o.box, opts_.occluder_lod,
                             checkedParts(scene_, o.geometry, *mesh, partsToDraw(object)));
  }

  // The parts of `object` this job draws (PartDraw), fixed from its first
  // draw in the job on, so that its depth and colour passes and redraws all
  // draw the same triangles. Until then it is what the latest test of its
  // parts left (partsHide) or, untested, the parts that meet the region.
  // Either leaves out only parts no pixel of the final frame's region shows:
  // outside the region, or strictly behind depth drawn by objects that are
  // drawn (docs/architecture.md, "Part draws").
  PartDraw partsToDraw(uint32_t object) {
    if (!part_draws_) return {};
    const ObjectBounds& o = scene_.objects[object];
    const GeometryParts& g = scene_.parts[o.geometry];
    if (!g.ordered()) return {};
    if (mask_stamp_[object] != stamp_) {
      const Camera& camera = job_camera_;
      mask_[object] = partsInRegion(o, g, projector(camera), camera, gl_.renderer.width(),
                                    gl_.renderer.height(), bound(object, camera), job_region_);
      mask_stamp_[object] = stamp_;
    }
    frozen_stamp_[object] = stamp_;
    return {&g, mask_[object]};
  }

  // What a test of `object`'s parts left, for partsToDraw, unless a draw
  // already fixed its parts for this job.
  void testedParts(uint32_t object, uint8_t shown) {
    if (frozen_stamp_[object] == stamp_) return;
    mask_[object] = shown;
    mask_stamp_[object] = stamp_;
  }

  // `singles` (ascending): candidates likely visible, which queries test
  // alone instead of in runs.
  std::vector<uint32_t> test(const std::vector<uint32_t>& candidates, const FrameJob& job,
                             Decision* d, const std::vector<uint32_t>& singles) {
    if (opts_.method == VisibilityMethod::Queries)
      return queryHierarchically(candidates, job.camera, d, singles);
    return testPyramid(candidates, job, d);
  }

  // The object's conservative footprint and nearest depth (its query box's).
  // `camera` must be the current job's (newJob): the bound is kept for the
  // rest of the job, whose tests, batches and footprints ask for the same
  // objects again.
  ScreenBound bound(uint32_t object, const Camera& camera) const {
    if (bound_stamp_.size() != scene_.objects.size()) {
      bound_stamp_.assign(scene_.objects.size(), 0);
      bound_cache_.resize(scene_.objects.size());
    }
    if (bound_stamp_[object] == stamp_) return bound_cache_[object];
    const Box3d& box = scene_.objects[object].box;
    ScreenBound b{true};  // no box, no bound: it shows
    if (box.valid())
      b = projector(camera).bound(queryBoxBounds(box, camera, gl_.renderer.height()));
    bound_stamp_[object] = stamp_;
    bound_cache_[object] = b;
    return b;
  }

  // Whether no part box of the object (formats.h, GeometryParts) can show
  // against the pyramid, `ob` being its own bound: each part's rectangle
  // with the object's depth bound (partBound; docs/architecture.md, "Part
  // boxes"). False when the scene has no parts for it. `seen`: a pixel where
  // the pyramid found `ob` not hidden (or -1, -1): a part whose rectangle
  // holds it shows there too, untested. With part draws every part is
  // tested (the pyramid hides a part outside the region too) and those that
  // may show are what partsToDraw draws of it.
  bool partsHide(uint32_t object, const Camera& camera, const ScreenBound& ob,
                 std::pair<int, int> seen) {
    if (!opts_.part_boxes || scene_.parts.empty() || ob.reaches_near) return false;
    const ObjectBounds& o = scene_.objects[object];
    const GeometryParts& g = scene_.parts[o.geometry];
    if (g.parts.empty() || !o.box.valid() || o.weight < kMinPartTriangles) return false;
    std::array<ScreenBound, kMaxParts> parts;
    size_t n = partBounds(o, g, projector(camera), camera, gl_.renderer.height(), ob, &parts);
    const bool draws = part_draws_ && g.ordered();
    auto [sx, sy] = seen;
    uint8_t shown = 0;
    for (size_t k = 0; k < n; ++k) {
      const ScreenBound& p = parts[k];
      if (p.reaches_near || (sx >= p.x0 && sx <= p.x1 && sy >= p.y0 && sy <= p.y1)) {
        if (!draws) return false;
        shown = uint8_t(shown | 1u << k);
      }
    }
    for (size_t k = 0; k < n; ++k)
      if (!(shown >> k & 1) && !pyramid_.hides(parts[k])) {
        if (!draws) return false;
        shown = uint8_t(shown | 1u << k);
      }
    if (draws) testedParts(object, shown);
    return shown == 0;
  }

  // The job's objects not marked visible (the fused tests' candidates),
  // ascending.
  std::vector<uint32_t> unmarked(const FrameJob& job) const {
    std::vector<uint32_t> out;
    for (uint32_t o : job.objects)
      if (!(job.frame < marked_until_[o])) out.push_back(o);
    return out;
  }

  // A new job: bounds and parts kept for the last one no longer hold.
  void newJob(const FrameJob& job) {
    if (++stamp_ == 0) {  // wrapped: no stamp may match a kept one
      std::fill(bound_stamp_.begin(), bound_stamp_.end(), 0);
      std::fill(mask_stamp_.begin(), mask_stamp_.end(), 0);
      std::fill(frozen_stamp_.begin(), frozen_stamp_.end(), 0);
      stamp_ = 1;
      pyramid_stamp_ = 0;
    }
    projector_.reset();
    job_camera_ = job.camera;
    job_region_ = job.region;
  }

  // The job's projection (its camera; newJob drops it).
  const ScreenProjector& projector(const Camera& camera) const {
    if (!projector_) projector_.emplace(camera, gl_.renderer.width(), gl_.renderer.height());
    return *projector_;
  }

  // The pixels of the region the object may cover.
  Rect footprint(uint32_t object, const FrameJob& job) const {
    ScreenBound b = bound(object, job.camera);
    if (b.reaches_near) return job.region;
    return intersection(Rect{b.x0, b.y0, b.x1 + 1 - b.x0, b.y1 + 1 - b.y0}, job.region);
  }

  // testPyramid again for `passed` (ascending, objects that passed before
  // `drawn` went into depth): only those whose footprint shares a cell with
  // a footprint of `drawn` are tested, since the depth under the others is
  // what they passed against. The depth is read back in any case (the
  // prediction and the EQUAL pass use the latest). Returns what passes,
  // ascending.
  std::vector<uint32_t> retestWhereDrawn(const std::vector<uint32_t>& passed,
                                         const std::vector<uint32_t>& drawn, const FrameJob& job,
                                         Decision* d) {
    CellCoverage written(job.region, kCoverageShift);
    Rect dirty;  // the footprints' bounding rectangle
    for (uint32_t o : drawn) {
      Rect f = footprint(o, job);
      written.mark(f);
      dirty = boundingRect(dirty, f);
    }
    written.finish();
    std::vector<uint32_t> again, out;
    for (uint32_t o : passed) (written.meets(footprint(o, job)) ? again : out).push_back(o);
    std::vector<uint32_t> still = testPyramid(again, job, d, &dirty);
    out.insert(out.end(), still.begin(), still.end());
    std::sort(out.begin(), out.end());
    return out;
  }

  // Reads the depth drawn so far back once and tests `candidates`
  // (ascending) on the CPU against its farthest-depth pyramid, in rounds of
  // runs of consecutive objects like the queries (a run's bound is the union
  // of its members', so a hidden run hides them all). Returns those that may
  // show.
  // `dirty` (frame pixels, optional): the depth changed only there since
  // this job's last readback, which is then read back and rebuilt there
  // alone.
  std::vector<uint32_t> testPyramid(const std::vector<uint32_t>& candidates, const FrameJob& job,
                                    Decision* d, const Rect* dirty = nullptr) {
    // A region of no pixels (more clients than the frame has pixels, or a
    // pool part left empty) shows nothing.
    if (job.region.empty()) return {};
    // Rasterising what was drawn is drawing, not deciding: wait for it
    // before the readback is timed.
    gl_.renderer.finish();
    auto tr = Clock::now();
    if (dirty && pyramid_stamp_ == stamp_) {
      Rect r = intersection(*dirty, job.region);
      if (!r.empty()) {
        gl_.renderer.readDepth(r, &dirty_depth_);
        for (int y = 0; y < r.h; ++y)
          std::copy_n(dirty_depth_.data() + size_t(y) * size_t(r.w), size_t(r.w),
                      depth_.data() + size_t(y + r.y - job.region.y) * size_t(job.region.w) +
                          size_t(r.x - job.region.x));
        d->retrieve_ms += msSince(tr);
        pyramid_.update(depth_.data(), r);
      }
    } else {
      gl_.renderer.readDepth(job.region, &depth_);
      d->retrieve_ms += msSince(tr);
      pyramid_.build(depth_.data(), job.region);
      pyramid_stamp_ = stamp_;
    }
    pyramid_camera_ = job.camera;
    pyramid_frame_ = job.frame;
    bounds_.resize(candidates.size());
    for (size_t i = 0; i < candidates.size(); ++i) bounds_[i] = bound(candidates[i], job.camera);
    std::vector<uint32_t> passed;
    std::vector<std::pair<size_t, size_t>> runs = {{0, candidates.size()}}, next;
    for (uint32_t size : opts_.run_sizes) {
      next.clear();
      for (auto [begin, end] : runs)
        for (size_t b = begin; b < end; b += size) {
          size_t e = std::min(end, b + size);
          ScreenBound u = bounds_[b];
          for (size_t k = b + 1; k < e; ++k) u = unite(u, bounds_[k]);
          ++d->tested;
          std::pair<int, int> seen{-1, -1};
          if (pyramid_.hides(u, DepthPyramid::kDefaultBudget, &seen)) continue;
          if (e - b == 1) {
            if (!partsHide(candidates[b], job.camera, u, seen)) passed.push_back(candidates[b]);
          } else
            next.push_back({b, e});
        }
      runs.swap(next);
    }
    return passed;
  }

  // Tests `candidates` (ascending) against the depth drawn so far with
  // hardware occlusion queries: runs of consecutive objects (object indices
  // follow the skeleton's pre-order, so runs are spatially coherent) by
  // their union box, in rounds of decreasing run size (run_sizes, ending at
  // 1); returns those that pass. As in CHC++, only objects that were hidden
  // are batched into runs: `singles` (ascending; last frame's visible ones,
  // likely visible again) are queried alone from the first round. Boxes
  // reaching the near plane are not queried: they pass. A round's queries
  // are issued with no state change between them (Renderer::queryBoxes) and
  // its results all read before the next round reuses the query objects.
  std::vector<uint32_t> queryHierarchically(const std::vector<uint32_t>& candidates,
                                            const Camera& camera, Decision* d,
                                            const std::vector<uint32_t>& singles) {
    Renderer& r = gl_.renderer;
    const GlApi& gl = gl_.context->gl();
    GLenum target = opts_.query_threshold == 0 ? GL_ANY_SAMPLES_PASSED : GL_SAMPLES_PASSED;
    std::vector<uint32_t> passed;
    std::vector<std::pair<size_t, size_t>> runs, next;
    bool after_single = true;  // a run starts at the first candidate
    for (size_t k = 0; k < candidates.size(); ++k) {
      bool single = std::binary_search(singles.begin(), singles.end(), candidates[k]);
      if (single || after_single)
        runs.push_back({k, k + 1});
      else
        runs.back().second = k + 1;
      after_single = single;
    }
    std::vector<Box3d> boxes;
    for (uint32_t size : opts_.run_sizes) {
      std::vector<std::pair<size_t, size_t>> asked;
      next.clear();
      boxes.clear();
      for (auto [begin, end] : runs)
        for (size_t b = begin; b < end; b += size) {
          size_t e = std::min(end, b + size);
          Box3d box;
          for (size_t k = b; k < e; ++k) box.expand(scene_.objects[candidates[k]].box);
          if (boxReachesNearPlane(box, camera, r.height())) {
            if (e - b == 1)
              passed.push_back(candidates[b]);
            else
              next.push_back({b, e});
            continue;
          }
          boxes.push_back(box);
          asked.push_back({b, e});
        }
      if (queries_.size() < asked.size()) growQueries(asked.size());
      r.beginQueries();
      r.queryBoxes(boxes, queries_.data(), target);
      r.endQueries();
      d->tested += asked.size();
      auto tq = Clock::now();
      for (size_t i = 0; i < asked.size(); ++i) {
        GLuint samples = 0;
        gl.GetQueryObjectuiv(queries_[i], GL_QUERY_RESULT, &samples);
        bool shows =
            target == GL_ANY_SAMPLES_PASSED ? samples != 0 : samples > opts_.query_threshold;
        if (!shows) continue;
        if (asked[i].second - asked[i].first == 1)
          passed.push_back(candidates[asked[i].first]);
        else
          next.push_back(asked[i]);
      }
      d->retrieve_ms += msSince(tq);
      runs.swap(next);
    }
    return passed;
  }

  void growQueries(size_t n) {
    size_t old = queries_.size();
    queries_.resize(std::max(n, old * 2));
    gl_.context->gl().GenQueries(GLsizei(queries_.size() - old), queries_.data() + old);
  }

  const Scene& scene_;
  VisibilityOptions opts_;
  GlStage& gl_;
  std::vector<uint32_t> previous_;                  // last frame's visible list (ascending)
  std::vector<uint32_t> before_;                    // and the frame before's
  std::vector<uint32_t> last_region_, region_now_;  // the jobs' objects, last frame and this
  std::vector<uint32_t> marked_until_;              // per object: first frame to test again
  uint32_t frame_ = UINT32_MAX;                     // the frame of the jobs being decided
  std::vector<uint32_t> visible_now_, passed_now_;  // this frame's, over its jobs
  std::vector<GLuint> queries_;
  std::vector<float> depth_;
  DepthPyramid pyramid_;
  Camera pyramid_camera_;                // the camera pyramid_'s depth was drawn with
  uint32_t pyramid_frame_ = UINT32_MAX;  // and its frame
  uint32_t pyramid_stamp_ = 0;           // the job (stamp_) of depth_'s last full readback
  std::vector<float> dirty_depth_;       // testPyramid's partial readback
  // Whether the lists came from frames drawn in full (skip): last frame's
  // (previous_), the frame before's (before_), this frame's so far.
  bool previous_skipped_ = false, before_skipped_ = false, skipped_now_ = false;
  PredictedDepth predicted_;  // last frame's depth seen from this frame's camera
  std::vector<ScreenBound> bounds_;
  // bound()'s per job, by object: valid where bound_stamp_ equals stamp_.
  mutable std::vector<ScreenBound> bound_cache_;
  mutable std::vector<uint32_t> bound_stamp_;
  uint32_t stamp_ = 1;
  mutable std::optional<ScreenProjector> projector_;  // projector(), for this job
  Camera job_camera_;                                 // this job's (newJob)
  Rect job_region_;
  // partsToDraw's per job, by object: the parts to draw, valid where
  // mask_stamp_ equals stamp_, fixed where frozen_stamp_ does.
  bool part_draws_ = false;
  std::vector<uint8_t> mask_;
  std::vector<uint32_t> mask_stamp_, frozen_stamp_;
  enum class RedrawHook { None, Always, EqualAlways, EqualFails } redraw_hook_ = RedrawHook::None;
  std::vector<float> step1_depth_;  // the fused step 1's depth, kept for colorWhereEqual
  GLuint count_query_ = 0;          // colorWhereEqual's GL_SAMPLES_PASSED
  bool hide_all_ = false;
};

// What a client's stages share to decide how to work: the cost model (the
// visibility stage asks whether to cull, the render stage, which knows what
// drawing cost, records) and, for --stages auto, the trial of both stage
// modes (the visibility stage asks which mode a frame uses, the render stage
// records when frames finish).
class StageControl {
 public:
  StageControl(bool governor, StageMode stages) : enabled_(governor), stages_(stages) {
    // Test hook: DMMR_CULL_PAUSE=N starts the run with culling paused for N
    // jobs (of those with triangles), so that only the cost model's probes
    // can turn it back on.
    if (const char* pause = std::getenv("DMMR_CULL_PAUSE"))
      g_.pauseFor(uint32_t(std::strtoul(pause, nullptr, 10)));
  }
  // The stage mode of `frame`.
  // During the trial, a block's first frame waits (at most 2 s) until the
  // render stage has finished the frame before, so that one mode's block
  // does not overlap the other's: the server keeps frames in flight.
  StageMode mode(uint32_t frame) {
    if (stages_ != StageMode::Auto) return stages_;
    std::unique_lock<std::mutex> lock(mu_);
    if (first_frame_ == UINT32_MAX) first_frame_ = frame;
    uint32_t rel = frame - std::min(frame, first_frame_);
    StageMode m = trial_.modeFor(rel);
    if (!trial_.decided() && rel > 1 && trial_.modeFor(rel - 1) != m)
      done_cv_.wait_for(lock, std::chrono::seconds(2), [&] {
        return last_finished_ != UINT32_MAX && last_finished_ + 1 >= frame;
      });
    return m;
  }
  // The render stage finished `frame`; returns a line to log when this
  // decided the trial.
  std::string finished(uint32_t frame) {
    if (stages_ != StageMode::Auto) return "";
    std::lock_guard<std::mutex> lock(mu_);
    last_finished_ = frame;
    done_cv_.notify_all();
    if (trial_.decided() || first_frame_ == UINT32_MAX) return "";
    double ms = std::chrono::duration<double, std::milli>(Clock::now().time_since_epoch()).count();
    trial_.finished(frame - std::min(frame, first_frame_), ms);
    if (!trial_.decided()) return "";
    char line[200];
    std::snprintf(line, sizeof line,
                  "--stages auto: %s (split %.1f ms, fused %.1f ms per frame on the trial)",
                  trial_.chosen() == StageMode::Fused ? "fused" : "split", trial_.splitMs(),
                  trial_.fusedMs());
    return line;
  }
  // Whether a job whose list holds `region_triangles` is culled.
  bool culls(uint64_t region_triangles) {
    std::lock_guard<std::mutex> lock(mu_);
    if (!enabled_) return true;
    g_.region(region_triangles);
    return g_.culls();
  }
  bool probes() {
    std::lock_guard<std::mutex> lock(mu_);
    return enabled_ && g_.probes();
  }
  void probed(const CullCost& c) {
    std::lock_guard<std::mutex> lock(mu_);
    if (enabled_) g_.probed(c);
  }
  void record(bool culled, const CullCost& c) {
    std::lock_guard<std::mutex> lock(mu_);
    if (!enabled_) return;
    if (culled)
      g_.culled(c);
    else
      g_.unculled(c.region_triangles);
  }

 private:
  bool enabled_;
  StageMode stages_;
  std::mutex mu_;
  CullingGovernor g_;
  StageTrial trial_;
  uint32_t first_frame_ = UINT32_MAX;
  uint32_t last_finished_ = UINT32_MAX;  // the render stage's latest frame
  std::condition_variable done_cv_;
};

class VisibilityStage {
 public:
  VisibilityStage(const Scene& scene, HostCache& host, const ClientOptions& opts,
                  StageControl& control)
      : scene_(scene),
        host_(host),
        opts_(opts.visibility),
        prefetch_(opts.cache.prefetch),
        control_(control) {
    // Fused stages cull on the render stage's context: this one only passes
    // jobs on.
    if (opts_.method != VisibilityMethod::Off && opts_.stages != StageMode::Fused) {
      gl_ = std::make_unique<GlStage>(scene, host, opts.visibility_context, opts.view, opts.cache,
                                      opts.flush_triangles, opts.triangle_cull);
      culler_ = std::make_unique<Culler>(scene, opts_, *gl_);
      if (!opts.stage_turns.empty()) turns_ = std::make_unique<StageTurns>(opts.stage_turns);
    }
  }

  VisibleJob run(FrameJob job) {
    injectFault("visibility", job.frame);
    VisibleJob out;
    out.stats.objects = job.objects.size();
    bool here = culler_ && control_.mode(job.frame) != StageMode::Fused;
    // A job with nothing to draw (a background tile) is not culled here
    // either, nor counted as a skip: the render stage draws its empty list.
    const uint64_t region_tris = here ? regionTriangles(scene_, job.objects) : 0;
    const bool empty = here && region_tris == 0;
    if (!here || empty || !control_.culls(region_tris)) {
      // The render stage gets the whole list: it culls (fused stages), or
      // nothing does (no culling, or the cost model paused it).
      if (!here)
        out.fused = opts_.method != VisibilityMethod::Off;
      else if (!empty)
        culler_->skip(job);
      out.visible = job.objects;
      out.stats.visible = out.visible.size();
      out.job = std::move(job);
      return out;
    }
    StageTurns::Hold turn(turns_.get());
    double cpu0 = threadCpuMs();
    ThreadUsage usage0 = threadUsage();
    gl_->meshes.nextFrame();
    GpuCacheStats before = gl_->meshes.stats();
    Decision d = culler_->decide(job);
    addGpuStats(out.stats, before, gl_->meshes.stats());
    out.stats.vis_cpu_ms = threadCpuMs() - cpu0;
    ThreadUsage usage1 = threadUsage();
    out.stats.vis_sys_ms = usage1.sys_ms - usage0.sys_ms;
    out.stats.vis_faults = usage1.minor_faults - usage0.minor_faults;
    out.culled = true;
    out.visible = std::move(d.visible);
    out.stats.prepare_ms = d.prepare_ms;
    out.stats.retrieve_ms = d.retrieve_ms;
    out.stats.occluders = d.occluders;
    out.stats.queried = d.tested;
    out.stats.visible = out.visible.size();
    out.job = std::move(job);
    // Prefetch what the render stage will draw (it is a frame behind), so
    // its disk reads overlap this stage's and that stage's work.
    std::vector<uint32_t> geometries;
    geometries.reserve(out.visible.size());
    for (uint32_t o : out.visible) geometries.push_back(scene_.objects[o].geometry);
    if (prefetch_) host_.prefetch(geometries, /*urgent=*/true);
    return out;
  }

 private:
  const Scene& scene_;
  HostCache& host_;
  VisibilityOptions opts_;
  bool prefetch_;
  StageControl& control_;
  std::unique_ptr<GlStage> gl_;
  std::unique_ptr<Culler> culler_;
  std::unique_ptr<StageTurns> turns_;
};

// The render stage's ray tracer and its device level (--renderer raytrace).
struct RayStage {
  RayStage(const Scene& scene, HostCache& host, const ClientOptions& opts)
      : tracer(opts.ray_threads),
        meshes(
            scene, host,
            [this, q = opts.ray.quality, compact = opts.ray.compact](const GeometryData& g) {
              return tracer.build(g, q, compact);
            },
            opts.cache.gpu_budget, opts.cache.eviction) {}
  RayTracer tracer;
  RtCache meshes;
  // The tracer's top level: the objects jobs needed, kept while the device
  // level holds their meshes, so that the tiles of a frame and frames alike
  // find it ready (trace()). `pinned[i]` keeps instances[i]'s mesh alive.
  std::vector<RtInstance> instances;
  std::vector<std::shared_ptr<const RtMesh>> pinned;
  std::vector<uint32_t> top_index;  // by object: its index in `instances` (kNone: absent)
  std::vector<uint64_t> needed_stamp, geometry_stamp;  // by object, by geometry: this job's
  std::vector<uint32_t> geometry_slot;                 // by geometry: its index in job_meshes
  std::vector<std::shared_ptr<const RtMesh>> job_meshes;
  uint64_t stamp = 0;
  uint64_t list_version = 1;  // of `instances`, for RayTracer::render
  std::vector<uint32_t> required, all_objects;
  // What the whole of the last frame seen gives every job of it (frameSets):
  // its view, the anchor grid and, with shadows, the light's casters (the
  // whole frame's, so that every tile and division sees the same set).
  struct FrameSets {
    uint32_t frame = UINT32_MAX;
    Camera camera;
    std::vector<uint32_t> view, casters;
    double grid = 0;
  } sets;
  static constexpr uint32_t kNone = UINT32_MAX;
};

class RenderStage {
 public:
  RenderStage(const Scene& scene, HostCache& host, const ClientOptions& opts, StageControl& control,
              std::vector<SurfaceEffect> effects = {})
      : scene_(scene),
        host_(host),
        codec_(opts.codec),
        control_(control),
        host_before_(host.stats()),
        rank_(opts.rank),
        ray_opts_(opts.ray),
        effects_(effects),
        part_draws_(!opts.raytrace && opts.visibility.part_draws && !scene.parts.empty()) {
    if (opts.raytrace) {
      ray_ = std::make_unique<RayStage>(scene, host, opts);
    } else
      gl_ = std::make_unique<GlStage>(scene, host, opts.render_context, opts.view, opts.cache,
                                      opts.flush_triangles, opts.triangle_cull);
    if (!opts.raytrace && opts.visibility.method != VisibilityMethod::Off &&
        opts.visibility.stages != StageMode::Split)
      culler_ = std::make_unique<Culler>(scene, opts.visibility, *gl_);
    if (!opts.stage_turns.empty()) turns_ = std::make_unique<StageTurns>(opts.stage_turns);
    slow_ = slowFactor(opts.rank);
  }

  SubFrame run(const VisibleJob& v) {
    const FrameJob& job = v.job;
    injectFault("render", job.frame);
    StageTurns::Hold turn(turns_.get());
    double cpu0 = threadCpuMs();
    ThreadUsage usage0 = threadUsage();
    SubFrame out;
    out.frame = job.frame;
    out.region = job.region;
    out.stats = v.stats;
    ClientStats& st = out.stats;
    st.pass_ms = msSince(v.ready);  // from list ready to the render stage taking it
    if (ray_) {
      trace(v, st);
      out.drawn = v.visible;
      finishSubFrame(job, cpu0, usage0, out);
      return out;
    }
    // Per job: under tiles each tile is a frame for eviction, on purpose
    // (docs/architecture.md, "Geometry cache").
    gl_->meshes.nextFrame();
    host_.nextFrame();
    GpuCacheStats gpu_before = gl_->meshes.stats();
    auto t0 = Clock::now();
    Renderer& r = gl_->renderer;
    const uint64_t submitted0 = r.trianglesSubmitted();
    r.beginFrame(job.camera, job.region);
    auto draw = [&](uint32_t index, PartDraw parts) -> uint64_t {
      const ObjectBounds& o = scene_.objects[index];
      auto tl = Clock::now();
      const GpuMesh* mesh = gl_->meshes.acquire(o.geometry);
      st.load_ms += msSince(tl);
      if (!mesh) return 0;  // unreadable geometry: skipped, counted
      return r.draw(*mesh, o.transform, o.box, gl_->meshes.textures(),
                    checkedParts(scene_, o.geometry, *mesh, parts));
    };
    // Outside the fused culler (a paused or probed job, split stages): the
    // parts that meet the region.
    std::optional<ScreenProjector> projector;
    auto regionParts = [&](uint32_t index) -> PartDraw {
      const ObjectBounds& o = scene_.objects[index];
      if (!part_draws_ || !drawnByParts(o, scene_.parts[o.geometry])) return {};
      if (!projector) projector.emplace(job.camera, r.width(), r.height());
      const GeometryParts& g = scene_.parts[o.geometry];
      ScreenBound ob = projector->bound(queryBoxBounds(o.box, job.camera, r.height()));
      return {&g,
              partsInRegion(o, g, *projector, job.camera, r.width(), r.height(), ob, job.region)};
    };
    const double cpu_draw0 = threadCpuMs();
    const uint64_t region_tris = regionTriangles(scene_, job.objects);
    // A job with nothing to draw (a background tile) is neither culled nor
    // probed: there is nothing to save, and the cost model does not count it.
    const bool empty = region_tris == 0;
    bool fused_culled = v.fused && !empty && control_.culls(region_tris),
         culled = v.culled || fused_culled;
    Decision fused;
    double probe_ms = 0;   // the cost model's probe, when it paused culling
    double fused_cpu = 0;  // drawFused's CPU time
    if (fused_culled) {
      double c = threadCpuMs();
      fused = culler_->drawFused(job, draw);
      fused_cpu = threadCpuMs() - c;
      st.prepare_ms = fused.prepare_ms;
      st.retrieve_ms = fused.retrieve_ms;
      st.occluders = fused.occluders;
      st.queried = fused.tested;
      st.visible = fused.visible.size();
      st.triangles = fused.triangles;
    } else {
      bool probe = v.fused && !empty && control_.probes();
      if (v.fused && !probe && !empty)
        culler_->skip(job);
      else if (!v.fused && culler_)
        culler_->adopt(job, v.visible);  // a split frame of --stages auto
      for (uint32_t index : v.visible)   // ascending, as the reference
        st.triangles += draw(index, regionParts(index));
      if (probe) probeCulling(job, t0, cpu_draw0, region_tris, st, &probe_ms);
    }
    const std::vector<uint32_t>& drawn = fused_culled ? fused.visible : v.visible;
    r.finish();
    st.submitted = r.trianglesSubmitted() - submitted0;
    if (slow_ > 1) {  // DMMR_SLOW_CLIENT: spin (slow_ - 1) times the work so far
      double until = threadCpuMs() + (slow_ - 1) * (threadCpuMs() - cpu0);
      while (threadCpuMs() < until) {
      }
    }
    addGpuStats(st, gpu_before, gl_->meshes.stats());
    addHostStats(st);
    double culling = fused_culled ? fused.prepare_ms + fused.retrieve_ms : probe_ms;
    st.render_ms = msSince(t0) - st.load_ms - culling;
    // Deciding cost: the visibility stage's work, or the fused stage's
    // readback, tests and redraws. When llvmpipe rasterises on the stage
    // threads, their CPU time: with more processes than cores, wall-time
    // intervals measure whom the scheduler ran, and short ones (drawing a few
    // objects) against long ones (testing thousands) paused culling where it
    // paid (docs/benchmarks.md, "Pauses and growing regions").
    if (cpu_costs_ && (fused_culled || !v.fused))
      control_.record(culled, CullCost{v.fused ? fused_cpu - fused.draw_cpu_ms : v.stats.vis_cpu_ms,
                                       v.fused ? fused.draw_cpu_ms : threadCpuMs() - cpu_draw0,
                                       st.triangles, region_tris});
    else
      control_.record(
          culled,
          CullCost{v.fused ? culling + fused.redraw_ms : v.stats.prepare_ms + v.stats.retrieve_ms,
                   st.render_ms - (v.fused ? fused.redraw_ms : 0), st.triangles, region_tris});
    auto tr = Clock::now();
    r.readPixels(job.region, &rgba_);
    st.readback_ms = msSince(tr);
    out.drawn = drawn;  // lets the server weigh the next frames by what shows
    finishSubFrame(job, cpu0, usage0, out);
    return out;
  }

  void sent(double ms) { last_send_ms_ = ms; }

 private:
  // A job drawn in full while the cost model paused culling, and due for a
  // probe (CullingGovernor::probes): the culler tests the region against the
  // finished frame's depth, and the cost model hears what culling it would
  // have cost (the probe's readback and tests, twice, as a culled fused
  // frame reads back and tests at least twice) and saved (the draw time of
  // the triangles that did not pass). Its time counts as deciding.
  // `t0`, `cpu0`: when the job's drawing began, by the wall and the thread's
  // CPU clock; `region`: the triangles of the job's list.
  void probeCulling(const FrameJob& job, Clock::time_point t0, double cpu0, uint64_t region,
                    ClientStats& st, double* probe_ms) {
    gl_->renderer.finish();  // drawing, not probing
    double draw_ms = msSince(t0) - st.load_ms, draw_cpu = threadCpuMs() - cpu0;
    auto tp = Clock::now();
    double cp = threadCpuMs();
    Decision d;
    std::vector<uint32_t> passed = culler_->probe(job, &d);
    *probe_ms = msSince(tp);
    double probe_cpu = threadCpuMs() - cp;
    st.prepare_ms = *probe_ms - d.retrieve_ms;
    st.retrieve_ms = d.retrieve_ms;
    st.queried = d.tested;
    uint64_t kept = regionTriangles(scene_, passed);
    double decide = cpu_costs_ ? probe_cpu : *probe_ms, drew = cpu_costs_ ? draw_cpu : draw_ms;
    control_.probed(
        CullCost{2 * decide, region ? drew * double(kept) / double(region) : 0, kept, region});
  }

 public:
 private:
  // The host levels are shared by both stages; each sub-frame reports their
  // activity since the previous one.
  void addHostStats(ClientStats& st) {
    HostCacheStats h = host_.stats();
    st.ram_hits = h.hits - host_before_.hits;
    st.ram_misses = h.misses - host_before_.misses;
    st.disk_bytes = h.disk_bytes - host_before_.disk_bytes;
    st.uncached += h.uncached - host_before_.uncached;
    st.skipped = h.skipped - host_before_.skipped;
    st.ram_resident = h.resident;
    host_before_ = h;
  }

  // --renderer raytrace: the objects a job needs are its list (nothing culls
  // it), with shadows also the light's casters for the whole frame, with
  // reflections every object. Each one's BVH comes from the device level.
  // The tracer's top level keeps objects from job to job: it changes only
  // when a job needs an object it lacks, and then holds what the job needs
  // and every other object of the whole frame's view whose BVH the device
  // level holds, so that the frame's other tiles, and the next frames, seldom
  // change it again (without that, objects crossing from another client's
  // tiles rebuilt it many times a frame). Objects beyond what a job needs
  // change no pixel: a primary ray of the region meets only objects whose
  // box the region's sub-frustum holds (all in the list), and a shadow ray
  // from a point in view only casters. The device level's counts go where
  // the GPU level's do.
  void trace(const VisibleJob& v, ClientStats& st) {
    const FrameJob& job = v.job;
    RayStage& rs = *ray_;
    rs.meshes.nextFrame();
    host_.nextFrame();
    RtCacheStats before = rs.meshes.stats();
    const size_t objects = scene_.objects.size(), geometries = scene_.manifest.geometries;
    if (rs.top_index.size() != objects) {
      rs.top_index.assign(objects, RayStage::kNone);
      rs.needed_stamp.assign(objects, 0);
      rs.geometry_stamp.assign(geometries, 0);
      rs.geometry_slot.assign(geometries, 0);
    }
    const std::vector<uint32_t>& needed = neededObjects(v);
    const uint64_t stamp = ++rs.stamp;
    bool changed = false;
    st.visible = 0;  // the objects traced (the visibility stage passed them all)
    for (uint32_t index : needed) {
      const ObjectBounds& o = scene_.objects[index];
      if (rs.geometry_stamp[o.geometry] != stamp) {  // one lookup per geometry
        rs.geometry_stamp[o.geometry] = stamp;
        rs.geometry_slot[o.geometry] = uint32_t(rs.job_meshes.size());
        auto tl = Clock::now();
        rs.job_meshes.push_back(rs.meshes.acquire(o.geometry));
        st.load_ms += msSince(tl);
      }
      const std::shared_ptr<const RtMesh>& mesh = rs.job_meshes[rs.geometry_slot[o.geometry]];
      if (!mesh) continue;  // unreadable geometry: skipped, counted
      rs.needed_stamp[index] = stamp;
      uint32_t at = rs.top_index[index];
      changed |= at == RayStage::kNone || rs.instances[at].mesh != mesh.get();
      st.triangles += mesh->triangles();
      ++st.visible;
    }
    if (changed) {
      ++rs.list_version;
      // A new top level: what this job needs, and what else the frame shows
      // that the device level holds (marked with this job's stamp too).
      // Changed in place (a leaving object's place taken by the last), so
      // that the tracer finds most objects where they were.
      const std::vector<uint32_t>& view = frameSets(job).view;
      for (uint32_t index : view) {
        if (rs.needed_stamp[index] == stamp) continue;
        const ObjectBounds& o = scene_.objects[index];
        if (rs.geometry_stamp[o.geometry] != stamp) {
          if (!rs.meshes.holds(o.geometry)) continue;  // not built here: not needed here
          rs.geometry_stamp[o.geometry] = stamp;
          rs.geometry_slot[o.geometry] = uint32_t(rs.job_meshes.size());
          rs.job_meshes.push_back(rs.meshes.acquire(o.geometry));  // held: no load
        }
        if (rs.job_meshes[rs.geometry_slot[o.geometry]]) rs.needed_stamp[index] = stamp;
      }
      for (size_t i = 0; i < rs.instances.size();) {
        uint32_t index = rs.instances[i].object;
        if (rs.needed_stamp[index] == stamp) {
          ++i;
          continue;
        }
        rs.top_index[index] = RayStage::kNone;
        if (i + 1 != rs.instances.size()) {
          rs.instances[i] = rs.instances.back();
          rs.pinned[i] = std::move(rs.pinned.back());
          rs.top_index[rs.instances[i].object] = uint32_t(i);
        }
        rs.instances.pop_back();
        rs.pinned.pop_back();
      }
      auto add = [&](uint32_t index) {
        if (rs.needed_stamp[index] != stamp) return;  // unreadable, or not held
        const ObjectBounds& o = scene_.objects[index];
        const std::shared_ptr<const RtMesh>& mesh = rs.job_meshes[rs.geometry_slot[o.geometry]];
        uint32_t at = rs.top_index[index];
        if (at != RayStage::kNone) {  // there; its mesh may have been built again
          rs.instances[at].mesh = mesh.get();
          rs.pinned[at] = mesh;
          return;
        }
        SurfaceEffect effect = index < effects_.size() ? effects_[index] : SurfaceEffect::None;
        rs.top_index[index] = uint32_t(rs.instances.size());
        rs.instances.push_back({mesh.get(), o.transform, effect, index});
        rs.pinned.push_back(mesh);
      };
      for (uint32_t index : needed) add(index);
      for (uint32_t index : view) add(index);
    }
    auto tr = Clock::now();
    RayOptions opts = ray_opts_;
    opts.stride = job.ray_stride;  // the server's choice for this frame
    opts.anchor_grid = frameSets(job).grid;
    RtRenderStats top =
        rs.tracer.render(job.camera, job.width, job.height, job.region, rs.instances,
                         rs.meshes.textures(), opts, &rgba_, {}, rs.list_version);
    st.render_ms = msSince(tr) - top.top_ms;
    st.prepare_ms = top.top_ms;  // the top level's update
    rs.job_meshes.clear();       // meshes evicted during the gather and not kept are freed now
    RtCacheStats after = rs.meshes.stats();
    st.gpu_hits += after.hits - before.hits;
    st.gpu_misses += after.misses - before.misses;
    st.uncached += after.uncached - before.uncached;
    st.gpu_resident += after.resident;
    addHostStats(st);
  }

  static double boxDistance(const Box3d& b, Vec3d p) {
    double d2 = 0;
    for (int i = 0; i < 3; ++i) {
      double e = std::max({b.lo[i] - p[i], 0.0, p[i] - b.hi[i]});
      d2 += e * e;
    }
    return std::sqrt(d2);
  }

  // The frame's sets, computed once for all its jobs (RayStage::FrameSets):
  // - the view: the objects in the whole frame's frustum, culled through the
  //   skeleton (see trace());
  // - the top level's anchor grid (RayOptions::anchor_grid): the power of
  //   two at or below 64 times the distance d from the eye to the nearest
  //   box of the view (at least the near plane). Every client computes it
  //   from the frame alone, so all use one anchor and distributed frames
  //   equal one client's; the top level is set again only when the eye
  //   crosses into another cell or the grid changes; and since every visible
  //   surface is at least d away, a point's float error relative to its
  //   distance from the eye is at most 1 + 0.87 * 64 = 57 times what eye
  //   coordinates give (docs/raytrace.md);
  // - with shadows, the light's casters (shadowCasterPlanes).
  const RayStage::FrameSets& frameSets(const FrameJob& job) {
    RayStage::FrameSets& f = ray_->sets;
    if (f.frame == job.frame && f.camera == job.camera) return f;
    f.frame = job.frame;
    f.camera = job.camera;
    f.view.clear();
    cullObjects(scene_.skeleton, scene_.objects, frustumPlanes(job.camera), &f.view);
    double nearest = std::numeric_limits<double>::infinity();
    for (uint32_t index : f.view)
      nearest = std::min(nearest, boxDistance(scene_.objects[index].box, job.camera.eye));
    double d = std::max(job.camera.near, std::isfinite(nearest) ? nearest : 0.0);
    f.grid = std::exp2(std::floor(std::log2(64 * d)));
    f.casters.clear();
    if (ray_opts_.shadows)
      cullObjects(scene_.skeleton, scene_.objects,
                  shadowCasterPlanes(frustumPlanes(job.camera), ray_opts_.light), &f.casters);
    return f;
  }

  // The objects job `v` needs traced (ascending): see trace().
  const std::vector<uint32_t>& neededObjects(const VisibleJob& v) {
    RayStage& rs = *ray_;
    if (ray_opts_.reflections && ray_opts_.max_depth > 0) {  // a mirror may show anything
      if (rs.all_objects.size() != scene_.objects.size()) {
        rs.all_objects.resize(scene_.objects.size());
        std::iota(rs.all_objects.begin(), rs.all_objects.end(), 0u);
      }
      return rs.all_objects;
    }
    if (!ray_opts_.shadows) return v.visible;
    const std::vector<uint32_t>& casters = frameSets(v.job).casters;
    rs.required.clear();
    std::set_union(v.visible.begin(), v.visible.end(), casters.begin(), casters.end(),
                   std::back_inserter(rs.required));
    return rs.required;
  }

  // rgba_ holds the region's pixels: convert, compress, finish the stats.
  // `cpu0`, `usage0`: the stage thread's CPU clock and usage when the job began.
  void finishSubFrame(const FrameJob& job, double cpu0, ThreadUsage usage0, SubFrame& out) {
    ClientStats& st = out.stats;
    auto tr = Clock::now();
    rgb_.resize(size_t(job.region.area()) * 3);
    rgbaToRgb(rgba_.data(), size_t(job.region.area()), rgb_.data());
    st.readback_ms += msSince(tr);
    auto tc = Clock::now();
    out.codec = codec_;
    out.raw_size = rgb_.size();
    out.data = compress(codec_, rgb_.data(), rgb_.size());
    st.compress_ms = msSince(tc);
    st.bytes_raw = rgb_.size();
    st.bytes_sent = out.data.size();
    st.render_cpu_ms = threadCpuMs() - cpu0;
    ThreadUsage usage1 = threadUsage();
    st.render_sys_ms = usage1.sys_ms - usage0.sys_ms;
    st.render_faults = usage1.minor_faults - usage0.minor_faults;
    st.send_ms = last_send_ms_;
    std::string chosen = control_.finished(job.frame);
    if (!chosen.empty())
      std::fprintf(stderr, "dmmr-render: client rank %d: %s\n", rank_, chosen.c_str());
  }

  const Scene& scene_;
  HostCache& host_;
  Codec codec_;
  std::unique_ptr<GlStage> gl_;    // rasterising
  std::unique_ptr<RayStage> ray_;  // or ray-tracing
  StageControl& control_;
  std::unique_ptr<Culler> culler_;
  std::unique_ptr<StageTurns> turns_;
  double slow_ = 1;  // DMMR_SLOW_CLIENT
  HostCacheStats host_before_;
  int rank_;
  const bool cpu_costs_ = rasterisesOnCallingThread();  // the cost model judges by CPU time
  double last_send_ms_ = 0;
  std::vector<uint8_t> rgba_, rgb_;  // the readback's, kept across frames
  RayOptions ray_opts_;
  std::vector<SurfaceEffect> effects_;
  bool part_draws_ = false;  // draw the parts that meet the region (VisibilityOptions)
};

// Sends the first error of any stage to the server; later stages drain their
// queues without work until Shutdown arrives, so no rank blocks.
class FailureReport {
 public:
  explicit FailureReport(Comm& comm) : comm_(comm) {}
  void fail(const std::string& what) {
    std::lock_guard<std::mutex> lock(mu_);
    if (failed_) return;
    failed_ = true;
    comm_.send(0, Tag::Error, encodeText(what));
  }
  bool failed() const { return failed_; }

 private:
  Comm& comm_;
  std::mutex mu_;
  std::atomic<bool> failed_{false};
};

// Runs `make` on a new thread, reports whether it succeeded through the
// future, then runs `loop` with the object it made (on that same thread,
// where its GL context is current). Whatever escapes (any exception type,
// from the loop or the stage's destructor's callees) goes to `escaped`, and
// then `drain` runs, so the threads that feed this one never block on it.
template <typename Stage, typename Loop, typename Escaped, typename Drain>
std::thread startStage(const char* name, std::function<std::unique_ptr<Stage>()> make, Loop loop,
                       std::promise<std::string>* ready, Escaped escaped, Drain drain) {
  return std::thread([name, make, loop, ready, escaped, drain] {
    nameThisThread(name);
    std::unique_ptr<Stage> stage;
    std::string problem;
    runGuarded([&] { stage = make(); }, [&](const std::string& what) { problem = what; });
    ready->set_value(problem);
    runGuarded(
        [&] {
          loop(stage.get());  // null when construction failed: the loop only drains
          stage.reset();      // GL teardown on the thread whose context it is
        },
        escaped);
    drain();
  });
}

// Objects that entered the region since the last job: asked for ahead of
// the visibility and render stages, into free RAM only.
void prefetchEntering(const Scene& scene, HostCache& host, const std::vector<uint32_t>& objects,
                      std::vector<uint32_t>* region) {
  std::vector<uint32_t> entering, geometries;
  std::set_difference(objects.begin(), objects.end(), region->begin(), region->end(),
                      std::back_inserter(entering));
  for (uint32_t o : entering) geometries.push_back(scene.objects[o].geometry);
  host.prefetch(geometries, /*urgent=*/false);
  *region = objects;
}

}  // namespace

int runClient(Comm& comm, const ClientOptions& client_opts) {
  ClientOptions opts = client_opts;
  opts.rank = comm.rank();
  int ok = 0;
  comm.broadcast(0, &ok);  // did the server load the scene?
  if (!ok) return 1;

  std::string problem;
  Scene scene;
  std::vector<SurfaceEffect> effects;
  std::unique_ptr<HostCache> host;
  try {
    // The skeleton's names choose the ray tracer's effects, and ray-tracing
    // clients cull their frame's view and shadow casters through it;
    // rasterising clients never traverse it.
    bool named =
        opts.raytrace && opts.ray.reflections && !(opts.mirror.empty() && opts.glass.empty());
    // Part boxes serve the depth-pyramid tests and part draws.
    bool parts =
        !opts.raytrace &&
        ((opts.visibility.part_boxes && opts.visibility.method == VisibilityMethod::Pyramid) ||
         opts.visibility.part_draws);
    scene = loadScene(opts.scene, /*with_skeleton=*/opts.raytrace, parts);
    if (named)
      effects = effectsByName(scene.skeleton, scene.objects.size(), opts.mirror, opts.glass);
    if (!opts.raytrace) {
      scene.skeleton.clear();
      scene.skeleton.shrink_to_fit();
    }
    // Before the caches start to grow (memory_policy.h).
    preTouchHeap(preTouchBytes(opts.pre_touch_mib, scene.manifest.geometry_bytes));
    host = std::make_unique<HostCache>(
        scene, HostCacheOptions{opts.cache.ram_budget, opts.cache.ram_dir, opts.cache.eviction});
  } catch (const std::exception& e) {
    problem = e.what();
  }

  StageControl control(opts.visibility.governor, opts.visibility.stages);
  BoundedQueue<FrameJob> jobs(2);
  BoundedQueue<VisibleJob> visible(2);
  FailureReport failure(comm);
  std::promise<std::string> visReady, renderReady;

  auto visLoop = [&](VisibilityStage* stage) {
    while (auto job = jobs.pop()) {
      if (!stage || failure.failed()) continue;
      try {
        VisibleJob v = stage->run(std::move(*job));
        v.ready = Clock::now();
        visible.push(std::move(v));  // blocks while the render stage is behind
      } catch (const std::exception& e) {
        failure.fail(std::string("visibility stage: ") + e.what());
      }
    }
    visible.close();
  };
  auto renderLoop = [&](RenderStage* stage) {
    std::vector<SubFrame> batch;  // held until a job says flush (static tiles)
    while (auto v = visible.pop()) {
      if (!stage || failure.failed()) continue;
      try {
        batch.push_back(stage->run(*v));
        if (!v->job.flush) continue;
        // Until the server has the sub-frame (asleep meanwhile): a client
        // killed during its next job must not take a finished frame with it.
        auto ts = Clock::now();
        comm.send(0, Tag::SubFrame, encodeSubFrames(batch));
        batch.clear();
        stage->sent(msSince(ts));
      } catch (const std::exception& e) {
        failure.fail(std::string("render stage: ") + e.what());
      }
    }
  };
  std::thread visThread, renderThread;
  if (problem.empty()) {
    visThread = startStage<VisibilityStage>(
        "dmmr-visibility",
        [&] { return std::make_unique<VisibilityStage>(scene, *host, opts, control); }, visLoop,
        &visReady, [&](const std::string& what) { failure.fail("visibility stage: " + what); },
        [&] {
          while (jobs.pop()) {
          }
          visible.close();
        });
    renderThread = startStage<RenderStage>(
        "dmmr-draw",
        [&] { return std::make_unique<RenderStage>(scene, *host, opts, control, effects); },
        renderLoop, &renderReady,
        [&](const std::string& what) { failure.fail("render stage: " + what); },
        [&] {
          while (visible.pop()) {
          }
        });
    for (auto* ready : {&visReady, &renderReady}) {
      std::string p = ready->get_future().get();
      if (!p.empty() && problem.empty()) problem = p;
    }
  }
  // The MPI thread (this one): an exception here (MPI itself failing) must
  // still close the queues and join the stages, or destroying them while
  // joinable would be std::terminate; it is rethrown after.
  int go = 0;
  std::exception_ptr lost;
  try {
    injectFault("start", 0);
    comm.send(0, Tag::Hello, encodeText(problem));
    comm.broadcast(0, &go);
    std::vector<uint32_t> region;  // the previous job's objects
    while (go) {
      Message m = comm.recv(0);
      if (m.tag == Tag::Shutdown) break;
      if (m.tag == Tag::Ping) {  // the server measures the link (--balance auto)
        comm.send(0, Tag::Pong, m.bytes);
        continue;
      }
      if (m.tag != Tag::Job) continue;
      try {
        FrameJob job = decodeJob(m.bytes, scene.objects.size());
        if (opts.cache.prefetch) prefetchEntering(scene, *host, job.objects, &region);
        jobs.push(std::move(job));
      } catch (const std::exception& e) {
        failure.fail(e.what());
      }
    }
  } catch (...) {
    lost = std::current_exception();
  }
  jobs.close();
  if (visThread.joinable()) visThread.join();
  visible.close();
  if (renderThread.joinable()) renderThread.join();
  if (lost) std::rethrow_exception(lost);
  if (!go) return 1;
  comm.send(0, Tag::Bye, {});
  return failure.failed() ? 1 : 0;
}

}  // namespace dmmr
