#include "server.h"

#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include "affinity.h"
#include "atomic_file.h"
#include "cpu_time.h"
#include "error.h"
#include "guarded.h"
#include "image.h"
#include "plan.h"
#include "protocol.h"
#include "scene.h"
#include "serve.h"
#include "stats_csv.h"
#include "walkthrough.h"

namespace dmmr {

namespace {

using Clock = std::chrono::steady_clock;

// Test hook: DMMR_INJECT_FAULT=server:WHAT, WHAT being send:FRAME (sending
// that frame's jobs fails) or send-record (the planner records a frame's
// send time while the assembler finishes it: the race TSan must not see).
bool injectedServerFault(const char* what) {
  static const char* spec = std::getenv("DMMR_INJECT_FAULT");
  return spec && std::strncmp(spec, "server:", 7) == 0 && std::strcmp(spec + 7, what) == 0;
}

// "client K (rank K)", as every message naming a client says it.
std::string clientName(int k) {
  return "client " + std::to_string(k) + " (rank " + std::to_string(k) + ")";
}

double msBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// What the planning thread records for a frame, and what the assembler adds.
struct FrameRecord {
  Clock::time_point started;
  double cull_ms = 0, divide_ms = 0, send_ms = 0;
  double plan_cpu_ms = 0;  // FramePlan::plan_cpu_ms
  uint64_t objects = 0, triangles = 0;
  std::vector<uint64_t> region_objects;   // as planned, per client
  Image image;                            // assembled RGBA, top row first
  std::vector<ClientStats> clients;       // per client, summed over its sub-frames
  std::vector<uint64_t> pixels;           // per client: pixels of its sub-frames
  std::vector<DrawnCover> cover;          // per client: FramePlanner::coverOf its sub-frames
  std::vector<RegionCost> planned;        // per client (frustum division): region, planned weight
  CostGrid grid;                          // the cost grid the frame was planned with
  std::vector<RegionForecast> forecasts;  // per client, with --division-log
  Camera camera;
  std::vector<int> owed;  // per client: sub-frames given and not yet back
  int expected = 0;       // sub-frames that make up the frame
  int received = 0;
};

// The stats CSV's header line for `clients` clients.
std::string statsHeader(int clients) {
  std::string h =
      "frame,frame_ms,latency_ms,cull_ms,divide_ms,send_ms,assemble_ms,write_ms,plan_cpu_ms,"
      "objects_in_frustum,triangles_in_frustum";
  for (int k = 1; k <= clients; ++k)
    for (const char* c :
         {"objects",       "occluders",   "queried",       "visible",      "triangles",
          "prepare_ms",    "retrieve_ms", "pass_ms",       "load_ms",      "render_ms",
          "readback_ms",   "compress_ms", "send_ms",       "bytes_raw",    "bytes_sent",
          "gpu_hits",      "gpu_misses",  "ram_hits",      "ram_misses",   "disk_bytes",
          "uncached",      "skipped",     "gpu_resident",  "ram_resident", "vis_cpu_ms",
          "render_cpu_ms", "vis_sys_ms",  "render_sys_ms", "vis_faults",   "render_faults",
          "submitted"})
      h += ",c" + std::to_string(k) + "_" + c;
  return h + "\n";
}

// The division log's header (ServerOptions::division_log): the server's
// side (planned weight, forecast), then the client's (its CostSample).
const char* const kDivisionLogHeader =
    "frame,client,planned,objects,drawn_lately,triangles_lately,fill_lately,pixels,tested,drawn,"
    "triangles,fill,ms,raster,submitted\n";

class Assembler {
 public:
  // `planner`, when given, hears which objects the clients drew.
  // `csv`: the stats CSV, each finished frame's row appended.
  // `hub`, when given, gets every frame (interactive mode); then `frames` is
  // only an upper bound and the run ends when the planner stops.
  // `division_log`, when given, gets the rows of frames planned with forecasts.
  Assembler(Comm& comm, const ServerOptions& opts, int clients, size_t frames,
            FramePlanner* planner, StatsCsvAppender& csv, ViewerHub* hub = nullptr,
            StatsCsvAppender* division_log = nullptr)
      : comm_(comm),
        opts_(opts),
        clients_(clients),
        frames_(frames),
        planner_(planner),
        csv_(csv),
        division_log_(division_log),
        hub_(hub) {
    assembled_ = opts.from_frame;
    last_done_ = Clock::now();
  }

  // Planning thread: registers a frame before its jobs go out.
  // `owed`: per client, the sub-frames it is given now (dynamic tiles add
  // theirs with owe() as they go out); `expected`: all of the frame's.
  void begin(uint32_t frame, FrameRecord rec, std::vector<int> owed, int expected) {
    rec.image = Image::blank(opts_.view.width, opts_.view.height);
    rec.clients.resize(size_t(clients_));
    rec.pixels.resize(size_t(clients_));
    rec.cover.resize(size_t(clients_));
    rec.owed = std::move(owed);
    rec.expected = expected;
    std::lock_guard<std::mutex> lock(mu_);
    pending_[frame] = std::move(rec);
  }

  // Dispatcher: `client` (1-based) was just given one more of `frame`'s tiles.
  void owe(uint32_t frame, int client) {
    std::lock_guard<std::mutex> lock(mu_);
    if (auto it = pending_.find(frame); it != pending_.end()) ++it->second.owed[size_t(client - 1)];
  }

  // Called (on the assembler thread) after each sub-frame from `client`.
  void onSubFrame(std::function<void(int client, uint32_t frame, const Rect& region)> f) {
    on_sub_frame_ = std::move(f);
  }

  // Planning thread: blocks until fewer than `in_flight` frames are
  // outstanding; false when the run failed.
  bool waitForRoom(uint32_t frame) {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return failed_ || frame < assembled_ + uint32_t(opts_.in_flight); });
    return !failed_;
  }

  // Planning thread: blocks until every frame before `frame` is assembled
  // (the pipeline drained); false when the run failed.
  bool waitAssembled(uint32_t frame) {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return failed_ || assembled_ >= frame; });
    return !failed_;
  }

  // Receives until every frame is assembled. After a failure (a client's
  // Error, a bad message, a send error recorded by the planner) it keeps
  // receiving until the planning thread has stopped: a healthy client may
  // be blocked sending a sub-frame while the planner is blocked sending it
  // a job, and only a receive here frees both. What arrives is still
  // assembled: a frame whose sub-frames all come is finished work, and is
  // written (take() does the same during the shutdown). client_timeout_s
  // without any message ends the run either way (silent).
  void run() {
    auto last = Clock::now();
    for (;;) {
      bool idle;
      {
        std::lock_guard<std::mutex> lock(mu_);
        if (failed_ ? planner_done_ : assembled_ >= frames_) return;
        if (planner_done_ && pending_.empty()) return;  // interactive: stopped
        // Nothing owed (an interactive run waiting for a pose): silence is
        // no sign of a dead client.
        idle = !failed_ && pending_.empty();
      }
      std::optional<Message> got = comm_.recvFor(kAnySource, kPollS);
      if (idle) last = Clock::now();
      if (!got) {
        if (msBetween(last, Clock::now()) > opts_.client_timeout_s * 1000) silent();
        continue;
      }
      last = Clock::now();
      take(*got);
    }
  }

  // Handles one message (on this thread, or during the shutdown once it has
  // returned); an error in it becomes the run's failure (the first one is
  // reported).
  void take(const Message& m) {
    try {
      handle(m);
    } catch (const std::exception& e) {
      fail(std::string("server: ") + e.what());
    }
  }

  // Planning thread: no more jobs will be sent.
  void plannerDone() {
    std::lock_guard<std::mutex> lock(mu_);
    planner_done_ = true;
  }
  // Planning thread: about to send to `client` (0: not sending), so that a
  // send that never completes can be blamed on the right client.
  void sendingTo(int client) { sending_to_.store(client); }

  // No message for client_timeout_s while sub-frames are owed, or while the
  // planner is blocked after a failure: names the clients that owe the
  // oldest frame (or the one the planner is sending to) and ends the job (an
  // orderly shutdown would wait for them forever). Every frame assembled so
  // far is on disk.
  [[noreturn]] void silent() {
    std::string who, owed, failure;
    uint32_t frame = 0;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (failed_) failure = " after the run failed (" + error_ + ")";
      if (!pending_.empty()) {
        frame = pending_.begin()->first;
        const FrameRecord& rec = pending_.begin()->second;
        for (int k = 1; k <= clients_; ++k)
          if (int n = rec.owed[size_t(k - 1)]; n > 0) {
            who += (who.empty() ? "" : ", ") + clientName(k);
            owed += (owed.empty() ? "" : ", ") + std::to_string(n) + " from client " +
                    std::to_string(k);
          }
      }
      if (int k = sending_to_.load(); k > 0 && failed_) who = clientName(k);
    }
    std::fprintf(stderr,
                 "\ndmmr-render: server (rank 0): %s sent nothing for %.0f s while frame %u "
                 "waited for it (sub-frames owed: %s)%s: it died or hangs; aborting the run "
                 "(%u frames assembled and written)\n",
                 who.empty() ? "no client" : who.c_str(), opts_.client_timeout_s, frame,
                 owed.empty() ? "none" : owed.c_str(), failure.c_str(), assembled_.load());
    comm_.abort(3);
  }

  void setSendMs(uint32_t frame, double ms) {
    if (injectedServerFault("send-record")) {  // land inside finishFrame's sleep
      auto deadline = Clock::now() + std::chrono::seconds(5);
      while (!receivedAll(frame) && Clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    std::lock_guard<std::mutex> lock(mu_);
    // The frame may already be assembled (its last sub-frame raced this
    // call); then its row went out without the send time.
    if (auto it = pending_.find(frame); it != pending_.end()) it->second.send_ms = ms;
  }

  void markFailed(const std::string& why) { fail(why); }
  bool failed() const {
    std::lock_guard<std::mutex> lock(mu_);
    return failed_;
  }
  const std::string& error() const { return error_; }

 private:
  static constexpr double kPollS = 0.05;  // how often a waiting receive checks for a failure

  // For the send-record hook: every sub-frame of `frame` is in.
  bool receivedAll(uint32_t frame) const {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = pending_.find(frame);
    return it == pending_.end() || it->second.received == it->second.expected;
  }

  void handle(const Message& m) {
    if (m.tag == Tag::Error) {
      fail("client " + std::to_string(m.source) + ": " + decodeText(m.bytes));
      return;
    }
    if (m.tag != Tag::SubFrame)
      throw Error(std::string("unexpected ") + tagName(m.tag) + " message from rank " +
                  std::to_string(m.source));
    for (const SubFrame& sf : decodeSubFrames(m.bytes)) {
      accept(m.source, sf);
      // After a failure no more tiles go out: the run is winding down.
      if (on_sub_frame_ && !failed()) on_sub_frame_(m.source, sf.frame, sf.region);
    }
  }

  void accept(int rank, const SubFrame& sf) {
    auto t0 = Clock::now();
    FrameRecord* rec;
    {
      std::lock_guard<std::mutex> lock(mu_);
      auto it = pending_.find(sf.frame);
      if (it == pending_.end()) {
        if (failed_) return;  // a frame begun after the failure and never completed
        throw Error("rank " + std::to_string(rank) + " sent frame " + std::to_string(sf.frame) +
                    ", which is not in flight");
      }
      rec = &it->second;
      // Under the lock: the dynamic dealer adds to `owed` from other threads.
      if (rank < 1 || rank > clients_ || rec->owed[size_t(rank - 1)] <= 0)
        throw Error("rank " + std::to_string(rank) + " sent a sub-frame of frame " +
                    std::to_string(sf.frame) + " it was not given");
      --rec->owed[size_t(rank - 1)];
    }
    if (!insideFrame(sf.region, rec->image.width, rec->image.height))
      throw Error("rank " + std::to_string(rank) + " sent a region outside the frame");
    std::vector<uint8_t> rgb = decompress(sf.codec, sf.data.data(), sf.data.size(), sf.raw_size);
    placeRgbRegion(rec->image, sf.region, rgb);
    accumulate(rec->clients[size_t(rank - 1)], sf.stats);
    rec->pixels[size_t(rank - 1)] += uint64_t(sf.region.area());
    if (planner_) {
      planner_->reportDrawn(sf.frame, sf.drawn);
      if (opts_.fitted_weights) {
        DrawnCover c = planner_->coverOf(rec->camera, rec->image.width, rec->image.height,
                                         sf.region, sf.drawn);
        rec->cover[size_t(rank - 1)].fill += c.fill;
        rec->cover[size_t(rank - 1)].raster += c.raster;
      }
    }
    assemble_ms_[sf.frame] += msBetween(t0, Clock::now());
    bool complete;
    {
      std::lock_guard<std::mutex> lock(mu_);  // receivedAll reads it
      complete = ++rec->received == rec->expected;
    }
    if (complete) finishFrame(sf.frame);
  }

  void finishFrame(uint32_t frame) {
    if (injectedServerFault("send-record"))  // widen the window the send time raced into
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
    // The record leaves the map under the lock: the planning thread's
    // setSendMs writes it under the same lock, so the row reads a settled
    // value, and a later setSendMs finds no record.
    FrameRecord rec;
    {
      std::lock_guard<std::mutex> lock(mu_);
      auto node = pending_.extract(frame);
      rec = std::move(node.mapped());
    }
    const bool grid = planner_ && opts_.cost_grid && rec.planned.size() == size_t(clients_);
    std::vector<CostSample> samples;
    if (planner_ && (opts_.fitted_weights || grid)) samples = costSamples(rec);
    if (planner_ && opts_.fitted_weights) planner_->reportCosts(frame, samples);
    if (grid) {
      // A slow client's time, scaled to a typical client's: the grid learns
      // where the screen costs, the fitted speeds which client is slow.
      std::vector<double> speeds = planner_->speeds();
      for (size_t k = 0; k < samples.size(); ++k)
        rec.planned[k].measured =
            samples[k].ms * (speeds.size() == samples.size() ? speeds[k] : 1.0);
      planner_->reportRegionCosts(rec.image.width, rec.image.height, rec.planned, rec.grid);
    }
    auto tw = Clock::now();
    if (!opts_.out.empty()) writePng(opts_.out + "/" + frameFileName(frame), rec.image);
    auto done = Clock::now();
    std::ostringstream row;
    row.setf(std::ios::fixed);
    row.precision(3);
    row << frame << "," << msBetween(last_done_, done) << "," << msBetween(rec.started, done) << ","
        << rec.cull_ms << "," << rec.divide_ms << "," << rec.send_ms << "," << assemble_ms_[frame]
        << "," << msBetween(tw, done) << "," << rec.plan_cpu_ms << "," << rec.objects << ","
        << rec.triangles;
    for (const ClientStats& c : rec.clients)
      row << "," << c.objects << "," << c.occluders << "," << c.queried << "," << c.visible << ","
          << c.triangles << "," << c.prepare_ms << "," << c.retrieve_ms << "," << c.pass_ms << ","
          << c.load_ms << "," << c.render_ms << "," << c.readback_ms << "," << c.compress_ms << ","
          << c.send_ms << "," << c.bytes_raw << "," << c.bytes_sent << "," << c.gpu_hits << ","
          << c.gpu_misses << "," << c.ram_hits << "," << c.ram_misses << "," << c.disk_bytes << ","
          << c.uncached << "," << c.skipped << "," << c.gpu_resident << "," << c.ram_resident << ","
          << c.vis_cpu_ms << "," << c.render_cpu_ms << "," << c.vis_sys_ms << "," << c.render_sys_ms
          << "," << c.vis_faults << "," << c.render_faults << "," << c.submitted;
    csv_.append(row.str() + "\n");  // after the frame's PNG: a row means its frame is on disk
    if (division_log_ && rec.forecasts.size() == rec.clients.size() &&
        rec.planned.size() == rec.clients.size())
      logDivision(frame, rec);
    if (hub_) {
      double frame_ms = msBetween(last_done_, done), latency_ms = msBetween(rec.started, done);
      hub_->frameDone(frameDone(frame, std::move(rec), frame_ms, latency_ms));
    }
    last_done_ = done;
    if (opts_.progress) std::fprintf(stderr, "\rdmmr-render: frame %u/%zu", frame + 1, frames_);
    assemble_ms_.erase(frame);
    std::lock_guard<std::mutex> lock(mu_);
    ++assembled_;
    cv_.notify_all();
  }

  // One division-log row per client: the server's side, then the client's.
  void logDivision(uint32_t frame, const FrameRecord& rec) {
    std::vector<CostSample> samples = costSamples(rec);
    std::ostringstream rows;
    rows.setf(std::ios::fixed);
    rows.precision(3);
    for (size_t k = 0; k < samples.size(); ++k) {
      const RegionForecast& f = rec.forecasts[k];
      const CostSample& c = samples[k];
      rows << frame << "," << k + 1 << "," << rec.planned[k].planned << "," << f.objects << ","
           << f.drawn_lately << "," << f.triangles_lately << "," << f.fill_lately << "," << c.pixels
           << "," << c.tested << "," << c.drawn << "," << c.triangles << "," << c.fill << ","
           << c.ms << "," << c.raster << "," << rec.clients[k].submitted << "\n";
    }
    division_log_->append(rows.str());
  }

  // What a viewer's frame header reports (serve.h).
  FrameDone frameDone(uint32_t frame, FrameRecord&& rec, double frame_ms, double latency_ms) {
    FrameDone d;
    d.frame = frame;
    d.cull_ms = rec.cull_ms;
    d.divide_ms = rec.divide_ms;
    d.assemble_ms = assemble_ms_[frame];
    d.frame_ms = frame_ms;
    d.latency_ms = latency_ms;
    for (const CostSample& c : costSamples(rec)) {
      d.clients.push_back({uint64_t(c.pixels), uint64_t(c.triangles), c.ms});
      d.triangles += uint64_t(c.triangles);
    }
    d.image = std::move(rec.image);
    return d;
  }

  // Each client's work and time on a frame, for fitted weights. The time is
  // the stage threads' CPU time when llvmpipe rasterises on them
  // (LP_NUM_THREADS=0, which mpirun -x gives every rank alike): free of
  // waiting for a core; otherwise the stages' wall time, which on a cluster
  // (one machine per client) is the client's cost.
  std::vector<CostSample> costSamples(const FrameRecord& rec) const {
    const bool cpu = rasterisesOnCallingThread();
    std::vector<CostSample> out;
    for (size_t k = 0; k < rec.clients.size(); ++k) {
      const ClientStats& c = rec.clients[k];
      CostSample s;
      s.client = int(k);
      s.drawn = double(c.visible);
      s.triangles = double(c.triangles);
      s.tested = double(c.queried);
      s.pixels = double(rec.pixels[k]);
      s.fill = rec.cover[k].fill;
      s.raster = rec.cover[k].raster;
      s.ms = cpu ? c.vis_cpu_ms + c.render_cpu_ms
                 : c.prepare_ms + c.retrieve_ms + c.load_ms + c.render_ms + c.readback_ms +
                       c.compress_ms;
      out.push_back(s);
    }
    return out;
  }

  void fail(const std::string& why) {
    std::lock_guard<std::mutex> lock(mu_);
    if (!failed_) error_ = why;
    failed_ = true;
    cv_.notify_all();
  }

  Comm& comm_;
  const ServerOptions& opts_;
  const int clients_;
  const size_t frames_;
  FramePlanner* planner_;
  std::function<void(int, uint32_t, const Rect&)> on_sub_frame_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::map<uint32_t, FrameRecord> pending_;
  std::map<uint32_t, double> assemble_ms_;
  std::atomic<uint32_t> assembled_{0};  // written under mu_; silent() reads it without
  bool failed_ = false, planner_done_ = false;
  std::atomic<int> sending_to_{0};
  std::string error_;
  StatsCsvAppender& csv_;
  StatsCsvAppender* division_log_;
  ViewerHub* hub_;
  Clock::time_point last_done_;
};

// --balance tiles-dynamic: tiles go out on demand, at most `window` in
// flight per client, oldest frame first; a client gets its next tile as soon
// as one of its sub-frames is back. Sends happen on the planning thread (a
// frame's tiles arrive) and on the assembler thread (a tile returned),
// serialised by the lock. The window is below what a client's queues hold,
// so a send never waits for a client that waits for the server.
class TileDispatcher {
 public:
  TileDispatcher(Comm& comm, Assembler& assembler, int clients, int window)
      : sending_(comm), assembler_(assembler), pool_(0, clients, window), given_(size_t(clients)) {}

  void add(std::vector<FrameJob> jobs) {
    std::lock_guard<std::mutex> lock(mu_);
    size_t first = pool_.size();
    pool_.add(jobs.size());
    for (size_t i = 0; i < jobs.size(); ++i) jobs_[uint32_t(first + i)] = std::move(jobs[i]);
    pump();
  }

  // Sends nothing more: the clients are told to shut down next, and a job
  // posted after that would be in flight for ever.
  void close() {
    std::lock_guard<std::mutex> lock(mu_);
    closed_ = true;
  }

  // `client` (1-based) returned the sub-frame of `region` of `frame`: its
  // oldest tile in flight when that is one of this dealer's (clients answer
  // in order; under --balance auto other strategies' jobs come and go
  // between drained blocks, and a pool's client also returns its own region
  // of the same frame: those are not this dealer's to count).
  void returned(int client, uint32_t frame, const Rect& region) {
    std::lock_guard<std::mutex> lock(mu_);
    auto& given = given_[size_t(client - 1)];
    if (given.empty() || given.front().frame != frame || !(given.front().region == region)) return;
    pool_.done(client - 1, given.front().tile);
    given.pop_front();
    pump();
  }

 private:
  // Jobs go out without waiting for the client to take them (SendBatch):
  // this runs on the assembler's thread too, which must go on receiving.
  void pump() {
    sending_.poll();
    if (closed_) return;
    for (int k = 0; k < int(given_.size()); ++k)
      for (uint32_t id : pool_.refill(k)) {
        auto it = jobs_.find(id);
        assembler_.owe(it->second.frame, k + 1);
        sending_.post(k + 1, Tag::Job, encodeJob(it->second));
        given_[size_t(k)].push_back({id, it->second.frame, it->second.region});
        jobs_.erase(it);
      }
  }

  SendBatch sending_;  // under mu_
  bool closed_ = false;
  Assembler& assembler_;
  std::mutex mu_;
  TilePool pool_;
  std::map<uint32_t, FrameJob> jobs_;  // by pool index, until sent
  // Per client: the tiles in the order sent.
  struct Given {
    uint32_t tile, frame;
    Rect region;
  };
  std::vector<std::deque<Given>> given_;
};

// --balance auto: the median round trip of a 1 KiB message to each client,
// the slowest client's, in ms.
double measureRoundTripMs(Comm& comm, int clients) {
  std::vector<uint8_t> probe(1024, 0x5a);
  double worst = 0;
  for (int k = 1; k <= clients; ++k) {
    std::vector<double> rtt;
    for (int i = 0; i < 5; ++i) {
      auto t0 = Clock::now();
      comm.send(k, Tag::Ping, probe);
      Message m = comm.recv(k);
      if (m.tag != Tag::Pong || m.bytes != probe)
        throw Error(std::string("link probe: client ") + std::to_string(k) + " answered " +
                    tagName(m.tag));
      rtt.push_back(msBetween(t0, Clock::now()));
    }
    std::sort(rtt.begin(), rtt.end());
    worst = std::max(worst, rtt[rtt.size() / 2]);
  }
  return worst;
}

// Tells every client to stop and waits until each has said Bye, receiving
// whatever they still send (handed to `take`, or dropped), so no rank is
// left blocked.
void shutdownClients(Comm& comm, int clients, double timeout_s,
                     const std::function<void(const Message&)>& take = {}) {
  for (int k = 1; k <= clients; ++k) comm.send(k, Tag::Shutdown, {});
  std::vector<uint8_t> bye(size_t(clients) + 1, 0);
  for (int byes = 0; byes < clients;) {
    std::optional<Message> m = comm.recvFor(kAnySource, timeout_s);
    if (!m) {
      std::string who;
      for (int k = 1; k <= clients; ++k)
        if (!bye[size_t(k)]) who += " " + std::to_string(k);
      std::fprintf(stderr,
                   "dmmr-render: server (rank 0): client(s)%s did not acknowledge shutdown "
                   "within %.0f s; aborting\n",
                   who.c_str(), timeout_s);
      comm.abort(3);
    }
    if (m->tag == Tag::Bye && !bye[size_t(m->source)]) {
      bye[size_t(m->source)] = 1;
      ++byes;
    } else if (m->tag != Tag::Bye && take) {
      take(*m);
    }
  }
}

// The interactive mode's hub: the home pose is the walkthrough's first point
// or, without one, a view of the scene's bounds from above one side.
std::unique_ptr<ViewerHub> makeHub(const ServerOptions& opts, const Scene& scene,
                                   const Walkthrough& path, int clients, double near) {
  ViewerHello hello;
  hello.width = opts.view.width;
  hello.height = opts.view.height;
  hello.fovy_deg = opts.view.fovy_deg;
  hello.clients = clients;
  for (const ObjectBounds& o : scene.objects) {
    hello.bounds.expand(o.box.lo);
    hello.bounds.expand(o.box.hi);
  }
  if (!path.points.empty()) {
    hello.home_position = path.points[0].position;
    hello.home_rotation = path.points[0].rotation;
  } else if (hello.bounds.valid()) {
    Vec3d c = (hello.bounds.lo + hello.bounds.hi) * 0.5;
    double r = std::max(length(hello.bounds.hi - hello.bounds.lo) * 0.5, near * 10);
    double d = r / std::tan(opts.view.fovy_deg * M_PI / 360);
    hello.home_position = c + Vec3d{0.0, -0.8, 0.6} * d;
    hello.home_rotation = lookAtRotation(hello.home_position, c, {0, 0, 1});
  }
  return std::make_unique<ViewerHub>(opts.serve_opts, hello, viewerPage());
}

}  // namespace

int runServer(Comm& comm, const ServerOptions& opts) {
  const int clients = comm.size() - 1;
  if (clients < 1) {
    std::fprintf(stderr,
                 "dmmr-render: needs at least one client: run it under mpirun with "
                 "-np 2 or more (rank 0 is the server)\n");
    return 1;
  }
  Scene scene;
  Walkthrough path;
  std::string problem;
  std::unique_ptr<StatsCsvAppender> csv, division_log;
  try {
    scene = loadScene(opts.scene);
    if (!opts.walkthrough.empty())
      path = readWalkthrough(opts.walkthrough);
    else if (!opts.serve)
      throw Error("no --walkthrough given");
    if (opts.serve && opts.from_frame > 0) throw Error("--from-frame needs a walkthrough run");
    if (!opts.serve && opts.from_frame >= path.points.size())
      throw Error("--from-frame " + std::to_string(opts.from_frame) + " is not a frame of " +
                  opts.walkthrough + " (" + std::to_string(path.points.size()) + " frames)");
    if (!opts.out.empty()) std::filesystem::create_directories(opts.out);
    if (!opts.out.empty() && !opts.serve) {
      if (opts.from_frame > 0) checkResume(opts.out, opts.settings, opts.from_frame);
      writeRunSettings(opts.out, opts.settings);
    }
    // Created here, before the clients are told to go: a stats file that
    // cannot be written stops the run before any work is done.
    csv = std::make_unique<StatsCsvAppender>(
        opts.stats, resumeStatsCsv(opts.stats, statsHeader(clients), opts.from_frame));
    if (!opts.division_log.empty())
      division_log = std::make_unique<StatsCsvAppender>(
          opts.division_log,
          resumeStatsCsv(opts.division_log, kDivisionLogHeader, opts.from_frame));
  } catch (const std::exception& e) {
    problem = e.what();
  }
  int ok = problem.empty() ? 1 : 0;
  comm.broadcast(0, &ok);
  if (!ok) {
    std::fprintf(stderr, "dmmr-render: server (rank 0): %s\n", problem.c_str());
    return 1;
  }
  // Every client reports whether it is ready (scene, context, renderer).
  // A client that never answers (stuck loading or creating its context)
  // ends the run after --client-timeout, named; the others wait in the
  // broadcast below, so only an abort ends them.
  std::map<int, std::string> problems;
  std::vector<bool> answered(size_t(clients) + 1, false);
  for (int k = 0; k < clients; ++k) {
    std::optional<Message> m = comm.recvFor(kAnySource, opts.client_timeout_s);
    if (!m) {
      std::string who;
      for (int c = 1; c <= clients; ++c)
        if (!answered[size_t(c)]) who += (who.empty() ? "" : ", ") + clientName(c);
      std::fprintf(stderr,
                   "dmmr-render: server (rank 0): %s did not say whether it is ready within "
                   "%.0f s (--client-timeout): it died or hangs while starting; aborting\n",
                   who.c_str(), opts.client_timeout_s);
      comm.abort(3);
    }
    answered[size_t(m->source)] = true;
    if (m->tag != Tag::Hello)
      problems[m->source] = std::string("sent ") + tagName(m->tag) + " before saying Hello";
    else if (!m->bytes.empty())
      problems[m->source] = decodeText(m->bytes);
  }
  int go = problems.empty() ? 1 : 0;
  comm.broadcast(0, &go);
  if (!go) {
    for (auto& [rank, text] : problems)
      std::fprintf(stderr, "dmmr-render: client %d (rank %d): %s\n", rank, rank, text.c_str());
    return 1;
  }

  const ViewOptions& v = opts.view;
  double near = v.near > 0 ? v.near : defaultNear(scene);
  // --balance auto: one frame to load, then three frames of each strategy,
  // then the fastest (BalanceTrial).
  std::optional<BalanceTrial> trial;
  if (opts.balance == Balance::Auto) {
    double rtt = 0;
    try {
      rtt = measureRoundTripMs(comm, clients);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "dmmr-render: server (rank 0): %s\n", e.what());
      shutdownClients(comm, clients, opts.client_timeout_s);
      return 1;
    }
    trial.emplace(
        std::vector<Balance>{Balance::Frustum, Balance::TilesStatic, Balance::TilesDynamic}, 1, 3);
    std::fprintf(stderr,
                 "dmmr-render: --balance auto: round trip %.3f ms to the slowest of %d "
                 "client(s); timing each strategy on 3 frames\n",
                 rtt, clients);
  }
  // Interactive mode: the hub serves viewers; their poses replace the path.
  std::unique_ptr<ViewerHub> hub;
  if (opts.serve) {
    try {
      hub = makeHub(opts, scene, path, clients, near);
      std::fprintf(stderr,
                   "dmmr-render: serving %s (server pid %d: SIGINT or SIGTERM to it ends the "
                   "run in order)\n",
                   hub->start().c_str(), int(::getpid()));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "dmmr-render: server (rank 0): %s\n", e.what());
      shutdownClients(comm, clients, opts.client_timeout_s);
      return 1;
    }
  }
  const size_t frames = hub ? size_t(UINT32_MAX) : path.points.size();
  FramePlanner planner(scene);
  if (opts.cost_grid && opts.visible_weights)
    planner.enableCostGrid(FramePlanner::kGridColumns, FramePlanner::kGridRows);
  // Only frames in flight let a client catch up: with one, every frame waits
  // for its slowest client, and shares that lean against the past unbalance it.
  planner.setCatchUp(opts.catch_up && opts.in_flight > 1);
  planner.setUnseen(opts.unseen);
  Assembler assembler(comm, opts, clients, frames, opts.visible_weights ? &planner : nullptr, *csv,
                      hub.get(), division_log.get());
  TileDispatcher dispatcher(comm, assembler, clients, opts.tile_window);
  assembler.onSubFrame([&](int client, uint32_t frame, const Rect& region) {
    dispatcher.returned(client, frame, region);
  });
  std::thread assembling([&] {
    nameThisThread("dmmr-assemble");
    runGuarded([&] { assembler.run(); },
               [&](const std::string& what) { assembler.markFailed("server: " + what); });
  });
  auto nowMs = [] {
    return std::chrono::duration<double, std::milli>(Clock::now().time_since_epoch()).count();
  };
  // Everything the planning thread does is guarded: an exception of any type
  // ends the run through the assembler, never as std::terminate of a
  // joinable thread.
  auto planFrames = [&] {
    for (uint32_t f = opts.from_frame; f < frames; ++f) {
      uint32_t i = f - opts.from_frame;
      if (trial && trial->boundary(i)) {
        if (!assembler.waitAssembled(f)) break;
        trial->blockBoundary(i, nowMs());
        if (trial->decided()) {
          std::string times;
          for (size_t c = 0; c < trial->candidates().size(); ++c)
            times += std::string(c ? ", " : "") + balanceName(trial->candidates()[c]) + " " +
                     std::to_string(int(trial->blockMs()[c] + 0.5)) + " ms";
          std::fprintf(stderr, "dmmr-render: --balance auto: %s per frame: %s from frame %u\n",
                       times.c_str(), balanceName(trial->winner()), f);
        }
      }
      if (!assembler.waitForRoom(f)) break;
      Balance balance = trial ? trial->strategy(i) : opts.balance;
      Camera cam;
      int stride = opts.ray_stride;
      if (hub) {
        bool exact = false;
        std::optional<Pose> pose = hub->nextPose(f, &exact);
        stride = exact ? 1 : opts.ray_stride;
        if (!pose) break;  // stopped
        cam = Camera{pose->position, {}, pose->fovy_deg, double(v.width) / v.height, near};
        unitRotation(pose->rotation, &cam.rotation);  // checked when decoded
      } else {
        cam = cameraAt(path.points[f], v.width, v.height, v.fovy_deg, near);
      }
      FrameRecord rec;
      rec.started = Clock::now();
      rec.camera = cam;
      planner.planningFrame(f);
      // Each job, with the client it goes to (-1: the dispatcher decides).
      std::vector<std::pair<int, FrameJob>> jobs;
      // A job for `rect` drawing `objects` (flushed unless told otherwise).
      auto makeJob = [&](const Rect& rect, std::vector<uint32_t>&& objects) {
        FrameJob j{f, cam, v.width, v.height, rect, std::move(objects), true, {}};
        if (opts.visible_weights) j.hints = planner.drawnLately(j.objects);
        j.ray_stride = uint8_t(stride);
        return j;
      };
      if (balance == Balance::Frustum) {
        const int per = opts.regions_per_client;
        const int parts = opts.pool_parts > 0 ? opts.pool_parts : 2 * clients;
        FramePlan plan = planner.plan(cam, v.width, v.height, clients, per, opts.pool_share,
                                      opts.pool_share > 0 ? parts : 0);
        rec.cull_ms = plan.cull_ms;
        rec.divide_ms = plan.divide_ms;
        rec.plan_cpu_ms = plan.plan_cpu_ms;
        rec.objects = plan.objects_in_frustum;
        rec.triangles = plan.triangles_in_frustum;
        rec.grid = std::move(plan.grid);
        // Per client: its first region's rectangle (the cost grid's, which
        // needs one region a client) and the weight of all its regions.
        for (int k = 0; k < clients; ++k)
          rec.planned.push_back({plan.regions[size_t(k)].rect, 0, 0});
        if (division_log) rec.forecasts.resize(size_t(clients));
        for (size_t j = 0; j < plan.regions.size(); ++j) {
          const int k = regionClient(j, clients);
          rec.planned[size_t(k)].planned += plan.planned[j];
          if (division_log)
            rec.forecasts[size_t(k)] += planner.forecast(cam, v.width, v.height, plan.regions[j]);
          jobs.push_back(
              {k + 1, makeJob(plan.regions[j].rect, std::move(plan.regions[j].objects))});
          // A client's sub-frames go back in one batch, after its last region.
          jobs.back().second.flush = j + size_t(clients) >= plan.regions.size();
        }
        for (Region& part : plan.pool)  // to whichever client is free first
          jobs.push_back({-1, makeJob(part.rect, std::move(part.objects))});
      } else {
        int tile_w = opts.tile_w, tile_h = opts.tile_h;
        if (opts.tiles_per_client > 0)
          gridTileSize(v.width, v.height, clients * opts.tiles_per_client, &tile_w, &tile_h);
        TilePlan plan = planner.planTiles(cam, v.width, v.height, tile_w, tile_h);
        rec.cull_ms = plan.cull_ms;
        rec.divide_ms = plan.divide_ms;
        rec.plan_cpu_ms = plan.plan_cpu_ms;
        rec.objects = plan.objects_in_frustum;
        rec.triangles = plan.triangles_in_frustum;
        auto job = [&](size_t t) { return makeJob(plan.tiles[t], std::move(plan.objects[t])); };
        if (balance == Balance::TilesStatic) {
          auto dealt = dealTiles(plan.tiles.size(), plan.columns, clients, opts.tile_order);
          for (int k = 0; k < clients; ++k)
            for (size_t i = 0; i < dealt[size_t(k)].size(); ++i) {
              jobs.push_back({k + 1, job(dealt[size_t(k)][i])});
              jobs.back().second.flush = i + 1 == dealt[size_t(k)].size();  // one batch back
            }
        } else {
          for (size_t t = 0; t < plan.tiles.size(); ++t) jobs.push_back({-1, job(t)});
        }
      }
      std::vector<int> owed(size_t(clients), 0);
      for (const auto& [k, j] : jobs)
        if (k > 0) ++owed[size_t(k - 1)];
      auto ts = Clock::now();
      assembler.begin(f, std::move(rec), std::move(owed), int(jobs.size()));
      if (injectedServerFault(("send:" + std::to_string(f)).c_str()))
        throw Error("fault injected by DMMR_INJECT_FAULT sending frame " + std::to_string(f));
      // A frame of static tiles is many jobs per client: stop at a failure
      // rather than send the rest to clients that are winding down. The
      // jobs for no client in particular (dynamic tiles, a pool's parts) go
      // to the dispatcher after the others, so that each client's own
      // region comes first in its queue.
      // The jobs go out together (SendBatch): each client takes its own
      // when it polls next, and the planner waits for the last of them, not
      // for each in turn.
      std::vector<FrameJob> pool;
      SendBatch batch(comm);
      for (auto& [k, j] : jobs) {
        if (k < 0) {
          pool.push_back(std::move(j));
          continue;
        }
        if (assembler.failed()) break;
        batch.post(k, Tag::Job, encodeJob(j));
      }
      batch.wait([&](int k) { assembler.sendingTo(k); });
      assembler.sendingTo(0);
      if (!pool.empty() && !assembler.failed()) dispatcher.add(std::move(pool));
      assembler.setSendMs(f, msBetween(ts, Clock::now()));
    }
  };
  runGuarded(planFrames, [&](const std::string& what) { assembler.markFailed("server: " + what); });
  assembler.plannerDone();
  assembling.join();
  if (hub) hub->stop();
  if (opts.progress) std::fprintf(stderr, "\n");  // ends the progress line before the logs
  if (opts.fitted_weights) {                      // what the division weighed, for the log
    std::ostringstream m;
    m << planner.costModel() << ", speeds";
    for (double sp : planner.speeds()) m << " " << sp;
    std::fprintf(stderr, "dmmr-render: --weights fitted: %s\n", m.str().c_str());
  }
  if (planner.costGridEnabled()) {  // what the division learnt, for the log
    std::ostringstream m;
    m << planner.costGrid();
    std::fprintf(stderr, "dmmr-render: --cost-grid: %s\n", m.str().c_str());
  }
  // Sub-frames still on their way complete frames that every client
  // finished before a failure.
  dispatcher.close();
  shutdownClients(comm, clients, opts.client_timeout_s,
                  [&](const Message& m) { assembler.take(m); });
  if (assembler.failed()) {
    std::fprintf(stderr, "dmmr-render: %s\n", assembler.error().c_str());
    return 1;
  }
  return 0;
}

}  // namespace dmmr
