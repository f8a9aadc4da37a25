// Tests for the little-endian byte streams and the checked container
// (common/bytes.h). Expected values come from the container layout documented
// in bytes.h and from an independent bitwise CRC-32, never from the code under
// test.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "bytes.h"
#include "error.h"
#include "test_support.h"

namespace dmmr {
namespace {

// Reference CRC-32 (IEEE 802.3, reflected, as zlib computes it), bit by bit.
uint32_t referenceCrc(const uint8_t* p, size_t n) {
  uint32_t c = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}

uint64_t readLE(const std::vector<uint8_t>& b, size_t at, size_t n) {
  uint64_t v = 0;
  for (size_t i = 0; i < n; ++i) v |= uint64_t(b[at + i]) << (8 * i);
  return v;
}

void putLE(std::vector<uint8_t>& b, uint64_t v, size_t n) {
  for (size_t i = 0; i < n; ++i) b.push_back(uint8_t(v >> (8 * i)));
}

// Builds a container by hand from the layout in bytes.h.
std::vector<uint8_t> handContainer(const char* magic, uint32_t version,
                                   const std::vector<uint8_t>& payload) {
  std::vector<uint8_t> f(magic, magic + 8);
  putLE(f, version, 4);
  putLE(f, payload.size(), 8);
  f.insert(f.end(), payload.begin(), payload.end());
  putLE(f, referenceCrc(f.data(), f.size()), 4);
  return f;
}

using dmmr::test::errorOf;

// Expects `f` to throw dmmr::Error whose message holds every needle.
template <typename F>
void expectError(F&& f, std::initializer_list<std::string> needles) {
  std::string msg = errorOf(f);
  ASSERT_FALSE(msg.empty()) << "no dmmr::Error thrown";
  for (const auto& n : needles)
    EXPECT_NE(msg.find(n), std::string::npos) << "message: " << msg << "\nmissing: " << n;
}

constexpr FileKind kTestKind{"DMMRTEST", 3, "test"};

// ---- crc32 ------------------------------------------------------------------

TEST(Crc32Test, KnownCheckValue) {
  // The standard CRC-32 check value for the ASCII digits 1..9.
  const char* s = "123456789";
  EXPECT_EQ(crc32(reinterpret_cast<const uint8_t*>(s), 9), 0xCBF43926u);
  EXPECT_EQ(crc32(nullptr, 0), 0u);
}

TEST(Crc32Test, MatchesBitwiseReferenceOnRandomData) {
  std::mt19937 rng(7);
  for (size_t n : {1u, 2u, 3u, 17u, 255u, 4096u}) {
    std::vector<uint8_t> b(n);
    for (auto& v : b) v = uint8_t(rng());
    EXPECT_EQ(crc32(b.data(), b.size()), referenceCrc(b.data(), b.size())) << n;
  }
}

TEST(Crc32Test, SeedContinuesAChecksum) {
  std::vector<uint8_t> b(1000);
  std::mt19937 rng(8);
  for (auto& v : b) v = uint8_t(rng());
  for (size_t cut : {0u, 1u, 500u, 999u, 1000u})
    EXPECT_EQ(crc32(b.data() + cut, b.size() - cut, crc32(b.data(), cut)),
              referenceCrc(b.data(), b.size()))
        << cut;
}

// ---- ByteWriter ---------------------------------------------------------------

TEST(ByteWriterTest, WritesLittleEndian) {
  ByteWriter w;
  w.u8(0xAB);
  w.u32(0x01020304u);
  w.u64(0x1122334455667788ull);
  w.i32(-2);
  w.f32(1.0f);  // 0x3F800000
  w.f64(-2.0);  // 0xC000000000000000
  w.str("hi");
  std::vector<uint8_t> want = {0xAB, 0x04, 0x03, 0x02, 0x01, 0x88, 0x77, 0x66, 0x55,
                               0x44, 0x33, 0x22, 0x11, 0xFE, 0xFF, 0xFF, 0xFF, 0x00,
                               0x00, 0x80, 0x3F, 0,    0,    0,    0,    0,    0,
                               0,    0xC0, 2,    0,    0,    0,    'h',  'i'};
  EXPECT_EQ(w.bytes(), want);
}

TEST(ByteWriterTest, ArraysAreElementwiseLittleEndian) {
  ByteWriter w;
  uint16_t s[2] = {0x0102, 0xA0B0};
  uint32_t u[1] = {0xDEADBEEF};
  w.array(s, 2);
  w.array(u, 1);
  w.array(static_cast<const float*>(nullptr), 0);
  EXPECT_EQ(w.bytes(), (std::vector<uint8_t>{0x02, 0x01, 0xB0, 0xA0, 0xEF, 0xBE, 0xAD, 0xDE}));
}

// ---- ByteReader ---------------------------------------------------------------

TEST(ByteReaderTest, RandomScalarsRoundTrip) {
  std::mt19937_64 rng(11);
  for (int round = 0; round < 200; ++round) {
    uint8_t a = uint8_t(rng());
    uint32_t b = uint32_t(rng());
    uint64_t c = rng();
    int32_t d = int32_t(uint32_t(rng()));
    float e = std::bit_cast<float>(uint32_t(rng()));
    double f = std::bit_cast<double>(rng());
    std::string g(size_t(rng() % 40), 'x');
    for (char& ch : g) ch = char(rng());
    ByteWriter w;
    w.u8(a);
    w.u32(b);
    w.u64(c);
    w.i32(d);
    w.f32(e);
    w.f64(f);
    w.str(g);
    ByteReader r(w.bytes().data(), w.bytes().size(), "mem");
    EXPECT_EQ(r.u8("a"), a);
    EXPECT_EQ(r.u32("b"), b);
    EXPECT_EQ(r.u64("c"), c);
    EXPECT_EQ(r.i32("d"), d);
    EXPECT_EQ(std::bit_cast<uint32_t>(r.f32("e")), std::bit_cast<uint32_t>(e));  // NaNs too
    EXPECT_EQ(std::bit_cast<uint64_t>(r.f64("f")), std::bit_cast<uint64_t>(f));
    EXPECT_EQ(r.str("g"), g);
    EXPECT_EQ(r.remaining(), 0u);
    EXPECT_NO_THROW(r.finish());
  }
}

TEST(ByteReaderTest, ArrayRoundTrip) {
  std::vector<float> v = {1.5f, -2.25f, 3e30f};
  ByteWriter w;
  w.array(v.data(), v.size());
  ByteReader r(w.bytes().data(), w.bytes().size(), "mem");
  std::vector<float> out;
  r.array(&out, 3, "values");
  EXPECT_EQ(out, v);
  r.finish();
}

TEST(ByteReaderTest, ReadingPastTheEndThrowsNamingPathAndField) {
  uint8_t b[3] = {1, 2, 3};
  ByteReader r(b, 3, "dir/short.bin");
  expectError([&] { r.u32("the count"); }, {"dir/short.bin", "the count", "truncated"});
  // Nothing was consumed by the failed read.
  EXPECT_EQ(r.remaining(), 3u);
  EXPECT_EQ(r.u8("x"), 1);
}

TEST(ByteReaderTest, StringLongerThanLimitThrows) {
  ByteWriter w;
  w.str(std::string(100, 'a'));
  ByteReader r(w.bytes().data(), w.bytes().size(), "names.bin");
  expectError([&] { r.str("name", 99); }, {"names.bin", "name", "too large"});
  ByteReader r2(w.bytes().data(), w.bytes().size(), "names.bin");
  EXPECT_EQ(r2.str("name", 100), std::string(100, 'a'));
}

TEST(ByteReaderTest, StringLengthPastTheEndThrows) {
  ByteWriter w;
  w.u32(10);
  w.u8('a');
  ByteReader r(w.bytes().data(), w.bytes().size(), "s.bin");
  expectError([&] { r.str("label"); }, {"s.bin", "label", "truncated"});
}

TEST(ByteReaderTest, HostileArrayCountThrowsBeforeAllocating) {
  uint8_t b[16] = {};
  for (uint64_t n : {uint64_t(5), uint64_t(1) << 40, ~uint64_t(0), ~uint64_t(0) / 4 + 1}) {
    ByteReader r(b, 16, "h.bin");
    std::vector<uint32_t> out;
    expectError([&] { r.array(&out, n, "items"); }, {"h.bin", "items"});
    EXPECT_TRUE(out.empty());
  }
  ByteReader r(b, 16, "h.bin");
  std::vector<uint32_t> out;
  r.array(&out, 4, "items");
  EXPECT_EQ(out.size(), 4u);
}

TEST(ByteReaderTest, FinishRejectsTrailingBytes) {
  uint8_t b[5] = {};
  ByteReader r(b, 5, "t.bin");
  r.u32("x");
  expectError([&] { r.finish(); }, {"t.bin", "1 trailing"});
}

// ---- container ------------------------------------------------------------------

TEST(ContainerTest, LayoutMatchesDocumentation) {
  std::vector<uint8_t> payload = {9, 8, 7, 6, 5};
  std::vector<uint8_t> f = wrapContainer(kTestKind, payload);
  ASSERT_EQ(f.size(), kContainerOverhead + payload.size());
  EXPECT_EQ(f, handContainer("DMMRTEST", 3, payload));
  EXPECT_EQ(std::string(f.begin(), f.begin() + 8), "DMMRTEST");
  EXPECT_EQ(readLE(f, 8, 4), 3u);
  EXPECT_EQ(readLE(f, 12, 8), payload.size());
  EXPECT_EQ(readLE(f, f.size() - 4, 4), referenceCrc(f.data(), f.size() - 4));
}

TEST(ContainerTest, RoundTripReturnsThePayload) {
  std::mt19937 rng(3);
  for (size_t n : {0u, 1u, 100u, 70000u}) {
    std::vector<uint8_t> payload(n);
    for (auto& b : payload) b = uint8_t(rng());
    std::vector<uint8_t> f = wrapContainer(kTestKind, payload);
    auto [p, size] = openContainer(kTestKind, f, "rt.bin");
    ASSERT_EQ(size, n);
    EXPECT_EQ(std::vector<uint8_t>(p, p + size), payload);
  }
}

TEST(ContainerTest, RejectsWrongMagic) {
  std::vector<uint8_t> f = handContainer("DMMRTESU", 3, {1, 2});
  expectError([&] { openContainer(kTestKind, f, "m.bin"); }, {"m.bin", "magic", "test"});
}

TEST(ContainerTest, RejectsUnknownVersion) {
  for (uint32_t v : {0u, 2u, 4u, 0xFFFFFFFFu}) {
    std::vector<uint8_t> f = handContainer("DMMRTEST", v, {1, 2});
    expectError([&] { openContainer(kTestKind, f, "v.bin"); },
                {"v.bin", "version " + std::to_string(v)});
  }
}

TEST(ContainerTest, RejectsEveryTruncation) {
  std::vector<uint8_t> f = wrapContainer(kTestKind, {1, 2, 3, 4, 5, 6, 7});
  for (size_t n = 0; n < f.size(); ++n) {
    std::vector<uint8_t> cut(f.begin(), f.begin() + long(n));
    expectError([&] { openContainer(kTestKind, cut, "cut.bin"); }, {"cut.bin"});
  }
}

TEST(ContainerTest, RejectsTrailingBytes) {
  std::vector<uint8_t> f = wrapContainer(kTestKind, {1, 2, 3});
  f.push_back(0);
  expectError([&] { openContainer(kTestKind, f, "tail.bin"); }, {"tail.bin", "1 trailing"});
}

TEST(ContainerTest, RejectsChecksumMismatch) {
  std::vector<uint8_t> payload = {1, 2, 3, 4, 5, 6, 7, 8};
  std::vector<uint8_t> good = wrapContainer(kTestKind, payload);
  for (size_t i = 20; i < good.size(); ++i) {  // every payload and checksum byte
    std::vector<uint8_t> f = good;
    f[i] ^= 0x10;
    expectError([&] { openContainer(kTestKind, f, "crc.bin"); }, {"crc.bin", "checksum"});
  }
}

TEST(ContainerTest, RejectsHugePayloadSizeWithoutOverflow) {
  // Sizes near 2^64 must not wrap around when the overhead is added.
  for (uint64_t size : {~uint64_t(0), ~uint64_t(0) - kContainerOverhead + 1, uint64_t(1) << 62}) {
    std::vector<uint8_t> f(std::begin(kTestKind.magic), std::begin(kTestKind.magic) + 8);
    putLE(f, 3, 4);
    putLE(f, size, 8);
    putLE(f, 0, 4);
    putLE(f, referenceCrc(f.data(), f.size()), 4);
    expectError([&] { openContainer(kTestKind, f, "big.bin"); }, {"big.bin", "truncated"});
  }
}

TEST(ContainerTest, RejectsPayloadSizeSmallerThanTheFile) {
  std::vector<uint8_t> f = handContainer("DMMRTEST", 3, {1, 2, 3, 4});
  f[12] = 2;  // claims 2 payload bytes: the rest reads as trailing bytes
  expectError([&] { openContainer(kTestKind, f, "s.bin"); }, {"s.bin", "trailing"});
}

}  // namespace
}  // namespace dmmr
