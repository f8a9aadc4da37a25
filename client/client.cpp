#include "client.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <future>
#include <iterator>
#include <memory>
#include <mutex>
#include <thread>

#include "draw.h"
#include "error.h"
#include "gpu_cache.h"
#include "host_cache.h"
#include "protocol.h"
#include "queue.h"
#include "scene.h"

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
};

// Test hook: DMMR_INJECT_FAULT=STAGE:FRAME[:HOW] (STAGE visibility or
// render; HOW throw, the default, kill or hang) makes that stage of client 1
// fail at that frame, so tests reach the failure paths mid-run.
void injectFault(const char* stage, uint32_t frame) {
  const char* spec = std::getenv("DMMR_INJECT_FAULT");
  const char* rank = std::getenv("OMPI_COMM_WORLD_RANK");
  if (!spec || (rank && std::strcmp(rank, "1") != 0)) return;
  size_t n = std::strlen(stage);
  if (std::strncmp(spec, stage, n) != 0 || spec[n] != ':') return;
  char* rest = nullptr;
  if (std::strtoul(spec + n + 1, &rest, 10) != frame) return;
  if (std::strcmp(rest, ":kill") == 0) std::raise(SIGKILL);
  if (std::strcmp(rest, ":hang") == 0)
    for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
  throw Error("fault injected by DMMR_INJECT_FAULT at frame " + std::to_string(frame));
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
          const CacheOptions& cache)
      : context(createContext(ctx)),
        renderer(context->gl(), view.width, view.height),
        backend(renderer),
        meshes(scene, host, backend, cache.gpu_budget, cache.eviction) {}
  std::unique_ptr<GlContext> context;
  Renderer renderer;
  RendererBackend backend;
  GpuCache meshes;
};

class VisibilityStage {
 public:
  VisibilityStage(const Scene& scene, HostCache& host, const ClientOptions& opts)
      : scene_(scene),
        host_(host),
        opts_(opts.visibility),
        prefetch_(opts.cache.prefetch),
        gl_(scene, host, opts.visibility_context, opts.view, opts.cache),
        marked_until_(scene.objects.size(), 0) {}

  VisibleJob run(FrameJob job) {
    injectFault("visibility", job.frame);
    gl_.meshes.nextFrame();
    GpuCacheStats before = gl_.meshes.stats();
    VisibleJob out = decide(std::move(job));
    addGpuStats(out.stats, before, gl_.meshes.stats());
    // Prefetch what the render stage will draw (it is a frame behind), so
    // its disk reads overlap this stage's and that stage's work.
    std::vector<uint32_t> geometries;
    geometries.reserve(out.visible.size());
    for (uint32_t o : out.visible) geometries.push_back(scene_.objects[o].geometry);
    if (prefetch_) host_.prefetch(geometries, /*urgent=*/true);
    return out;
  }

 private:
  VisibleJob decide(FrameJob job) {
    VisibleJob out;
    out.stats.objects = job.objects.size();
    if (!opts_.enabled) {  // no culling: the render stage draws the whole list
      out.visible = job.objects;
      out.stats.visible = out.visible.size();
      out.job = std::move(job);
      return out;
    }
    auto t0 = Clock::now();
    startFrame(job.frame);
    static const std::vector<uint32_t> kNone;
    const auto& potential =
        opts_.potential_every_frame || previous_.empty() ? scene_.occluders : kNone;
    VisibilityPlan plan =
        planVisibility(job.objects, previous_, potential, marked_until_, job.frame);
    Renderer& r = gl_.renderer;
    r.beginDepthFrame(job.camera, job.region);
    for (uint32_t o : plan.occluders) drawDepth(o);
    // Queries: every object not marked, occluders included (an occluder hidden
    // by other occluders need not be drawn; one that shows passes against its
    // own depth, since its widened box lies in front of it). Hierarchically:
    // runs of consecutive candidates (object indices follow the skeleton's
    // pre-order, so runs are spatially coherent) are tested by their union
    // box first, and only the runs that pass are split and tested again. A
    // union box encloses its members' boxes, so a run that fails hides them
    // all. Boxes that reach the near plane are never queried: they pass.
    // Occluders still marked from an earlier pass are taken without a query,
    // like every marked object: the paper's n frames.
    std::vector<uint32_t> candidates, taken = plan.marked;
    for (uint32_t o : mergeSorted({plan.occluders, plan.queried}))
      (job.frame < marked_until_[o] ? taken : candidates).push_back(o);
    QueryTally tally;
    std::vector<uint32_t> passed = queryHierarchically(candidates, job.camera, &tally);
    // Second pass, for frames where the previous list was a poor occluder set
    // (the camera went through a wall): draw what passed and was not yet in
    // depth, and test it again against that fuller depth. Each object still
    // passes wherever it is the front-most (its widened box lies in front of
    // it), so the argument for exactness is unchanged.
    std::vector<uint32_t> fresh, kept;
    for (uint32_t o : passed)
      (std::binary_search(plan.occluders.begin(), plan.occluders.end(), o) ? kept : fresh)
          .push_back(o);
    if (!fresh.empty() && fresh.size() >= opts_.second_pass_min) {
      std::sort(fresh.begin(), fresh.end());
      for (uint32_t o : fresh) drawDepth(o);
      passed = queryHierarchically(fresh, job.camera, &tally);
      passed.insert(passed.end(), kept.begin(), kept.end());
    }
    const GlApi& gl = gl_.context->gl();
    double retrieve = tally.retrieve_ms;
    size_t issued = tally.issued;
    gl.check("occlusion queries");
    out.stats.prepare_ms = msSince(t0) - retrieve;
    out.stats.retrieve_ms = retrieve;
    std::sort(passed.begin(), passed.end());
    passed_now_.insert(passed_now_.end(), passed.begin(), passed.end());
    out.visible = mergeSorted({taken, passed});
    visible_now_.insert(visible_now_.end(), out.visible.begin(), out.visible.end());
    out.stats.occluders = plan.occluders.size();
    out.stats.queried = issued;
    out.stats.visible = out.visible.size();
    out.job = std::move(job);
    return out;
  }

  // A frame can come as several jobs (tiles): what they found visible is the
  // next frame's occluder set, and what passed a query is marked from the
  // next frame on, so a frame's later tiles are not handed its earlier
  // tiles' objects unqueried.
  void startFrame(uint32_t frame) {
    if (frame == frame_) return;
    for (uint32_t o : passed_now_) marked_until_[o] = frame_ + 1 + opts_.keep_frames;
    previous_ = mergeSorted({visible_now_});
    passed_now_.clear();
    visible_now_.clear();
    frame_ = frame;
  }

  void drawDepth(uint32_t object) {
    const ObjectBounds& o = scene_.objects[object];
    if (const GpuMesh* mesh = gl_.meshes.acquire(o.geometry))  // null: skipped, counted
      gl_.renderer.drawDepth(*mesh, o.transform, o.box, opts_.occluder_lod);
  }

  struct QueryTally {
    size_t issued = 0;
    double retrieve_ms = 0;
  };

  // Tests `candidates` (ascending) against the depth drawn so far: runs of
  // consecutive objects by their union box, in rounds of decreasing run size
  // (options' run_sizes, ending at 1); returns those that pass. Boxes
  // reaching the near plane are not queried: they pass.
  std::vector<uint32_t> queryHierarchically(const std::vector<uint32_t>& candidates,
                                            const Camera& camera, QueryTally* tally) {
    Renderer& r = gl_.renderer;
    const GlApi& gl = gl_.context->gl();
    GLenum target = opts_.query_threshold == 0 ? GL_ANY_SAMPLES_PASSED : GL_SAMPLES_PASSED;
    std::vector<uint32_t> passed;
    std::vector<std::pair<size_t, size_t>> runs = {{0, candidates.size()}}, next;
    for (uint32_t size : opts_.run_sizes) {
      std::vector<std::pair<size_t, size_t>> asked;
      next.clear();
      r.beginQueries();
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
          if (queries_.size() <= asked.size()) growQueries(asked.size() + 1);
          r.queryBox(box, queries_[asked.size()], target);
          asked.push_back({b, e});
        }
      r.endQueries();
      tally->issued += asked.size();
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
      tally->retrieve_ms += msSince(tq);
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
  HostCache& host_;
  VisibilityOptions opts_;
  bool prefetch_;
  GlStage gl_;
  std::vector<uint32_t> previous_;                  // last frame's visible list (ascending)
  std::vector<uint32_t> marked_until_;              // per object: first frame to query again
  uint32_t frame_ = UINT32_MAX;                     // the frame of the jobs being decided
  std::vector<uint32_t> visible_now_, passed_now_;  // this frame's, over its jobs
  std::vector<GLuint> queries_;
};

class RenderStage {
 public:
  RenderStage(const Scene& scene, HostCache& host, const ClientOptions& opts)
      : scene_(scene),
        host_(host),
        codec_(opts.codec),
        gl_(scene, host, opts.render_context, opts.view, opts.cache),
        host_before_(host.stats()) {}

  SubFrame run(const VisibleJob& v) {
    const FrameJob& job = v.job;
    injectFault("render", job.frame);
    gl_.meshes.nextFrame();
    host_.nextFrame();
    GpuCacheStats gpu_before = gl_.meshes.stats();
    SubFrame out;
    out.frame = job.frame;
    out.region = job.region;
    out.stats = v.stats;
    ClientStats& st = out.stats;
    st.pass_ms = msSince(v.ready);  // from list ready to the render stage taking it
    auto t0 = Clock::now();
    Renderer& r = gl_.renderer;
    r.beginFrame(job.camera, job.region);
    for (uint32_t index : v.visible) {  // ascending, as the reference draws
      const ObjectBounds& o = scene_.objects[index];
      auto tl = Clock::now();
      const GpuMesh* mesh = gl_.meshes.acquire(o.geometry);
      st.load_ms += msSince(tl);
      if (!mesh) continue;  // unreadable geometry: skipped, counted
      r.draw(*mesh, o.transform, o.box, gl_.meshes.textures());
      st.triangles += mesh->triangles;
    }
    r.finish();
    addGpuStats(st, gpu_before, gl_.meshes.stats());
    // The host levels are shared by both stages; each sub-frame reports
    // their activity since the previous one.
    HostCacheStats h = host_.stats();
    st.ram_hits = h.hits - host_before_.hits;
    st.ram_misses = h.misses - host_before_.misses;
    st.disk_bytes = h.disk_bytes - host_before_.disk_bytes;
    st.uncached += h.uncached - host_before_.uncached;
    st.skipped = h.skipped - host_before_.skipped;
    st.ram_resident = h.resident;
    host_before_ = h;
    st.render_ms = msSince(t0) - st.load_ms;
    auto tr = Clock::now();
    std::vector<uint8_t> rgba, rgb;
    r.readPixels(job.region, &rgba);
    rgb.resize(size_t(job.region.area()) * 3);
    for (size_t i = 0, n = size_t(job.region.area()); i < n; ++i)
      for (int c = 0; c < 3; ++c) rgb[i * 3 + c] = rgba[i * 4 + c];
    st.readback_ms = msSince(tr);
    auto tc = Clock::now();
    out.codec = codec_;
    out.raw_size = rgb.size();
    out.data = compress(codec_, rgb.data(), rgb.size());
    st.compress_ms = msSince(tc);
    st.bytes_raw = rgb.size();
    st.bytes_sent = out.data.size();
    st.send_ms = last_send_ms_;
    out.drawn = v.visible;  // lets the server weigh the next frames by what shows
    return out;
  }

  void sent(double ms) { last_send_ms_ = ms; }

 private:
  const Scene& scene_;
  HostCache& host_;
  Codec codec_;
  GlStage gl_;
  HostCacheStats host_before_;
  double last_send_ms_ = 0;
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
// where its GL context is current).
template <typename Stage, typename Loop>
std::thread startStage(std::function<std::unique_ptr<Stage>()> make, Loop loop,
                       std::promise<std::string>* ready) {
  return std::thread([make, loop, ready] {
    std::unique_ptr<Stage> stage;
    try {
      stage = make();
      ready->set_value("");
    } catch (const std::exception& e) {
      ready->set_value(e.what());
    }
    loop(stage.get());  // null when construction failed: the loop only drains
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

int runClient(Comm& comm, const ClientOptions& opts) {
  int ok = 0;
  comm.broadcast(0, &ok);  // did the server load the scene?
  if (!ok) return 1;

  std::string problem;
  Scene scene;
  std::unique_ptr<HostCache> host;
  try {
    scene = loadScene(opts.scene, /*with_skeleton=*/false);
    host = std::make_unique<HostCache>(
        scene, HostCacheOptions{opts.cache.ram_budget, opts.cache.ram_dir, opts.cache.eviction});
  } catch (const std::exception& e) {
    problem = e.what();
  }

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
        [&] { return std::make_unique<VisibilityStage>(scene, *host, opts); }, visLoop, &visReady);
    renderThread =
        startStage<RenderStage>([&] { return std::make_unique<RenderStage>(scene, *host, opts); },
                                renderLoop, &renderReady);
    for (auto* ready : {&visReady, &renderReady}) {
      std::string p = ready->get_future().get();
      if (!p.empty() && problem.empty()) problem = p;
    }
  }
  comm.send(0, Tag::Hello, encodeText(problem));
  int go = 0;
  comm.broadcast(0, &go);

  if (go) {
    std::vector<uint32_t> region;  // the previous job's objects
    for (;;) {
      Message m = comm.recv(0);
      if (m.tag == Tag::Shutdown) break;
      if (m.tag == Tag::Ping) {  // the server measures the link (--balance auto)
        comm.send(0, Tag::Pong, m.bytes);
        continue;
      }
      if (m.tag != Tag::Job) continue;
      try {
        FrameJob job = decodeJob(m.bytes);
        if (opts.cache.prefetch) prefetchEntering(scene, *host, job.objects, &region);
        jobs.push(std::move(job));
      } catch (const std::exception& e) {
        failure.fail(e.what());
      }
    }
  }
  jobs.close();
  if (visThread.joinable()) visThread.join();
  visible.close();
  if (renderThread.joinable()) renderThread.join();
  if (!go) return 1;
  comm.send(0, Tag::Bye, {});
  return failure.failed() ? 1 : 0;
}

}  // namespace dmmr
