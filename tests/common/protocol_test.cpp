// Server-client messages: round trips, and a named rejection for each way a
// message can be malformed (they come over the network: never a crash).
#include <gtest/gtest.h>

#include <limits>

#include "error.h"
#include "protocol.h"

using namespace dmmr;

namespace {

// The sample job's scene: its highest object index is the last one.
constexpr size_t kObjects = 4000000001u;

FrameJob sampleJob() {
  FrameJob j;
  j.frame = 7;
  j.camera = Camera{{1.5, -2, 1e6}, Quatd{0.1, 0.2, 0.3, 0.927}, 50, 1.25, 0.01};
  j.width = 640;
  j.height = 480;
  j.region = {64, 128, 64, 32};
  j.objects = {1, 5, 9, 4000000000u};
  j.flush = false;
  return j;
}

SubFrame sampleSubFrame(uint32_t frame, Rect r) {
  SubFrame s;
  s.frame = frame;
  s.region = r;
  s.codec = Codec::None;
  s.raw_size = uint64_t(r.area()) * 3;
  s.data.assign(size_t(s.raw_size), 0x42);
  s.stats.render_ms = 3.5;
  s.stats.vis_cpu_ms = 1.25;
  s.stats.render_cpu_ms = 2.75;
  s.stats.vis_sys_ms = 0.125;
  s.stats.render_sys_ms = 0.5;
  s.stats.vis_faults = 17;
  s.stats.render_faults = 4096;
  s.stats.triangles = 1234;
  s.stats.submitted = 1000;
  s.stats.gpu_resident = 99;
  s.drawn = {2, 3};
  return s;
}

std::string errorOf(const std::vector<uint8_t>& bytes, bool job) {
  try {
    if (job)
      decodeJob(bytes, kObjects);
    else
      decodeSubFrames(bytes);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Protocol, JobRoundTripsWithItsFlushFlag) {
  FrameJob j = sampleJob();
  EXPECT_EQ(decodeJob(encodeJob(j), kObjects), j);
  j.flush = true;
  EXPECT_EQ(decodeJob(encodeJob(j), kObjects), j);
}

// What a client indexes with a job's contents is checked at decoding.
std::string jobError(const FrameJob& j, size_t objects = kObjects) {
  try {
    decodeJob(encodeJob(j), objects);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Protocol, JobRejectsAnObjectBeyondTheScene) {
  FrameJob j = sampleJob();
  EXPECT_NE(jobError(j, 4000000000u).find("beyond the scene"), std::string::npos);
  j.objects = {0, 1, 2};
  EXPECT_EQ(jobError(j, 3), "");
  EXPECT_NE(jobError(j, 2).find("beyond the scene"), std::string::npos);
}

TEST(Protocol, JobRejectsObjectsNotAscending) {
  FrameJob j = sampleJob();
  j.objects = {1, 5, 5};
  EXPECT_NE(jobError(j).find("not ascending"), std::string::npos);
  j.objects = {5, 1};
  EXPECT_NE(jobError(j).find("not ascending"), std::string::npos);
}

TEST(Protocol, JobRoundTripsWithItsHints) {
  FrameJob j = sampleJob();
  j.hints = {5, 4000000000u};
  EXPECT_EQ(decodeJob(encodeJob(j), kObjects), j);
}

TEST(Protocol, JobRejectsHintsNotAmongItsObjectsOrNotAscending) {
  FrameJob j = sampleJob();
  j.hints = {2};  // not an object of the job
  EXPECT_NE(jobError(j).find("not among the objects"), std::string::npos) << jobError(j);
  j.hints = {9, 5};
  EXPECT_NE(jobError(j).find("hints not ascending"), std::string::npos) << jobError(j);
  j.hints = {5, 5};
  EXPECT_NE(jobError(j).find("hints not ascending"), std::string::npos) << jobError(j);
  j.hints = {1, 5, 9, 4000000000u};  // all of them
  EXPECT_EQ(jobError(j), "");
}

TEST(Protocol, JobRoundTripsItsRayStrideAndRejectsOneOutsideOneToEight) {
  FrameJob j = sampleJob();
  for (uint8_t s : {1, 2, 8}) {
    j.ray_stride = s;
    EXPECT_EQ(decodeJob(encodeJob(j), kObjects), j);
  }
  for (uint8_t s : {0, 9, 255}) {
    j.ray_stride = s;
    EXPECT_NE(jobError(j).find("ray stride outside 1 to 8"), std::string::npos) << jobError(j);
  }
}

TEST(Protocol, JobRejectsARegionOutsideItsFrame) {
  FrameJob j = sampleJob();
  j.region = {600, 0, 41, 10};  // one column past 640
  EXPECT_NE(jobError(j).find("region outside the frame"), std::string::npos);
  j.region = {std::numeric_limits<int>::max() - 5, 0, 100, 1};  // x + w overflows int
  EXPECT_NE(jobError(j).find("region outside the frame"), std::string::npos);
  j.region = {0, 0, 640, 480};
  EXPECT_EQ(jobError(j), "");
}

TEST(Protocol, JobRejectsACameraThatCannotProject) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  constexpr double inf = std::numeric_limits<double>::infinity();
  for (auto [spoil, what] : std::vector<std::pair<void (*)(Camera&), std::string>>{
           {[](Camera& c) { c.eye.y = nan; }, "not finite"},
           {[](Camera& c) { c.rotation.w = inf; }, "not finite"},
           {[](Camera& c) { c.fovy_deg = 180; }, "field of view"},
           {[](Camera& c) { c.fovy_deg = 0; }, "field of view"},
           {[](Camera& c) { c.aspect = -1; }, "not positive"},
           {[](Camera& c) { c.near = 0; }, "not positive"},
           {[](Camera& c) {
              c.rotation = Quatd{0, 0, 0, 0};
            },
            "zero rotation"}}) {
    FrameJob j = sampleJob();
    spoil(j.camera);
    EXPECT_NE(jobError(j).find(what), std::string::npos) << what << ": " << jobError(j);
  }
}

TEST(Protocol, JobRejectsTruncationTrailingBytesAndABadFlag) {
  std::vector<uint8_t> b = encodeJob(sampleJob());
  for (size_t n : {size_t(0), size_t(3), b.size() / 2, b.size() - 1})
    EXPECT_NE(errorOf({b.begin(), b.begin() + long(n)}, true), "") << "truncated to " << n;
  std::vector<uint8_t> trailing = b;
  trailing.push_back(0);
  EXPECT_NE(errorOf(trailing, true), "");
  std::vector<uint8_t> flag = b;
  flag[flag.size() - 6] = 2;  // the flush byte: then the (empty) hint list's count, the stride
  EXPECT_NE(errorOf(flag, true).find("flush"), std::string::npos) << errorOf(flag, true);
}

TEST(Protocol, ABatchOfSubFramesRoundTrips) {
  std::vector<SubFrame> batch = {sampleSubFrame(3, {0, 0, 4, 2}), sampleSubFrame(3, {4, 0, 3, 2}),
                                 sampleSubFrame(3, {0, 2, 7, 1})};
  EXPECT_EQ(decodeSubFrames(encodeSubFrames(batch)), batch);
  SubFrame one = sampleSubFrame(9, {1, 1, 2, 2});
  EXPECT_EQ(decodeSubFrame(encodeSubFrame(one)), one);
}

TEST(Protocol, SubFramesRejectAnEmptyBatchTruncationAndTrailingBytes) {
  EXPECT_NE(errorOf(encodeSubFrames({}), false).find("no sub-frames"), std::string::npos);
  std::vector<uint8_t> b =
      encodeSubFrames({sampleSubFrame(1, {0, 0, 2, 2}), sampleSubFrame(1, {2, 0, 2, 2})});
  for (size_t n : {size_t(2), size_t(40), b.size() / 2, b.size() - 1})
    EXPECT_NE(errorOf({b.begin(), b.begin() + long(n)}, false), "") << "truncated to " << n;
  b.push_back(7);
  EXPECT_NE(errorOf(b, false), "");
}

TEST(Protocol, SubFramesRejectACountTheBytesCannotHold) {
  std::vector<uint8_t> b = encodeSubFrames({sampleSubFrame(1, {0, 0, 1, 1})});
  b[0] = b[1] = b[2] = 0xff;  // little-endian count: ~16M sub-frames in a few hundred bytes
  EXPECT_NE(errorOf(b, false).find("more sub-frames"), std::string::npos) << errorOf(b, false);
}

TEST(Protocol, SingleSubFrameDecoderRejectsABatch) {
  std::vector<uint8_t> b =
      encodeSubFrames({sampleSubFrame(1, {0, 0, 1, 1}), sampleSubFrame(1, {1, 0, 1, 1})});
  EXPECT_THROW(decodeSubFrame(b), Error);
}

TEST(Protocol, RawSizeMustMatchTheRegion) {
  SubFrame s = sampleSubFrame(1, {0, 0, 2, 2});
  s.raw_size = 11;
  EXPECT_NE(errorOf(encodeSubFrame(s), false).find("raw size"), std::string::npos);
}

TEST(Protocol, AccumulateSumsTilesAndKeepsTheLatestResidency) {
  ClientStats total, a, b;
  a.render_ms = 2;
  a.render_cpu_ms = 1.5;
  a.vis_cpu_ms = 0.5;
  a.render_sys_ms = 0.25;
  a.render_faults = 3;
  a.triangles = 10;
  a.submitted = 6;
  a.gpu_resident = 100;
  b.render_ms = 3.5;
  b.render_cpu_ms = 3;
  b.vis_cpu_ms = 1;
  b.render_sys_ms = 0.5;
  b.vis_sys_ms = 0.125;
  b.render_faults = 4;
  b.vis_faults = 9;
  b.triangles = 5;
  b.submitted = 2;
  b.gpu_resident = 80;
  b.ram_resident = 7;
  accumulate(total, a);
  accumulate(total, b);
  EXPECT_DOUBLE_EQ(total.render_ms, 5.5);
  EXPECT_DOUBLE_EQ(total.render_cpu_ms, 4.5);
  EXPECT_DOUBLE_EQ(total.vis_cpu_ms, 1.5);
  EXPECT_DOUBLE_EQ(total.render_sys_ms, 0.75);
  EXPECT_DOUBLE_EQ(total.vis_sys_ms, 0.125);
  EXPECT_EQ(total.render_faults, 7u);
  EXPECT_EQ(total.vis_faults, 9u);
  EXPECT_EQ(total.triangles, 15u);
  EXPECT_EQ(total.submitted, 8u);
  EXPECT_EQ(total.gpu_resident, 80u);
  EXPECT_EQ(total.ram_resident, 7u);
}
