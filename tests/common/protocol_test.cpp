// Server-client messages: round trips, and a named rejection for each way a
// message can be malformed (they come over the network: never a crash).
#include <gtest/gtest.h>

#include "error.h"
#include "protocol.h"

using namespace dmmr;

namespace {

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
  s.stats.triangles = 1234;
  s.stats.gpu_resident = 99;
  s.drawn = {2, 3};
  return s;
}

std::string errorOf(const std::vector<uint8_t>& bytes, bool job) {
  try {
    if (job)
      decodeJob(bytes);
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
  EXPECT_EQ(decodeJob(encodeJob(j)), j);
  j.flush = true;
  EXPECT_EQ(decodeJob(encodeJob(j)), j);
}

TEST(Protocol, JobRejectsTruncationTrailingBytesAndABadFlag) {
  std::vector<uint8_t> b = encodeJob(sampleJob());
  for (size_t n : {size_t(0), size_t(3), b.size() / 2, b.size() - 1})
    EXPECT_NE(errorOf({b.begin(), b.begin() + long(n)}, true), "") << "truncated to " << n;
  std::vector<uint8_t> trailing = b;
  trailing.push_back(0);
  EXPECT_NE(errorOf(trailing, true), "");
  std::vector<uint8_t> flag = b;
  flag.back() = 2;  // the flush byte ends the message
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
  a.triangles = 10;
  a.gpu_resident = 100;
  b.render_ms = 3.5;
  b.triangles = 5;
  b.gpu_resident = 80;
  b.ram_resident = 7;
  accumulate(total, a);
  accumulate(total, b);
  EXPECT_DOUBLE_EQ(total.render_ms, 5.5);
  EXPECT_EQ(total.triangles, 15u);
  EXPECT_EQ(total.gpu_resident, 80u);
  EXPECT_EQ(total.ram_resident, 7u);
}
