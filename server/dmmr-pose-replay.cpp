// dmmr-pose-replay --url URL --walkthrough PATH [--rate 60] [--duration S]
// Plays a walkthrough's control points, one per tick at --rate Hz (looping
// for --duration seconds), as a live pose stream to `dmmr-render --serve`,
// as a head-mounted display would send them; acks every frame; records per
// pose whether a frame came for it and the pose-to-frame latency. The
// interactive mode's benchmark client (docs/benchmarks.md).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>

#include "atomic_file.h"
#include "error.h"
#include "image.h"
#include "viewer_client.h"
#include "walkthrough.h"

namespace {

struct PoseRecord {
  double sent_ms = 0;
  bool served = false;
  double latency_ms = 0;
  uint32_t frame = 0;
  std::string encoding;
  uint64_t bytes = 0;
  double encode_ms = 0, server_latency_ms = 0;
  // The server's split of the latency (docs/interactive.md, frame header).
  double pose_wait_ms = 0, pick_to_done_ms = 0, done_to_send_ms = 0;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  size_t i = size_t(std::min<double>(double(v.size() - 1), std::floor(p * double(v.size()))));
  return v[i];
}

}  // namespace

int main(int argc, char** argv) {
  std::string url, walkthrough, csv, still_out, summary;
  double rate = 60, duration = 0, drain_s = 3, timeout_s = 30;
  int quality = 80;
  CLI::App app{"dmmr-pose-replay: a walkthrough as a live pose stream to dmmr-render --serve"};
  app.add_option("--url", url, "the URL dmmr-render --serve printed (with its token)")->required();
  app.add_option("--walkthrough", walkthrough, "AnimationPath file: one pose per control point")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--rate", rate, "poses a second")->check(CLI::Range(0.1, 1000.0));
  app.add_option("--duration", duration, "seconds to stream, looping the path (0: the path once)")
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("--quality", quality, "JPEG quality while moving, 1..100; 0: every frame PNG")
      ->check(CLI::Range(0, 100));
  app.add_option("--csv", csv, "per-pose CSV: seq, sent, served, latency, frame, bytes, ...");
  app.add_option("--summary", summary, "summary as JSON (for the benchmark scripts)");
  app.add_option("--still-out", still_out,
                 "after the last pose, wait for the exact (still) frame and write it here as "
                 "PNG, with its pose as PATH.path (an AnimationPath of one point)");
  app.add_option("--drain", drain_s, "seconds to wait for frames after the last pose")
      ->check(CLI::Range(0.0, 600.0));
  app.add_option("--timeout", timeout_s, "seconds to wait for the connection and the still")
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);

  try {
    dmmr::ServeUrl at;
    if (!dmmr::parseServeUrl(url, &at))
      throw dmmr::Error("--url " + url + ": expected http://HOST:PORT/?token=...");
    dmmr::Walkthrough path = dmmr::readWalkthrough(walkthrough);
    dmmr::ViewerClient viewer(at, timeout_s);
    const auto& hello = viewer.hello();
    const uint32_t width = hello.value("width", 0u), height = hello.value("height", 0u);
    const double fovy = hello.value("fovy_deg", 45.0);
    const double period = 1000.0 / rate;
    const size_t poses = duration > 0 ? size_t(std::ceil(duration * rate)) : path.points.size();

    std::vector<PoseRecord> rec(poses);
    std::map<std::string, std::vector<double>> bytes_by_enc, encode_by_enc;
    std::optional<dmmr::ViewerClient::Received> still;
    auto take = [&](const dmmr::ViewerClient::Received& r) {
      if (r.kind == dmmr::ViewerClient::Received::Kind::Closed)
        throw dmmr::Error("the server closed the connection (code " + std::to_string(r.close_code) +
                          ": " + r.close_reason + ")");
      if (r.kind != dmmr::ViewerClient::Received::Kind::Frame) return;
      const auto& h = r.header;
      uint32_t frame = h.value("frame", 0u), seq = h.value("seq", 0u);
      viewer.sendAck(frame);
      std::string enc = h.value("encoding", "");
      double encode_ms = h["server"].value("encode_ms", 0.0);
      bytes_by_enc[enc].push_back(double(r.frame.image.size()));
      encode_by_enc[enc].push_back(encode_ms);
      if (h.value("still", false)) {
        still = r;
        return;
      }
      if (seq < 1 || seq > poses)
        throw dmmr::Error("a frame for pose " + std::to_string(seq) + ", which was never sent");
      PoseRecord& p = rec[seq - 1];
      p.served = true;
      p.latency_ms = r.at_ms - h.value("time_ms", 0.0);
      p.frame = frame;
      p.encoding = enc;
      p.bytes = r.frame.image.size();
      p.encode_ms = encode_ms;
      p.server_latency_ms = h["server"].value("latency_ms", 0.0);
      p.pose_wait_ms = h["server"].value("pose_wait_ms", 0.0);
      p.pick_to_done_ms = h["server"].value("pick_to_done_ms", 0.0);
      p.done_to_send_ms = h["server"].value("done_to_send_ms", 0.0);
    };

    dmmr::Pose last;
    double next = dmmr::steadyMs();
    for (size_t i = 0; i < poses; ++i) {
      for (double now = dmmr::steadyMs(); now < next; now = dmmr::steadyMs())
        take(viewer.receive((next - now) / 1000));
      const dmmr::ControlPoint& cp = path.points[i % path.points.size()];
      dmmr::Pose p;
      p.seq = uint32_t(i + 1);
      p.position = cp.position;
      p.rotation = cp.rotation;
      p.fovy_deg = fovy;
      p.width = width;
      p.height = height;
      p.quality = uint8_t(quality);
      p.time_ms = dmmr::steadyMs();
      viewer.sendPose(p);
      rec[i].sent_ms = p.time_ms;
      last = p;
      // A stall (this process starved of the CPU) sends no burst after it.
      next = std::max(next + period, p.time_ms);
    }
    double end = dmmr::steadyMs() + drain_s * 1000;
    for (double now = dmmr::steadyMs(); now < end; now = dmmr::steadyMs())
      take(viewer.receive((end - now) / 1000));
    if (!still_out.empty()) {
      double deadline = dmmr::steadyMs() + timeout_s * 1000;
      while (!still && dmmr::steadyMs() < deadline) take(viewer.receive(0.1));
      if (!still) throw dmmr::Error("no still frame within " + std::to_string(timeout_s) + " s");
      if (still->header.value("seq", 0u) != last.seq)
        throw dmmr::Error("the still frame is for pose " +
                          std::to_string(still->header.value("seq", 0u)) + ", not the last (" +
                          std::to_string(last.seq) + ")");
      dmmr::writeFileAtomic(still_out, still->frame.image);
      dmmr::Walkthrough one;
      one.points.push_back({0, last.position, last.rotation});
      dmmr::writeWalkthrough(still_out + ".path", one);
    }
    viewer.close();

    std::vector<double> lat, first, second;
    size_t served = 0;
    for (size_t i = 0; i < poses; ++i)
      if (rec[i].served) {
        ++served;
        lat.push_back(rec[i].latency_ms);
        (i < poses / 2 ? first : second).push_back(rec[i].latency_ms);
      }
    if (!csv.empty()) {
      std::ostringstream o;
      o << "seq,sent_ms,served,latency_ms,frame,encoding,bytes,encode_ms,server_latency_ms,"
           "pose_wait_ms,pick_to_done_ms,done_to_send_ms\n";
      o.setf(std::ios::fixed);
      o.precision(3);
      for (size_t i = 0; i < poses; ++i) {
        const PoseRecord& r = rec[i];
        o << i + 1 << "," << r.sent_ms - rec[0].sent_ms << "," << int(r.served) << ",";
        if (r.served)
          o << r.latency_ms << "," << r.frame << "," << r.encoding << "," << r.bytes << ","
            << r.encode_ms << "," << r.server_latency_ms << "," << r.pose_wait_ms << ","
            << r.pick_to_done_ms << "," << r.done_to_send_ms;
        else
          o << ",,,,,,,,";
        o << "\n";
      }
      std::string s = o.str();
      dmmr::writeFileAtomic(csv, s);
    }
    auto mean = [](const std::vector<double>& v) {
      double s = 0;
      for (double x : v) s += x;
      return v.empty() ? 0.0 : s / double(v.size());
    };
    nlohmann::json j = {{"poses_sent", poses},
                        {"poses_served", served},
                        {"rate_hz", rate},
                        {"seconds", (rec.back().sent_ms - rec.front().sent_ms) / 1000},
                        {"latency_median_ms", percentile(lat, 0.5)},
                        {"latency_p95_ms", percentile(lat, 0.95)},
                        {"latency_first_half_median_ms", percentile(first, 0.5)},
                        {"latency_second_half_median_ms", percentile(second, 0.5)}};
    for (const auto& [enc, b] : bytes_by_enc) {
      j["encodings"][enc] = {{"frames", b.size()},
                             {"bytes_mean", mean(b)},
                             {"encode_ms_mean", mean(encode_by_enc[enc])}};
    }
    std::printf(
        "dmmr-pose-replay: %zu poses sent at %.0f Hz, %zu served (%.1f%%); latency median %.1f "
        "ms, p95 %.1f ms (first half %.1f, second half %.1f)\n",
        poses, rate, served, 100.0 * double(served) / double(poses), percentile(lat, 0.5),
        percentile(lat, 0.95), percentile(first, 0.5), percentile(second, 0.5));
    for (const auto& [enc, b] : bytes_by_enc)
      std::printf("dmmr-pose-replay: %s: %zu frames, %.0f bytes and %.2f ms encode on average\n",
                  enc.c_str(), b.size(), mean(b), mean(encode_by_enc[enc]));
    if (!summary.empty()) {
      std::string s = j.dump(2) + "\n";
      dmmr::writeFileAtomic(summary, s);
    }
    return served > 0 ? 0 : 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dmmr-pose-replay: %s\n", e.what());
    return 1;
  }
}
