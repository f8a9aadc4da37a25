// Tests for the scene file formats (common/formats.h) and the scene loader
// (common/scene.h): round trips, the payload layout written out by hand, and
// one test per rejection. Expected bytes come from a hand-written encoder and
// an independent bitwise CRC-32, never from the code under test.
#if defined(__GNUC__) && !defined(__clang__)
// GCC pairs the replaced operator new below with std::free in inlined code
// and warns, though the replacement new allocates with std::malloc.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <new>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "formats.h"
#include "scene.h"
#include "test_support.h"

// ---- allocation tracking -----------------------------------------------------
// Replacing the global operator new lets the hostile-count tests check that a
// decoder fails before allocating what a corrupt count asks for.
namespace {
std::atomic<size_t> g_largest_allocation{0};
}  // namespace

void* operator new(size_t n) {
  size_t seen = g_largest_allocation.load(std::memory_order_relaxed);
  while (n > seen && !g_largest_allocation.compare_exchange_weak(seen, n)) {
  }
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, size_t) noexcept {
  std::free(p);
}

namespace dmmr {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using Bytes = std::vector<uint8_t>;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---- helpers -------------------------------------------------------------------

uint32_t referenceCrc(const uint8_t* p, size_t n) {
  uint32_t c = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}

// A little-endian writer independent of ByteWriter.
struct Hand {
  Bytes b;
  void raw(uint64_t v, int n) {
    for (int i = 0; i < n; ++i) b.push_back(uint8_t(v >> (8 * i)));
  }
  void u8(uint8_t v) { raw(v, 1); }
  void u16(uint16_t v) { raw(v, 2); }
  void u32(uint32_t v) { raw(v, 4); }
  void u64(uint64_t v) { raw(v, 8); }
  void i32(int32_t v) { raw(uint32_t(v), 4); }
  void f32(float v) {
    uint32_t u;
    std::memcpy(&u, &v, 4);
    raw(u, 4);
  }
  void f64(double v) {
    uint64_t u;
    std::memcpy(&u, &v, 8);
    raw(u, 8);
  }
  void vec(Vec3d v) {
    f64(v.x);
    f64(v.y);
    f64(v.z);
  }
  void str(const std::string& s) {
    u32(uint32_t(s.size()));
    b.insert(b.end(), s.begin(), s.end());
  }
};

// The container: magic[8] | version u32 | size u64 | payload | crc u32.
Bytes payloadOf(const Bytes& file) {
  return Bytes(file.begin() + 20, file.end() - 4);
}

void recrc(Bytes& file) {
  uint32_t c = referenceCrc(file.data(), file.size() - 4);
  for (int i = 0; i < 4; ++i) file[file.size() - 4 + size_t(i)] = uint8_t(c >> (8 * i));
}

// `file`'s magic and version around a new payload, with a correct size and CRC.
Bytes withPayload(const Bytes& file, const Bytes& payload) {
  Hand h;
  h.b.assign(file.begin(), file.begin() + 12);
  h.u64(payload.size());
  h.b.insert(h.b.end(), payload.begin(), payload.end());
  h.u32(0);
  recrc(h.b);
  return h.b;
}

Bytes patched(const Bytes& file, size_t payload_offset, std::initializer_list<uint8_t> bytes) {
  Bytes p = payloadOf(file);
  size_t i = payload_offset;
  for (uint8_t v : bytes) p.at(i++) = v;
  return withPayload(file, p);
}

using dmmr::test::errorOf;

// Expects `f` to throw dmmr::Error whose message holds `path` and `needle`.
#define EXPECT_DMMR_ERROR(stmt, path, needle)                                            \
  do {                                                                                   \
    std::string msg_ = errorOf([&] { (void)(stmt); });                                   \
    if (msg_.empty()) {                                                                  \
      ADD_FAILURE() << "no dmmr::Error from " #stmt;                                     \
    } else {                                                                             \
      EXPECT_NE(msg_.find(path), std::string::npos) << msg_ << "\nlacks " << (path);     \
      EXPECT_NE(msg_.find(needle), std::string::npos) << msg_ << "\nlacks " << (needle); \
    }                                                                                    \
  } while (0)

// Runs `decode` on every proper prefix of `file`: each must throw Error naming path.
template <typename D>
void expectEveryTruncationThrows(const Bytes& file, D decode) {
  for (size_t n = 0; n < file.size(); ++n) {
    Bytes cut(file.begin(), file.begin() + long(n));
    std::string msg = errorOf([&] { decode(cut, "cut/file.bin"); });
    ASSERT_FALSE(msg.empty()) << "prefix of " << n << " bytes accepted";
    EXPECT_NE(msg.find("cut/file.bin"), std::string::npos) << msg;
  }
}

// Largest single allocation made while `f` runs.
template <typename F>
size_t largestAllocation(F&& f) {
  g_largest_allocation = 0;
  f();
  return g_largest_allocation.load();
}

template <typename D>
void expectFailsWithoutHugeAllocation(const Bytes& file, D decode) {
  auto t0 = std::chrono::steady_clock::now();
  size_t largest = largestAllocation([&] {
    std::string msg = errorOf([&] { decode(file, "hostile.bin"); });
    EXPECT_NE(msg.find("hostile.bin"), std::string::npos) << "message: " << msg;
  });
  EXPECT_LT(largest, size_t(1) << 16);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(1));
}

Mat4d randomAffine(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-10, 10), s(0.1, 4);
  Quatd q{u(rng), u(rng), u(rng), u(rng)};
  double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  q = {q.x / n, q.y / n, q.z / n, q.w / n};
  return Mat4d::translate({u(rng), u(rng), u(rng)}) * Mat4d::rotation(q) *
         Mat4d::scale({s(rng), s(rng), s(rng)});
}

Box3d randomBox(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-100, 100), e(0, 50);
  Box3d b;
  b.lo = {u(rng), u(rng), u(rng)};
  b.hi = b.lo + Vec3d{e(rng), e(rng), e(rng)};
  return b;
}

// ---- bounds ----------------------------------------------------------------------

std::vector<ObjectBounds> sampleObjects(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-100, 100);
  std::vector<ObjectBounds> out(n);
  for (auto& o : out) {
    o.geometry = uint32_t(rng());
    o.transform = randomAffine(rng);
    o.sphere.center = {u(rng), u(rng), u(rng)};
    o.sphere.radius = std::fabs(u(rng));
    o.box = randomBox(rng);
    o.use_box = rng() & 1;
    o.weight = (uint64_t(rng()) << 32) | rng();
  }
  if (n > 0) out[0].sphere.radius = 0;  // a point is a valid sphere
  return out;
}

constexpr size_t kBoundsRecord = 4 + 96 + 32 + 48 + 1 + 8;

Bytes handBounds(const std::vector<ObjectBounds>& objects) {
  Hand h;
  h.u32(uint32_t(objects.size()));
  for (const auto& o : objects) {
    h.u32(o.geometry);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) h.f64(o.transform.at(r, c));
    h.vec(o.sphere.center);
    h.f64(o.sphere.radius);
    h.vec(o.box.lo);
    h.vec(o.box.hi);
    h.u8(o.use_box);
    h.u64(o.weight);
  }
  return h.b;
}

TEST(BoundsFormat, RoundTrip) {
  for (size_t n : {0u, 1u, 2u, 37u}) {
    auto objects = sampleObjects(n, uint32_t(n + 1));
    EXPECT_EQ(decodeBounds(encodeBounds(objects), "b.bin"), objects) << n;
  }
}

TEST(BoundsFormat, PayloadLayoutMatchesHandEncoding) {
  auto objects = sampleObjects(3, 5);
  Bytes f = encodeBounds(objects);
  EXPECT_EQ(std::string(f.begin(), f.begin() + 8), "DMMRBNDS");
  EXPECT_EQ(payloadOf(f), handBounds(objects));
  EXPECT_EQ(payloadOf(f).size(), 4 + 3 * kBoundsRecord);
}

TEST(BoundsFormat, RejectsWrongMagic) {
  Bytes f = encodeBounds(sampleObjects(1, 1));
  f[0] ^= 1;
  EXPECT_DMMR_ERROR(decodeBounds(f, "dir/bounds.bin"), "dir/bounds.bin", "magic");
  EXPECT_DMMR_ERROR(decodeBounds(encodeOccluders({1}), "o.bin"), "o.bin", "magic");
}

TEST(BoundsFormat, RejectsUnknownVersion) {
  Bytes f = encodeBounds(sampleObjects(1, 1));
  f[8] = 2;
  recrc(f);
  EXPECT_DMMR_ERROR(decodeBounds(f, "dir/bounds.bin"), "dir/bounds.bin", "version 2");
}

TEST(BoundsFormat, RejectsEveryTruncation) {
  expectEveryTruncationThrows(encodeBounds(sampleObjects(2, 3)), decodeBounds);
}

TEST(BoundsFormat, RejectsTrailingBytes) {
  Bytes f = encodeBounds(sampleObjects(2, 3));
  Bytes longer = f;
  longer.push_back(0);
  EXPECT_DMMR_ERROR(decodeBounds(longer, "t.bin"), "t.bin", "trailing");
  Bytes p = payloadOf(f);
  p.push_back(7);
  EXPECT_DMMR_ERROR(decodeBounds(withPayload(f, p), "t.bin"), "t.bin", "trailing");
}

TEST(BoundsFormat, RejectsChecksumMismatch) {
  Bytes f = encodeBounds(sampleObjects(2, 3));
  f[40] ^= 4;
  EXPECT_DMMR_ERROR(decodeBounds(f, "c.bin"), "c.bin", "checksum");
}

TEST(BoundsFormat, RejectsNonFiniteTransform) {
  for (double bad : {kNaN, kInf, -kInf}) {
    auto objects = sampleObjects(2, 4);
    objects[1].transform.at(2, 3) = bad;
    EXPECT_DMMR_ERROR(decodeBounds(encodeBounds(objects), "x.bin"), "x.bin", "object 1");
  }
}

TEST(BoundsFormat, RejectsBadSphereRadius) {
  for (double bad : {-1.0, -1e-300, kNaN, kInf}) {
    auto objects = sampleObjects(2, 4);
    objects[1].sphere.radius = bad;
    EXPECT_DMMR_ERROR(decodeBounds(encodeBounds(objects), "r.bin"), "r.bin", "radius");
  }
}

TEST(BoundsFormat, RejectsNonFiniteSphereCentre) {
  auto objects = sampleObjects(1, 4);
  objects[0].sphere.center.y = kNaN;
  EXPECT_DMMR_ERROR(decodeBounds(encodeBounds(objects), "s.bin"), "s.bin", "not finite");
}

TEST(BoundsFormat, RejectsBoxMinGreaterThanMax) {
  auto objects = sampleObjects(1, 4);
  objects[0].box.lo.z = objects[0].box.hi.z + 1;
  EXPECT_DMMR_ERROR(decodeBounds(encodeBounds(objects), "m.bin"), "m.bin", "min greater");
}

TEST(BoundsFormat, RejectsNonFiniteBox) {
  auto objects = sampleObjects(1, 4);
  objects[0].box = Box3d{};  // empty box: +inf .. -inf
  EXPECT_DMMR_ERROR(decodeBounds(encodeBounds(objects), "e.bin"), "e.bin", "not finite");
}

TEST(BoundsFormat, RejectsVolumeKindOtherThan0Or1) {
  Bytes f = encodeBounds(sampleObjects(2, 4));
  Bytes bad = patched(f, 4 + kBoundsRecord + 180, {2});
  EXPECT_DMMR_ERROR(decodeBounds(bad, "v.bin"), "v.bin", "volume kind");
  EXPECT_NO_THROW(decodeBounds(patched(f, 4 + kBoundsRecord + 180, {1}), "v.bin"));
}

TEST(BoundsFormat, RejectsHostileObjectCountWithoutAllocating) {
  Bytes f = encodeBounds(sampleObjects(1, 4));
  expectFailsWithoutHugeAllocation(patched(f, 0, {0xFF, 0xFF, 0xFF, 0xFF}), decodeBounds);
  expectFailsWithoutHugeAllocation(patched(f, 0, {2, 0, 0, 0}), decodeBounds);
}

// ---- skeleton ----------------------------------------------------------------------

SkeletonNode node(NodeKind kind, uint32_t parent, uint32_t end, uint32_t object = kNone,
                  std::string name = "") {
  SkeletonNode n;
  n.kind = kind;
  n.parent = parent;
  n.end = end;
  n.object = object;
  n.name = std::move(name);
  return n;
}

// root(0) { xf(1) { a(2) b(3) } g(4) { c(5) } }
std::vector<SkeletonNode> sampleSkeleton() {
  std::vector<SkeletonNode> s = {
      node(NodeKind::Group, kNone, 6, kNone, "root"),
      node(NodeKind::Transform, 0, 4, kNone, "xf"),
      node(NodeKind::Object, 1, 3, 0, "a"),
      node(NodeKind::Object, 1, 4, 1),
      node(NodeKind::Group, 0, 6, kNone, "g\xc3\xa9"),
      node(NodeKind::Object, 4, 6, 2, std::string("nul\0inside", 10)),
  };
  s[0].box = {{-1, -2, -3}, {4, 5, 6}};
  s[2].box = {{0, 0, 0}, {0, 0, 0}};
  s[5].box = {{-1, -2, -3}, {-1, 5, 6}};
  return s;
}

Bytes handSkeleton(const std::vector<SkeletonNode>& nodes) {
  Hand h;
  h.u32(uint32_t(nodes.size()));
  for (const auto& n : nodes) {
    h.u8(uint8_t(n.kind));
    h.u32(n.parent);
    h.u32(n.end);
    h.u32(n.object);
    h.u8(n.box.valid());
    if (n.box.valid()) {
      h.vec(n.box.lo);
      h.vec(n.box.hi);
    }
    h.str(n.name);
  }
  return h.b;
}

auto decodeSkel = [](const Bytes& f, const std::string& p) { return decodeSkeleton(f, p); };

TEST(SkeletonFormat, RoundTrip) {
  auto s = sampleSkeleton();
  EXPECT_EQ(decodeSkeleton(encodeSkeleton(s), "k.bin"), s);
  std::vector<SkeletonNode> single = {node(NodeKind::Object, kNone, 1, 7)};
  EXPECT_EQ(decodeSkeleton(encodeSkeleton(single), "k.bin"), single);
  // A deep chain: each group holds the next.
  std::vector<SkeletonNode> chain;
  for (uint32_t i = 0; i < 1000; ++i)
    chain.push_back(node(NodeKind::Group, i == 0 ? kNone : i - 1, 1001));
  chain.push_back(node(NodeKind::Object, 999, 1001, 0));
  EXPECT_EQ(decodeSkeleton(encodeSkeleton(chain), "k.bin"), chain);
}

TEST(SkeletonFormat, PayloadLayoutMatchesHandEncoding) {
  auto s = sampleSkeleton();
  Bytes f = encodeSkeleton(s);
  EXPECT_EQ(std::string(f.begin(), f.begin() + 8), "DMMRSKEL");
  EXPECT_EQ(payloadOf(f), handSkeleton(s));
}

TEST(SkeletonFormat, RejectsWrongMagic) {
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeBounds({}), "k.bin"), "k.bin", "magic");
}

TEST(SkeletonFormat, RejectsUnknownVersion) {
  Bytes f = encodeSkeleton(sampleSkeleton());
  f[9] = 1;  // version 257
  recrc(f);
  EXPECT_DMMR_ERROR(decodeSkeleton(f, "k.bin"), "k.bin", "version 257");
}

TEST(SkeletonFormat, RejectsEveryTruncation) {
  expectEveryTruncationThrows(encodeSkeleton(sampleSkeleton()), decodeSkel);
}

TEST(SkeletonFormat, RejectsTrailingBytes) {
  Bytes f = encodeSkeleton(sampleSkeleton());
  Bytes p = payloadOf(f);
  p.push_back(0);
  EXPECT_DMMR_ERROR(decodeSkeleton(withPayload(f, p), "k.bin"), "k.bin", "trailing");
  f.push_back(0);
  EXPECT_DMMR_ERROR(decodeSkeleton(f, "k.bin"), "k.bin", "trailing");
}

TEST(SkeletonFormat, RejectsChecksumMismatch) {
  Bytes f = encodeSkeleton(sampleSkeleton());
  f[f.size() - 6] ^= 0x80;
  EXPECT_DMMR_ERROR(decodeSkeleton(f, "k.bin"), "k.bin", "checksum");
}

TEST(SkeletonFormat, RejectsNoNodes) {
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton({}), "k.bin"), "k.bin", "no nodes");
}

TEST(SkeletonFormat, RejectsUnknownNodeKind) {
  Bytes f = encodeSkeleton({node(NodeKind::Group, kNone, 1)});
  EXPECT_DMMR_ERROR(decodeSkeleton(patched(f, 4, {3}), "k.bin"), "k.bin", "unknown kind 3");
}

TEST(SkeletonFormat, RejectsBoxFlagOtherThan0Or1) {
  Bytes f = encodeSkeleton({node(NodeKind::Group, kNone, 1)});
  EXPECT_DMMR_ERROR(decodeSkeleton(patched(f, 4 + 13, {2}), "k.bin"), "k.bin", "box flag");
}

TEST(SkeletonFormat, RejectsNonFiniteOrInvertedNodeBox) {
  auto s = sampleSkeleton();
  s[4].box = {{0, 0, 0}, {1, kInf, 1}};
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "not finite");
  s[4].box = {{0, 0, 2}, {1, 1, 1}};  // invalid: encoded without a box, decodes as empty
  auto d = decodeSkeleton(encodeSkeleton(s), "k.bin");
  EXPECT_FALSE(d[4].box.valid());
  Bytes f = encodeSkeleton({node(NodeKind::Group, kNone, 1)});
  Hand h;
  h.u32(1);
  h.u8(0);
  h.u32(kNone);
  h.u32(1);
  h.u32(kNone);
  h.u8(1);
  h.vec({0, 0, 2});
  h.vec({1, 1, 1});
  h.str("");
  EXPECT_DMMR_ERROR(decodeSkeleton(withPayload(f, h.b), "k.bin"), "k.bin", "min greater");
}

TEST(SkeletonFormat, RejectsRootWithParent) {
  std::vector<SkeletonNode> s = {node(NodeKind::Group, 0, 1)};
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 0");
}

TEST(SkeletonFormat, RejectsParentNotBeforeNode) {
  for (uint32_t parent : {2u, 3u, kNone}) {
    auto s = sampleSkeleton();
    s[2].parent = parent;
    EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 2");
  }
}

TEST(SkeletonFormat, RejectsParentNotEnclosing) {
  auto s = sampleSkeleton();
  s[5].parent = 1;  // node 1's subtree ends at 4
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 5");
  s = sampleSkeleton();
  s[4].parent = 3;  // an object node: its subtree ends at 4
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 4");
}

// Regression: node 3 lies inside node 1's subtree (1..4) but named the root as
// its parent; the parent must be the innermost enclosing subtree.
TEST(SkeletonFormat, RejectsParentThatIsNotTheInnermostEnclosingNode) {
  auto s = sampleSkeleton();
  s[3].parent = 0;
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 3");
  s = sampleSkeleton();
  s[5].parent = 0;  // inside g(4)
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 5");
}

TEST(SkeletonFormat, RejectsNodeOutsideTheRootSubtree) {
  std::vector<SkeletonNode> s = {node(NodeKind::Group, kNone, 2), node(NodeKind::Object, 0, 2, 0),
                                 node(NodeKind::Object, 0, 3, 1)};
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 2");
  s[2].parent = kNone;  // a second root
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 2");
}

TEST(SkeletonFormat, RejectsBadSubtreeEnd) {
  struct Case {
    size_t node;
    uint32_t end;
  };
  // end <= index, end > count, end beyond the parent's end.
  for (Case c : {Case{1, 1}, Case{1, 0}, Case{4, 3}, Case{0, 7}, Case{4, 7}}) {
    auto s = sampleSkeleton();
    s[c.node].end = c.end;
    EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin",
                      "node " + std::to_string(c.node));
  }
  std::vector<SkeletonNode> s = {node(NodeKind::Group, kNone, 4), node(NodeKind::Group, 0, 3),
                                 node(NodeKind::Group, 1, 4), node(NodeKind::Object, 2, 4, 0)};
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 2");
}

// Regression: node 1's subtree (1..5) would cross g(4)'s (4..6); node 4 names
// the root as its parent although it lies inside node 1's range.
TEST(SkeletonFormat, RejectsCrossingSubtrees) {
  auto s = sampleSkeleton();
  s[1].end = 5;
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 4");
}

TEST(SkeletonFormat, RejectsObjectNodeWithChildren) {
  std::vector<SkeletonNode> s = {node(NodeKind::Group, kNone, 3), node(NodeKind::Object, 0, 3, 0),
                                 node(NodeKind::Object, 1, 3, 1)};
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 1");
}

TEST(SkeletonFormat, RejectsObjectIndexOnNonObjectNode) {
  auto s = sampleSkeleton();
  s[1].object = 0;
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 1");
}

TEST(SkeletonFormat, RejectsObjectNodeWithoutObjectIndex) {
  auto s = sampleSkeleton();
  s[3].object = kNone;
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "node 3");
}

TEST(SkeletonFormat, RejectsOverlongName) {
  auto s = sampleSkeleton();
  s[2].name = std::string(4096, 'n');
  EXPECT_EQ(decodeSkeleton(encodeSkeleton(s), "k.bin"), s);
  s[2].name += "n";
  EXPECT_DMMR_ERROR(decodeSkeleton(encodeSkeleton(s), "k.bin"), "k.bin", "too large");
}

TEST(SkeletonFormat, RejectsHostileCountsWithoutAllocating) {
  Bytes f = encodeSkeleton({node(NodeKind::Group, kNone, 1, kNone, "abc")});
  expectFailsWithoutHugeAllocation(patched(f, 0, {0xFF, 0xFF, 0xFF, 0xFF}), decodeSkel);
  expectFailsWithoutHugeAllocation(patched(f, 4 + 14, {0xFF, 0xFF, 0xFF, 0x7F}), decodeSkel);
}

// ---- occluders -------------------------------------------------------------------

auto decodeOccl = [](const Bytes& f, const std::string& p) { return decodeOccluders(f, p); };

TEST(OccludersFormat, RoundTrip) {
  for (const std::vector<uint32_t>& o :
       {std::vector<uint32_t>{}, {0}, {1, 2, 3}, {5, 900, 0xFFFFFFFEu, 0xFFFFFFFFu}})
    EXPECT_EQ(decodeOccluders(encodeOccluders(o), "o.bin"), o);
}

TEST(OccludersFormat, PayloadLayoutMatchesHandEncoding) {
  Bytes f = encodeOccluders({3, 0x01020304});
  EXPECT_EQ(std::string(f.begin(), f.begin() + 8), "DMMROCCL");
  EXPECT_EQ(payloadOf(f), (Bytes{2, 0, 0, 0, 3, 0, 0, 0, 4, 3, 2, 1}));
}

TEST(OccludersFormat, RejectsWrongMagic) {
  EXPECT_DMMR_ERROR(decodeOccluders(encodeSkeleton(sampleSkeleton()), "o.bin"), "o.bin", "magic");
}

TEST(OccludersFormat, RejectsUnknownVersion) {
  Bytes f = encodeOccluders({1});
  f[8] = 0;
  recrc(f);
  EXPECT_DMMR_ERROR(decodeOccluders(f, "o.bin"), "o.bin", "version 0");
}

TEST(OccludersFormat, RejectsEveryTruncation) {
  expectEveryTruncationThrows(encodeOccluders({1, 5, 9}), decodeOccl);
}

TEST(OccludersFormat, RejectsTrailingBytes) {
  Bytes f = encodeOccluders({1, 5});
  EXPECT_DMMR_ERROR(decodeOccluders(patched(f, 0, {1}), "o.bin"), "o.bin", "trailing");
  f.push_back(1);
  EXPECT_DMMR_ERROR(decodeOccluders(f, "o.bin"), "o.bin", "trailing");
}

TEST(OccludersFormat, RejectsChecksumMismatch) {
  Bytes f = encodeOccluders({1, 5});
  f[24] ^= 1;
  EXPECT_DMMR_ERROR(decodeOccluders(f, "o.bin"), "o.bin", "checksum");
}

TEST(OccludersFormat, RejectsIndicesNotStrictlyIncreasing) {
  EXPECT_DMMR_ERROR(decodeOccluders(encodeOccluders({1, 4, 4}), "o.bin"), "o.bin", "entry 2");
  EXPECT_DMMR_ERROR(decodeOccluders(encodeOccluders({7, 3}), "o.bin"), "o.bin", "entry 1");
}

TEST(OccludersFormat, RejectsHostileCountWithoutAllocating) {
  Bytes f = encodeOccluders({1, 2});
  expectFailsWithoutHugeAllocation(patched(f, 0, {0xFF, 0xFF, 0xFF, 0xFF}), decodeOccl);
}

// ---- part boxes --------------------------------------------------------------------

auto decodePartsFile = [](const Bytes& f, const std::string& p) { return decodeParts(f, p); };

std::vector<GeometryParts> sampleParts() {
  GeometryParts a;
  a.box = {{-1, -2, -3}, {1, 2, 3}};
  a.parts = {{0, 0, 0, 255, 255, 255}, {10, 20, 30, 40, 50, 60}};
  a.triangles = {3, 4, 0, 5};  // two submeshes: 3 + 4 and 0 + 5 triangles
  GeometryParts b;             // no parts (a small mesh): its box is the test
  b.box = {{0.5, 0.5, 0.5}, {0.5, 0.75, 1}};
  GeometryParts c;  // parts, not ordered (preprocessed with --part-order off)
  c.box = {{0, 0, 0}, {1, 1, 1}};
  c.parts = {{0, 0, 0, 1, 1, 1}};
  return {a, b, c};
}

TEST(PartsFormat, RoundTrip) {
  EXPECT_EQ(decodeParts(encodeParts({}), "p.bin"), std::vector<GeometryParts>{});
  EXPECT_EQ(decodeParts(encodeParts(sampleParts()), "p.bin"), sampleParts());
  GeometryParts full;
  full.box = {{0, 0, 0}, {1, 1, 1}};
  full.parts.assign(kMaxParts, {1, 2, 3, 4, 5, 6});
  EXPECT_EQ(decodeParts(encodeParts({full}), "p.bin"), std::vector<GeometryParts>{full});
}

TEST(PartsFormat, PayloadLayoutMatchesHandEncoding) {
  GeometryParts g;
  g.box = {{1, 0, 0}, {2, 0, 0}};
  g.parts = {{1, 2, 3, 4, 5, 6}};
  Bytes f = encodeParts({g});
  EXPECT_EQ(std::string(f.begin(), f.begin() + 8), "DMMRPART");
  EXPECT_EQ(f[8], 2);  // version
  // Count, box as f32 (1.0f = 0x3F800000, 2.0f = 0x40000000), part count,
  // part, submesh count (u16; 0: not ordered).
  const Bytes head = {1, 0, 0,    0,                             // geometry count
                      0, 0, 0x80, 0x3F, 0, 0, 0, 0, 0, 0, 0, 0,  // lo
                      0, 0, 0,    0x40, 0, 0, 0, 0, 0, 0, 0, 0,  // hi
                      1, 1, 2,    3,    4, 5, 6};
  Bytes unordered = head;
  unordered.insert(unordered.end(), {0, 0});
  EXPECT_EQ(payloadOf(f), unordered);
  // Ordered, one submesh: then one u32 per part, its triangles (258).
  g.triangles = {258};
  Bytes ordered = head;
  ordered.insert(ordered.end(), {1, 0, 2, 1, 0, 0});
  EXPECT_EQ(payloadOf(encodeParts({g})), ordered);
}

TEST(PartsFormat, ReadsVersion1AsPartsNotOrdered) {
  // Version 1 had no submesh count or part triangles.
  GeometryParts g;
  g.box = {{1, 0, 0}, {2, 0, 0}};
  g.parts = {{1, 2, 3, 4, 5, 6}};
  Bytes f = encodeParts({g});
  Bytes payload = payloadOf(f);
  payload.resize(payload.size() - 2);
  Bytes v1 = wrapContainer(FileKind{"DMMRPART", 1, "part boxes"}, payload);
  std::vector<GeometryParts> read = decodeParts(v1, "p.bin");
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0], g);
  EXPECT_FALSE(read[0].ordered());
}

TEST(PartsFormat, RejectsWrongMagicAndUnknownVersion) {
  EXPECT_DMMR_ERROR(decodeParts(encodeOccluders({1}), "p.bin"), "p.bin", "magic");
  Bytes f = encodeParts(sampleParts());
  f[8] = 3;
  recrc(f);
  EXPECT_DMMR_ERROR(decodeParts(f, "p.bin"), "p.bin",
                    "version 3 (this build reads version 1 to 2)");
  f[8] = 0;
  recrc(f);
  EXPECT_DMMR_ERROR(decodeParts(f, "p.bin"), "p.bin", "version 0");
}

TEST(PartsFormat, RejectsEveryTruncation) {
  expectEveryTruncationThrows(encodeParts(sampleParts()), decodePartsFile);
}

TEST(PartsFormat, RejectsTrailingBytes) {
  Bytes f = encodeParts(sampleParts());
  EXPECT_DMMR_ERROR(decodeParts(patched(f, 0, {1}), "p.bin"), "p.bin", "trailing");
  f.push_back(0);
  EXPECT_DMMR_ERROR(decodeParts(f, "p.bin"), "p.bin", "trailing");
}

TEST(PartsFormat, RejectsChecksumMismatch) {
  Bytes f = encodeParts(sampleParts());
  f[24] ^= 1;
  EXPECT_DMMR_ERROR(decodeParts(f, "p.bin"), "p.bin", "checksum");
}

TEST(PartsFormat, RejectsMoreThanMaxParts) {
  // The first geometry's part count sits after the count and its box.
  Bytes f = encodeParts(sampleParts());
  EXPECT_DMMR_ERROR(decodeParts(patched(f, 4 + 24, {uint8_t(kMaxParts + 1)}), "p.bin"), "p.bin",
                    "geometry 0: 9 parts");
}

TEST(PartsFormat, RejectsAPartWithMinAboveMax) {
  auto g = sampleParts();
  g[0].parts[1] = {10, 70, 30, 40, 50, 60};
  EXPECT_DMMR_ERROR(decodeParts(encodeParts(g), "p.bin"), "p.bin", "geometry 0: a part");
}

TEST(PartsFormat, RejectsBadBoxes) {
  auto g = sampleParts();
  g[1].box = {{0, 1, 0}, {1, 0, 1}};
  EXPECT_DMMR_ERROR(decodeParts(encodeParts(g), "p.bin"), "p.bin", "geometry 1: box has min");
  Bytes f = encodeParts(sampleParts());  // geometry 0's lo.x a NaN (0x7FC00000)
  EXPECT_DMMR_ERROR(decodeParts(patched(f, 4, {0, 0, 0xC0, 0x7F}), "p.bin"), "p.bin",
                    "geometry 0: box not finite");
}

TEST(PartsFormat, RejectsHostileCountWithoutAllocating) {
  Bytes f = encodeParts(sampleParts());
  expectFailsWithoutHugeAllocation(patched(f, 0, {0xFF, 0xFF, 0xFF, 0xFF}), decodePartsFile);
}

TEST(PartsFormat, RejectsASubmeshCountPastTheFile) {
  // Geometry 0's submesh count follows its box, part count and 2 parts.
  Bytes f = encodeParts(sampleParts());
  EXPECT_DMMR_ERROR(decodeParts(patched(f, 4 + 24 + 1 + 12, {0xFF, 0xFF}), "p.bin"), "p.bin",
                    "geometry 0's part triangles exceed the file");
}

// Quantised parts decode to boxes holding the originals and inside the
// geometry's box: random boxes near and far from the origin, flat and
// point-like ones, parts touching the box's faces.
TEST(PartsFormat, QuantizedPartsHoldTheirOriginals) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 2000; ++trial) {
    double offset = trial % 3 == 0 ? 0 : (trial % 3 == 1 ? 1e6 : -3e7);
    double scale = std::pow(10.0, int(rng() % 9) - 4);
    Box3d box;
    for (int a = 0; a < 3; ++a) {
      float lo = float(offset + (u(rng) - 0.5) * scale);
      float ext = (rng() % 5 == 0) ? 0.f : float(u(rng) * scale);  // flat on some axes
      box.lo[a] = lo;
      box.hi[a] = double(lo + ext);
    }
    std::vector<Box3d> parts(rng() % (kMaxParts + 1));
    for (Box3d& p : parts)
      for (int a = 0; a < 3; ++a) {
        double x = box.lo[a] + (box.hi[a] - box.lo[a]) * u(rng);
        double y = box.lo[a] + (box.hi[a] - box.lo[a]) * u(rng);
        if (rng() % 4 == 0) x = box.lo[a];
        if (rng() % 4 == 0) y = box.hi[a];
        p.lo[a] = std::min(x, y);
        p.hi[a] = std::max(x, y);
      }
    GeometryParts q = quantizeParts(box, parts);
    ASSERT_EQ(decodeParts(encodeParts({q}), "p.bin"), std::vector<GeometryParts>{q});
    ASSERT_EQ(q.parts.size(), parts.size());
    for (size_t k = 0; k < parts.size(); ++k) {
      Box3d d = partBox(q, k);
      for (int a = 0; a < 3; ++a) {
        ASSERT_LE(d.lo[a], parts[k].lo[a]) << "trial " << trial << " part " << k << " axis " << a;
        ASSERT_GE(d.hi[a], parts[k].hi[a]) << "trial " << trial << " part " << k << " axis " << a;
        ASSERT_GE(d.lo[a], box.lo[a]);
        ASSERT_LE(d.hi[a], box.hi[a]);
      }
    }
  }
}

TEST(PartsFormat, QuantizationKeepsPartsSmall) {
  // A part an eighth of the box decodes to within 1/255 of it on each side.
  Box3d box{{0, 0, 0}, {8, 8, 8}};
  Box3d part{{1, 2, 3}, {2, 3, 4}};
  Box3d d = partBox(quantizeParts(box, {part}), 0);
  for (int a = 0; a < 3; ++a) {
    EXPECT_GT(d.lo[a], part.lo[a] - 8.0 / 255 - 1e-12);
    EXPECT_LT(d.hi[a], part.hi[a] + 8.0 / 255 + 1e-12);
  }
}

// ---- geometry ----------------------------------------------------------------------

struct Attribs {
  bool normals, colors, texcoords;
};

GeometryData sampleGeometry(size_t nv, size_t triangles, Attribs a, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1000, 1000), t(0, 1);
  GeometryData g;
  for (size_t i = 0; i < nv * 3; ++i) g.positions.push_back(u(rng));
  if (a.normals)
    for (size_t i = 0; i < nv * 3; ++i) g.normals.push_back(t(rng));
  if (a.colors)
    for (size_t i = 0; i < nv * 4; ++i) g.colors.push_back(uint8_t(rng()));
  if (a.texcoords)
    for (size_t i = 0; i < nv * 2; ++i) g.texcoords.push_back(t(rng) * 4 - 2);
  if (nv > 0) {
    for (size_t i = 0; i < triangles * 3; ++i) g.indices.push_back(uint32_t(rng() % nv));
    g.indices[0] = uint32_t(nv - 1);  // the largest index occurs
  }
  // Submeshes cover the triangles in up to three ranges, plus an empty one.
  uint32_t ni = uint32_t(g.indices.size());
  uint32_t cut = ni / 3 / 2 * 3;
  SubMesh s0, s1, s2;
  s0.first_index = 0;
  s0.index_count = cut;
  s0.texture = 3;
  s1.first_index = cut;
  s1.index_count = ni - cut;
  s1.diffuse[0] = 0.25f, s1.diffuse[3] = 0.5f;
  s2.first_index = ni;
  s2.index_count = 0;
  s2.texture = 0;
  g.submeshes = {s0, s1, s2};
  return g;
}

Bytes handGeometry(const GeometryData& g) {
  size_t nv = g.positions.size() / 3;
  bool small = nv <= 65536;
  Hand h;
  h.u8(0);
  h.u8((g.normals.empty() ? 0 : 1) | (g.colors.empty() ? 0 : 2) | (g.texcoords.empty() ? 0 : 4) |
       (small ? 8 : 0));
  h.u32(uint32_t(nv));
  h.u32(uint32_t(g.indices.size()));
  h.u32(uint32_t(g.submeshes.size()));
  for (const auto& s : g.submeshes) {
    h.u32(s.first_index);
    h.u32(s.index_count);
    for (float d : s.diffuse) h.f32(d);
    h.i32(s.texture);
  }
  for (float v : g.positions) h.f32(v);
  for (float v : g.normals) h.f32(v);
  for (uint8_t v : g.colors) h.u8(v);
  for (float v : g.texcoords) h.f32(v);
  for (uint32_t i : g.indices) small ? h.u16(uint16_t(i)) : h.u32(i);
  return h.b;
}

// Payload offsets of the fixed header fields.
constexpr size_t kGeomFlags = 1, kGeomVertexCount = 2, kGeomIndexCount = 6, kGeomSubmeshCount = 10;

auto decodeGeom = [](const Bytes& f, const std::string& p) { return decodeGeometry(f, p); };

TEST(GeometryFormat, RoundTripWithEveryAttributeCombination) {
  for (int mask = 0; mask < 8; ++mask) {
    Attribs a{bool(mask & 1), bool(mask & 2), bool(mask & 4)};
    GeometryData g = sampleGeometry(50, 40, a, uint32_t(mask + 10));
    EXPECT_EQ(decodeGeometry(encodeGeometry(g), "g.bin"), g) << "attribute mask " << mask;
  }
}

TEST(GeometryFormat, RoundTripEmpty) {
  GeometryData g;
  EXPECT_EQ(decodeGeometry(encodeGeometry(g), "g.bin"), g);
  g.positions = {1, 2, 3};  // a vertex but no triangles
  EXPECT_EQ(decodeGeometry(encodeGeometry(g), "g.bin"), g);
}

TEST(GeometryFormat, RoundTripWith32BitIndices) {
  for (size_t nv : {size_t(65537), size_t(70000)}) {
    GeometryData g = sampleGeometry(nv, 30000, {true, true, true}, 77);
    g.indices[1] = 65536;  // needs more than 16 bits
    Bytes f = encodeGeometry(g);
    EXPECT_EQ(payloadOf(f)[kGeomFlags] & 8, 0) << "16-bit flag set for " << nv << " vertices";
    EXPECT_EQ(decodeGeometry(f, "g.bin"), g);
  }
}

TEST(GeometryFormat, SixteenBitIndicesUpTo65536Vertices) {
  GeometryData g = sampleGeometry(65536, 1000, {false, false, false}, 78);
  g.indices[1] = 65535;
  Bytes f = encodeGeometry(g);
  // 20-byte header + 4 checksum; payload: 14 fixed, 28 per submesh, 12 per
  // vertex and 2 per index.
  EXPECT_EQ(f.size(), 24 + 14 + 3 * 28 + 65536 * 12 + 3000 * 2);
  EXPECT_EQ(decodeGeometry(f, "g.bin"), g);
}

TEST(GeometryFormat, PayloadLayoutMatchesHandEncoding) {
  for (size_t nv : {size_t(7), size_t(66000)}) {
    GeometryData g = sampleGeometry(nv, 9, {true, true, true}, 79);
    Bytes f = encodeGeometry(g);
    EXPECT_EQ(std::string(f.begin(), f.begin() + 8), "DMMRGEOM");
    EXPECT_EQ(payloadOf(f), handGeometry(g)) << nv;
  }
  GeometryData g = sampleGeometry(7, 9, {false, true, false}, 80);
  EXPECT_EQ(payloadOf(encodeGeometry(g)), handGeometry(g));
}

TEST(GeometryFormat, Decodes32BitIndicesForFewVertices) {
  // Readers accept either index width when it fits.
  GeometryData g = sampleGeometry(10, 4, {false, false, false}, 81);
  Bytes f = encodeGeometry(g);
  Hand h;
  Bytes p = handGeometry(g);
  p[kGeomFlags] &= uint8_t(~8);
  size_t idx_at = p.size() - g.indices.size() * 2;
  p.resize(idx_at);
  h.b = p;
  for (uint32_t i : g.indices) h.u32(i);
  EXPECT_EQ(decodeGeometry(withPayload(f, h.b), "g.bin"), g);
}

TEST(GeometryFormat, RejectsWrongMagic) {
  EXPECT_DMMR_ERROR(decodeGeometry(encodeTexture({1, 1, true, true, {1, 2, 3, 4}}), "g.bin"),
                    "g.bin", "magic");
}

TEST(GeometryFormat, RejectsUnknownVersion) {
  Bytes f = encodeGeometry(sampleGeometry(5, 2, {}, 1));
  f[11] = 0x80;
  recrc(f);
  EXPECT_DMMR_ERROR(decodeGeometry(f, "g.bin"), "g.bin", "version");
}

TEST(GeometryFormat, RejectsEveryTruncation) {
  expectEveryTruncationThrows(encodeGeometry(sampleGeometry(5, 3, {true, true, true}, 2)),
                              decodeGeom);
}

TEST(GeometryFormat, RejectsTrailingBytes) {
  Bytes f = encodeGeometry(sampleGeometry(5, 3, {}, 2));
  Bytes p = payloadOf(f);
  p.push_back(0);
  p.push_back(0);
  EXPECT_DMMR_ERROR(decodeGeometry(withPayload(f, p), "g.bin"), "g.bin", "trailing");
  f.push_back(0);
  EXPECT_DMMR_ERROR(decodeGeometry(f, "g.bin"), "g.bin", "trailing");
}

TEST(GeometryFormat, RejectsChecksumMismatch) {
  Bytes f = encodeGeometry(sampleGeometry(5, 3, {}, 2));
  f[f.size() / 2] ^= 0x20;
  EXPECT_DMMR_ERROR(decodeGeometry(f, "g.bin"), "g.bin", "checksum");
}

TEST(GeometryFormat, RejectsUnknownEncoding) {
  Bytes f = encodeGeometry(sampleGeometry(5, 3, {}, 2));
  EXPECT_DMMR_ERROR(decodeGeometry(patched(f, 0, {4}), "g.bin"), "g.bin", "encoding 4");
}

TEST(GeometryFormat, RejectsUnknownFlags) {
  Bytes f = encodeGeometry(sampleGeometry(5, 3, {}, 2));
  for (uint8_t bit : {32, 64, 128})  // 16 marks an occluder level of detail
    EXPECT_DMMR_ERROR(decodeGeometry(patched(f, kGeomFlags, {uint8_t(8 | bit)}), "g.bin"), "g.bin",
                      "flags");
}

TEST(GeometryFormat, LevelOfDetailRoundTrips) {
  GeometryData g = sampleGeometry(5, 3, {}, 2);
  g.lod_indices = {0, 1, 2};
  EXPECT_EQ(decodeGeometry(encodeGeometry(g), "g.bin"), g);
}

TEST(GeometryFormat, RejectsLevelOfDetailIndexOutOfRange) {
  GeometryData g = sampleGeometry(5, 3, {}, 2);
  g.lod_indices = {0, 1, 4};
  Bytes f = encodeGeometry(g);
  g.lod_indices = {0, 1, 5};  // vertex 5 does not exist
  Bytes bad = encodeGeometry(g);
  EXPECT_NO_THROW(decodeGeometry(f, "g.bin"));
  EXPECT_DMMR_ERROR(decodeGeometry(bad, "g.bin"), "g.bin", "lod indices");
}

TEST(GeometryFormat, RejectsMissingLevelOfDetailAfterItsFlag) {
  Bytes f = encodeGeometry(sampleGeometry(5, 3, {}, 2));
  EXPECT_DMMR_ERROR(decodeGeometry(patched(f, kGeomFlags, {uint8_t(8 | 16)}), "g.bin"), "g.bin",
                    "lod index count");
}

TEST(GeometryFormat, RejectsIndexOutOfRange) {
  for (size_t nv : {size_t(5), size_t(65537)}) {
    GeometryData g = sampleGeometry(nv, 3, {}, 3);
    g.indices[4] = uint32_t(nv);
    EXPECT_DMMR_ERROR(decodeGeometry(encodeGeometry(g), "g.bin"), "g.bin",
                      "index " + std::to_string(nv) + " out of range");
  }
  GeometryData none = sampleGeometry(0, 0, {}, 3);
  none.indices = {0, 0, 0};
  none.submeshes.clear();
  EXPECT_DMMR_ERROR(decodeGeometry(encodeGeometry(none), "g.bin"), "g.bin", "out of range");
}

TEST(GeometryFormat, RejectsIndexCountNotMultipleOf3) {
  GeometryData g = sampleGeometry(5, 3, {}, 4);
  g.submeshes.clear();
  g.indices.push_back(0);
  EXPECT_DMMR_ERROR(decodeGeometry(encodeGeometry(g), "g.bin"), "g.bin", "multiple of 3");
}

TEST(GeometryFormat, RejectsSubmeshRangeOutOfBounds) {
  GeometryData base = sampleGeometry(5, 4, {}, 5);  // 12 indices
  struct Case {
    uint32_t first, count;
  };
  for (Case c : {Case{0, 15}, Case{15, 0}, Case{12, 3}, Case{3, 0xFFFFFFFFu}, Case{1, 3},
                 Case{0, 4}, Case{0xFFFFFFFFu, 0}}) {
    GeometryData g = base;
    g.submeshes[1].first_index = c.first;
    g.submeshes[1].index_count = c.count;
    SCOPED_TRACE(std::to_string(c.first) + "+" + std::to_string(c.count));
    EXPECT_DMMR_ERROR(decodeGeometry(encodeGeometry(g), "g.bin"), "g.bin", "submesh 1");
  }
  GeometryData g = base;
  g.submeshes[1].first_index = 0;
  g.submeshes[1].index_count = 12;  // overlapping ranges are fine
  EXPECT_EQ(decodeGeometry(encodeGeometry(g), "g.bin"), g);
}

TEST(GeometryFormat, RejectsBadTextureIndex) {
  GeometryData g = sampleGeometry(5, 4, {}, 6);
  g.submeshes[2].texture = -2;
  EXPECT_DMMR_ERROR(decodeGeometry(encodeGeometry(g), "g.bin"), "g.bin", "submesh 2");
}

TEST(GeometryFormat, RejectsNonFiniteDiffuse) {
  GeometryData g = sampleGeometry(5, 4, {}, 6);
  g.submeshes[0].diffuse[2] = std::numeric_limits<float>::infinity();
  EXPECT_DMMR_ERROR(decodeGeometry(encodeGeometry(g), "g.bin"), "g.bin", "submesh 0");
}

TEST(GeometryFormat, RejectsNonFinitePosition) {
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                    -std::numeric_limits<float>::infinity()}) {
    GeometryData g = sampleGeometry(5, 4, {true, false, false}, 7);
    g.positions[13] = bad;
    EXPECT_DMMR_ERROR(decodeGeometry(encodeGeometry(g), "g.bin"), "g.bin", "positions");
  }
}

TEST(GeometryFormat, Rejects16BitIndicesWithTooManyVertices) {
  GeometryData g = sampleGeometry(65537, 1, {}, 8);
  g.submeshes.clear();
  Bytes f = encodeGeometry(g);
  Bytes bad = patched(f, kGeomFlags, {8});
  EXPECT_DMMR_ERROR(decodeGeometry(bad, "g.bin"), "g.bin", "16-bit");
}

TEST(GeometryFormat, RejectsHostileCountsWithoutAllocating) {
  Bytes f = encodeGeometry(sampleGeometry(2, 1, {true, true, true}, 9));
  Bytes p = payloadOf(f);
  auto with = [&](size_t at, uint32_t v, uint8_t flags) {
    Bytes q = p;
    for (int i = 0; i < 4; ++i) q[at + size_t(i)] = uint8_t(v >> (8 * i));
    q[kGeomFlags] = flags;
    return withPayload(f, q);
  };
  expectFailsWithoutHugeAllocation(with(kGeomVertexCount, 0xFFFFFFFFu, 7), decodeGeom);
  expectFailsWithoutHugeAllocation(with(kGeomVertexCount, 65536, 15), decodeGeom);
  expectFailsWithoutHugeAllocation(with(kGeomIndexCount, 0xFFFFFFFFu, 15), decodeGeom);
  expectFailsWithoutHugeAllocation(with(kGeomIndexCount, 0xFFFFFFFFu, 7), decodeGeom);
  expectFailsWithoutHugeAllocation(with(kGeomSubmeshCount, 0xFFFFFFFFu, 15), decodeGeom);
}

TEST(GeometryFormat, RejectsHostileCountsInEveryEncodingWithoutAllocating) {
  // The compact encodings bound their counts by the bytes present too: the
  // meshopt streams by what a stream of their size can decode to.
  for (Encoding e : kEncodings) {
    Bytes f = encodeGeometry(sampleGeometry(40, 30, {true, true, true}, 9), e);
    for (size_t at : {kGeomVertexCount, kGeomIndexCount})
      for (uint32_t v : {0xFFFFFFF0u, 3000000u}) {
        Bytes p = payloadOf(f);
        for (int i = 0; i < 4; ++i) p[at + size_t(i)] = uint8_t(v >> (8 * i));
        SCOPED_TRACE(std::string(encodingName(e)) + " field " + std::to_string(at));
        expectFailsWithoutHugeAllocation(withPayload(f, p), decodeGeom);
      }
  }
}

// ---- textures ----------------------------------------------------------------------

TextureData sampleTexture(uint32_t w, uint32_t h, uint32_t seed) {
  std::mt19937 rng(seed);
  TextureData t;
  t.width = w;
  t.height = h;
  t.repeat_s = rng() & 1;
  t.repeat_t = rng() & 1;
  t.rgba.resize(size_t(w) * h * 4);
  for (auto& b : t.rgba) b = uint8_t(rng());
  return t;
}

auto decodeTex = [](const Bytes& f, const std::string& p) { return decodeTexture(f, p); };

TEST(TextureFormat, RoundTrip) {
  for (uint32_t seed = 0; seed < 4; ++seed) {
    TextureData t = sampleTexture(3 + seed, 5, seed);
    t.repeat_s = seed & 1;
    t.repeat_t = seed & 2;
    EXPECT_EQ(decodeTexture(encodeTexture(t), "t.bin"), t);
  }
  TextureData wide = sampleTexture(16384, 1, 9);  // the largest side
  EXPECT_EQ(decodeTexture(encodeTexture(wide), "t.bin"), wide);
}

TEST(TextureFormat, PayloadLayoutMatchesHandEncoding) {
  TextureData t = sampleTexture(2, 3, 1);
  t.repeat_s = false;
  t.repeat_t = true;
  Hand h;
  h.u32(2);
  h.u32(3);
  h.u8(0);
  h.u8(1);
  h.b.insert(h.b.end(), t.rgba.begin(), t.rgba.end());
  Bytes f = encodeTexture(t);
  EXPECT_EQ(std::string(f.begin(), f.begin() + 8), "DMMRTEXR");
  EXPECT_EQ(payloadOf(f), h.b);
}

TEST(TextureFormat, RejectsWrongMagic) {
  EXPECT_DMMR_ERROR(decodeTexture(encodeGeometry({}), "t.bin"), "t.bin", "magic");
}

TEST(TextureFormat, RejectsUnknownVersion) {
  Bytes f = encodeTexture(sampleTexture(1, 1, 1));
  f[8] = 9;
  recrc(f);
  EXPECT_DMMR_ERROR(decodeTexture(f, "t.bin"), "t.bin", "version 9");
}

TEST(TextureFormat, RejectsEveryTruncation) {
  expectEveryTruncationThrows(encodeTexture(sampleTexture(2, 2, 1)), decodeTex);
}

TEST(TextureFormat, RejectsTrailingBytes) {
  Bytes f = encodeTexture(sampleTexture(2, 2, 1));
  Bytes p = payloadOf(f);
  p.push_back(0);
  EXPECT_DMMR_ERROR(decodeTexture(withPayload(f, p), "t.bin"), "t.bin", "trailing");
  f.push_back(0);
  EXPECT_DMMR_ERROR(decodeTexture(f, "t.bin"), "t.bin", "trailing");
}

TEST(TextureFormat, RejectsChecksumMismatch) {
  Bytes f = encodeTexture(sampleTexture(2, 2, 1));
  f[22] ^= 1;
  EXPECT_DMMR_ERROR(decodeTexture(f, "t.bin"), "t.bin", "checksum");
}

TEST(TextureFormat, RejectsZeroSize) {
  for (auto [w, h] : {std::pair{0u, 1u}, std::pair{1u, 0u}, std::pair{0u, 0u}}) {
    TextureData t = sampleTexture(w, h, 1);
    EXPECT_DMMR_ERROR(decodeTexture(encodeTexture(t), "t.bin"), "t.bin", "out of range");
  }
}

TEST(TextureFormat, RejectsTooLargeSize) {
  Bytes f = encodeTexture(sampleTexture(1, 1, 1));
  // 16385 x 1 and 1 x 16385, with a payload too short for either.
  EXPECT_DMMR_ERROR(decodeTexture(patched(f, 0, {0x01, 0x40, 0, 0}), "t.bin"), "t.bin", "16385x1");
  EXPECT_DMMR_ERROR(decodeTexture(patched(f, 4, {0x01, 0x40, 0, 0}), "t.bin"), "t.bin", "1x16385");
  TextureData tall = sampleTexture(1, 16385, 2);
  EXPECT_DMMR_ERROR(decodeTexture(encodeTexture(tall), "t.bin"), "t.bin", "out of range");
}

TEST(TextureFormat, RejectsRepeatFlagsOtherThan0Or1) {
  Bytes f = encodeTexture(sampleTexture(1, 1, 1));
  EXPECT_DMMR_ERROR(decodeTexture(patched(f, 8, {2}), "t.bin"), "t.bin", "repeat");
  EXPECT_DMMR_ERROR(decodeTexture(patched(f, 9, {255}), "t.bin"), "t.bin", "repeat");
}

TEST(TextureFormat, RejectsHostileSizeWithoutAllocating) {
  Bytes f = encodeTexture(sampleTexture(1, 1, 1));
  expectFailsWithoutHugeAllocation(patched(f, 0, {0, 0x40, 0, 0, 0, 0x40, 0, 0}), decodeTex);
}

// ---- manifest ----------------------------------------------------------------------

Manifest sampleManifest() {
  Manifest m;
  m.objects = 12;
  m.geometries = 2;
  m.textures = 1;
  m.occluders = 3;
  m.triangles = 1ull << 40;
  m.unique_triangles = 123456789012ull;
  m.geometry_bytes = 0xFFFFFFFFFFFFFFFFull;
  m.bounds = {{-1.5, 0.1, -1e300}, {2.75, 0.30000000000000004, 1e300}};
  m.inputs = {"models/a.osgb", "b c.ive", "\xc3\xa9t\xc3\xa9.obj"};
  m.files = {{"skeleton.bin", {100, 0}},      {"bounds.bin", {200, 0xFFFFFFFFu}},
             {"occluders.bin", {28, 12345}},  {"geometry/000000.bin", {1ull << 33, 7}},
             {"geometry/000001.bin", {0, 8}}, {"textures/000000.bin", {64, 9}}};
  return m;
}

std::string dumped(const json& j) {
  return j.dump(1);
}
json sampleJson() {
  return json::parse(encodeManifest(sampleManifest()));
}

TEST(ManifestFormat, RoundTrip) {
  Manifest m = sampleManifest();
  EXPECT_EQ(decodeManifest(encodeManifest(m), "m.json"), m);
  Manifest empty;
  empty.bounds = {{0, 0, 0}, {0, 0, 0}};
  EXPECT_EQ(decodeManifest(encodeManifest(empty), "m.json"), empty);
}

TEST(ManifestFormat, RandomBoundsRoundTripExactly) {
  std::mt19937 rng(12);
  for (int i = 0; i < 50; ++i) {
    Manifest m = sampleManifest();
    m.bounds = randomBox(rng);
    m.bounds.lo.x = std::ldexp(m.bounds.lo.x, int(rng() % 200) - 100);
    m.bounds.hi.x = std::fabs(m.bounds.lo.x) * 3;
    EXPECT_EQ(decodeManifest(encodeManifest(m), "m.json"), m);
  }
}

TEST(ManifestFormat, WritesDocumentedFields) {
  json j = sampleJson();
  EXPECT_EQ(j["format"], "dmmr-scene");
  EXPECT_EQ(j["version"], 2);
  EXPECT_EQ(j["counts"]["objects"], 12);
  EXPECT_EQ(j["encoding"], "float32");
  EXPECT_EQ(j["files"]["bounds.bin"]["crc32"], 0xFFFFFFFFu);
  EXPECT_EQ(j["files"]["bounds.bin"]["bytes"], 200);
}

TEST(ManifestFormat, RejectsInvalidJson) {
  for (std::string text : {"", "{", "not json", "{\"format\": \"dmmr-scene\",}", "\xff\xfe"})
    EXPECT_DMMR_ERROR(decodeManifest(text, "s/manifest.json"), "s/manifest.json", "JSON");
}

TEST(ManifestFormat, RejectsEveryTruncation) {
  std::string text = encodeManifest(sampleManifest());
  size_t close = text.rfind('}');
  for (size_t n = 0; n < close; ++n)
    EXPECT_DMMR_ERROR(decodeManifest(text.substr(0, n), "cut.json"), "cut.json", "");
}

TEST(ManifestFormat, RejectsNonObjectTopLevel) {
  for (std::string text : {"[]", "1", "\"dmmr-scene\"", "null"})
    EXPECT_DMMR_ERROR(decodeManifest(text, "m.json"), "m.json", "format");
}

TEST(ManifestFormat, RejectsMissingField) {
  const std::vector<std::vector<std::string>> paths = {{"format"},
                                                       {"version"},
                                                       {"counts"},
                                                       {"counts", "objects"},
                                                       {"counts", "geometries"},
                                                       {"counts", "textures"},
                                                       {"counts", "occluders"},
                                                       {"counts", "triangles"},
                                                       {"counts", "unique_triangles"},
                                                       {"counts", "geometry_bytes"},
                                                       {"bounds"},
                                                       {"bounds", "min"},
                                                       {"bounds", "max"},
                                                       {"encoding"},
                                                       {"inputs"},
                                                       {"files"},
                                                       {"files", "bounds.bin", "crc32"},
                                                       {"files", "bounds.bin", "bytes"}};
  for (const auto& p : paths) {
    json j = sampleJson();
    json* parent = &j;
    for (size_t i = 0; i + 1 < p.size(); ++i) parent = &(*parent)[p[i]];
    parent->erase(p.back());
    EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", "'" + p.back() + "'");
  }
}

TEST(ManifestFormat, RejectsWrongType) {
  struct Case {
    std::vector<std::string> path;
    json value;
    std::string needle;
  };
  const std::vector<Case> cases = {
      {{"format"}, 1, "'format'"},
      {{"version"}, "1", "'version'"},
      {{"version"}, 1.0, "'version'"},
      {{"version"}, -1, "'version'"},
      {{"counts"}, json::array({1, 2}), "'objects'"},
      {{"counts", "objects"}, -3, "'objects'"},
      {{"counts", "geometries"}, 2.5, "'geometries'"},
      {{"counts", "triangles"}, true, "'triangles'"},
      {{"counts", "textures"}, nullptr, "'textures'"},
      {{"bounds", "min"}, json::array({1, 2}), "'min'"},
      {{"bounds", "max"}, json::array({1, 2, "3"}), "'max'"},
      {{"bounds", "max"}, 3, "'max'"},
      {{"encoding"}, json::array(), "'encoding'"},
      {{"inputs"}, "a.osgb", "'inputs'"},
      {{"inputs"}, json::array({"a", 2}), "'inputs'"},
      {{"files"}, json::array(), "'files'"},
      {{"files", "bounds.bin"}, 5, "crc32"},
      {{"files", "bounds.bin", "crc32"}, "0", "'crc32'"},
      {{"files", "bounds.bin", "bytes"}, -200, "'bytes'"},
  };
  for (const auto& c : cases) {
    json j = sampleJson();
    json* v = &j;
    for (const auto& k : c.path) v = &(*v)[k];
    *v = c.value;
    SCOPED_TRACE(dumped(j));
    EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", c.needle);
  }
}

TEST(ManifestFormat, RejectsCrcOutOfRange) {
  json j = sampleJson();
  j["files"]["bounds.bin"]["crc32"] = 0x100000000ull;
  EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", "bounds.bin");
}

TEST(ManifestFormat, RejectsUnsupportedVersion) {
  // 1: file CRCs over whole containers, which every intact file shares.
  for (uint64_t v : {0ull, 1ull, 3ull, 0x100000001ull, 0xFFFFFFFFFFFFFFFFull}) {
    json j = sampleJson();
    j["version"] = v;
    SCOPED_TRACE(v);
    EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", "version");
  }
}

TEST(ManifestFormat, RejectsBadFileName) {
  for (std::string name : {"../x", "/etc/passwd", "", "geometry/../../x", "a/..", ".."}) {
    json j = sampleJson();
    j["files"][name] = {{"bytes", 1}, {"crc32", 2}};
    EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", "'" + name + "'");
  }
}

TEST(ManifestFormat, RejectsFormatOtherThanDmmrScene) {
  for (std::string f : {"dmmr-scene2", "", "DMMR-SCENE"}) {
    json j = sampleJson();
    j["format"] = f;
    EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", "not a dmmr scene");
  }
}

TEST(ManifestFormat, RejectsUnknownEncoding) {
  json j = sampleJson();
  j["encoding"] = "float16";
  EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", "encoding 'float16'");
}

TEST(ManifestFormat, EncodingIsWrittenAndReadByName) {
  for (Encoding e : kEncodings) {
    Manifest m = sampleManifest();
    m.encoding = e;
    std::string text = encodeManifest(m);
    EXPECT_EQ(json::parse(text)["encoding"], encodingName(e));
    EXPECT_EQ(decodeManifest(text, "m.json"), m);
  }
}

TEST(ManifestFormat, RejectsInvalidBounds) {
  json j = sampleJson();
  j["bounds"]["min"] = {3, 0, 0};
  j["bounds"]["max"] = {2, 1, 1};
  EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", "bounds");
  std::string text = dumped(sampleJson());
  size_t at = text.find("2.75");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 4, "1e999");  // overflows to infinity, or fails to parse
  EXPECT_DMMR_ERROR(decodeManifest(text, "m.json"), "m.json", "");
}

TEST(ManifestFormat, RejectsCountsDisagreeingWithFiles) {
  json j = sampleJson();
  j["counts"]["geometries"] = 7;  // 6 files listed
  EXPECT_DMMR_ERROR(decodeManifest(dumped(j), "m.json"), "m.json", "counts");
}

// ---- scene loading -------------------------------------------------------------------

class SceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = (fs::temp_directory_path() /
            ("dmmr_scene_test_" + std::to_string(::getpid()) + "_" + info->name()))
               .string();
    fs::remove_all(dir_);
    fs::create_directories(dir_ + "/geometry");
    fs::create_directories(dir_ + "/textures");

    // Two instances of one geometry (a textured triangle), one texture.
    skeleton_ = {node(NodeKind::Group, kNone, 3, kNone, "root"), node(NodeKind::Object, 0, 2, 0),
                 node(NodeKind::Object, 0, 3, 1)};
    skeleton_[0].box = {{-1, -1, -1}, {11, 1, 1}};
    objects_ = sampleObjects(2, 99);
    for (auto& o : objects_) o.geometry = 0;
    occluders_ = {1};
    geometry_.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    geometry_.texcoords = {0, 0, 1, 0, 0, 1};
    geometry_.indices = {0, 1, 2};
    SubMesh sm;
    sm.index_count = 3;
    sm.texture = 0;
    geometry_.submeshes = {sm};
    texture_ = sampleTexture(2, 2, 5);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  void put(const std::string& name, const Bytes& bytes) {
    writeFileAtomic(dir_ + "/" + name, bytes);
    // The manifest lists the CRC of all but the stored CRC (manifestCrc).
    manifest_.files[name] = {bytes.size(), referenceCrc(bytes.data(), bytes.size() - 4)};
  }
  // Writes every file with correct sizes and CRCs in the manifest.
  void write() {
    manifest_ = Manifest{};
    put("skeleton.bin", encodeSkeleton(skeleton_));
    put("bounds.bin", encodeBounds(objects_));
    put("occluders.bin", encodeOccluders(occluders_));
    put("geometry/000000.bin", encodeGeometry(geometry_));
    put("textures/000000.bin", encodeTexture(texture_));
    manifest_.objects = objects_.size();
    manifest_.geometries = 1;
    manifest_.textures = 1;
    manifest_.occluders = occluders_.size();
    manifest_.triangles = 2;
    manifest_.unique_triangles = 1;
    manifest_.geometry_bytes =
        manifest_.files["geometry/000000.bin"].bytes + manifest_.files["textures/000000.bin"].bytes;
    manifest_.bounds = {{-1, -1, -1}, {11, 1, 1}};
    manifest_.inputs = {"tiny.osgt"};
    writeManifest();
  }
  void writeManifest() { writeFileAtomic(dir_ + "/manifest.json", encodeManifest(manifest_)); }
  std::string path(const std::string& name) const { return dir_ + "/" + name; }

  std::string dir_;
  Manifest manifest_;
  std::vector<SkeletonNode> skeleton_;
  std::vector<ObjectBounds> objects_;
  std::vector<uint32_t> occluders_;
  GeometryData geometry_;
  TextureData texture_;
};

TEST_F(SceneTest, LoadsAValidScene) {
  write();
  Scene s = loadScene(dir_);
  EXPECT_EQ(s.dir, dir_);
  EXPECT_EQ(s.manifest, manifest_);
  EXPECT_EQ(s.skeleton, skeleton_);
  EXPECT_EQ(s.objects, objects_);
  EXPECT_EQ(s.occluders, occluders_);
  EXPECT_EQ(loadGeometry(s, 0), geometry_);
  EXPECT_EQ(loadTexture(s, 0), texture_);
  EXPECT_NEAR(defaultNear(s), std::sqrt(144.0 + 4 + 4) * 1e-5, 1e-15);
}

TEST_F(SceneTest, RejectsMissingDirectoryAndManifest) {
  EXPECT_DMMR_ERROR(loadScene(dir_ + "/nope"), dir_ + "/nope", "");
  EXPECT_DMMR_ERROR(loadScene(dir_), path("manifest.json"), "");
}

TEST_F(SceneTest, RejectsFileSizeDifferingFromManifest) {
  write();
  Bytes b = readFileBytes(path("bounds.bin"));
  b.push_back(0);
  writeFileAtomic(path("bounds.bin"), b);
  EXPECT_DMMR_ERROR(loadScene(dir_), path("bounds.bin"), "size");
  write();
  manifest_.files["skeleton.bin"].bytes += 1;
  writeManifest();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("skeleton.bin"), "size");
}

TEST_F(SceneTest, RejectsFileCrcDifferingFromManifest) {
  write();
  manifest_.files["occluders.bin"].crc ^= 1;
  writeManifest();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("occluders.bin"), "checksum");
  write();
  Bytes k = readFileBytes(path("skeleton.bin"));
  k[25] ^= 2;  // same size, other bytes
  writeFileAtomic(path("skeleton.bin"), k);
  EXPECT_DMMR_ERROR(loadScene(dir_), path("skeleton.bin"), "checksum");
}

TEST_F(SceneTest, RejectsGeometryFileCrcDifferingFromManifest) {
  write();
  Scene s = loadScene(dir_);
  s.manifest.files["geometry/000000.bin"].crc ^= 0x100;
  EXPECT_DMMR_ERROR(loadGeometry(s, 0), path("geometry/000000.bin"), "checksum");
  EXPECT_DMMR_ERROR(loadGeometry(s, 1), path("manifest.json"), "geometry/000001.bin");
}

TEST_F(SceneTest, RejectsFileMissingFromManifest) {
  write();
  manifest_.files.erase("occluders.bin");
  writeManifest();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("manifest.json"), "occluders.bin");
}

TEST_F(SceneTest, RejectsObjectCountDifferingFromManifest) {
  write();
  manifest_.objects = 3;
  writeManifest();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("bounds.bin"), "manifest says 3");
}

TEST_F(SceneTest, LoadsPartsOnlyWhenAskedAndListed) {
  write();
  EXPECT_TRUE(loadScene(dir_, true, true).parts.empty());  // a scene from before part boxes
  GeometryParts g;
  g.box = {{0, 0, 0}, {1, 1, 0}};
  g.parts = {{0, 0, 0, 128, 255, 0}, {100, 0, 0, 255, 255, 0}};
  put("parts.bin", encodeParts({g}));
  writeManifest();
  EXPECT_TRUE(loadScene(dir_).parts.empty());  // the server's load: not read
  EXPECT_EQ(loadScene(dir_, false, true).parts, std::vector<GeometryParts>{g});
}

TEST_F(SceneTest, RejectsPartsForAnotherGeometryCount) {
  write();
  GeometryParts g;
  g.box = {{0, 0, 0}, {1, 1, 0}};
  put("parts.bin", encodeParts({g, g}));
  writeManifest();
  EXPECT_DMMR_ERROR(loadScene(dir_, false, true), path("parts.bin"),
                    "holds 2 geometries, the manifest says 1");
}

TEST_F(SceneTest, RejectsObjectNamingOutOfRangeGeometry) {
  objects_[1].geometry = 1;
  write();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("bounds.bin"), "object 1");
}

TEST_F(SceneTest, RejectsOccluderBeyondObjectCount) {
  occluders_ = {0, 2};
  write();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("occluders.bin"), "object 2");
}

TEST_F(SceneTest, RejectsOccluderCountDifferingFromManifest) {
  write();
  manifest_.occluders = 2;
  writeManifest();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("occluders.bin"), "count");
}

TEST_F(SceneTest, RejectsSkeletonMissingAnObject) {
  skeleton_ = {node(NodeKind::Group, kNone, 2), node(NodeKind::Object, 0, 2, 1)};
  write();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("skeleton.bin"), "object 0");
}

TEST_F(SceneTest, RejectsSkeletonRepeatingAnObject) {
  skeleton_.push_back(node(NodeKind::Object, 0, 4, 0));
  skeleton_[0].end = 4;
  write();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("skeleton.bin"), "object node 0");
}

TEST_F(SceneTest, RejectsSkeletonNamingOutOfRangeObject) {
  skeleton_[2].object = 2;
  write();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("skeleton.bin"), "object node 2");
}

TEST_F(SceneTest, RejectsGeometryNamingTextureBeyondCount) {
  geometry_.submeshes[0].texture = 1;
  write();
  Scene s = loadScene(dir_);
  EXPECT_DMMR_ERROR(loadGeometry(s, 0), path("geometry/000000.bin"), "texture 1");
}

TEST_F(SceneTest, CorruptFileNamesTheFile) {
  // A file that matches the manifest but is not a valid file of its kind.
  skeleton_ = {};
  write();
  EXPECT_DMMR_ERROR(loadScene(dir_), path("skeleton.bin"), "no nodes");
}

}  // namespace
}  // namespace dmmr
