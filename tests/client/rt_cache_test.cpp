// The ray tracer's device level (client/rt_cache.h) on a small generated
// plant, with fake meshes whose bytes are known: instances share one build,
// the level keeps within its budget, a mesh evicted while its frame is being
// gathered lives until the frame lets go of it, unreadable files give no
// mesh; and with the real ray tracer, the BVHs' bytes are what the budget
// counts.
#include <gtest/gtest.h>

#include <filesystem>
#include <osgDB/WriteFile>
#include <random>

#include "preprocess.h"
#include "rt_cache.h"
#include "scenegen.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace dmmr;
using dmmr::test::TempDir;

namespace {

struct PlantFixture {
  TempDir dir;
  Scene scene;
  PlantFixture() {
    scenegen::PlantParams params;
    params.seed = 9;
    params.triangles = 20'000;
    params.geodes = 60;
    std::string model = dir / "plant.osgb";
    EXPECT_TRUE(osgDB::writeNodeFile(*scenegen::makePlant(params), model));
    PreprocessOptions o;
    o.inputs = {model};
    o.out = dir / "scene";
    o.progress = false;
    preprocess(o);
    scene = loadScene(o.out);
  }
};

PlantFixture& plant() {
  static PlantFixture p;  // removed (its temporary directory too) at exit
  return p;
}

// Bytes of live fake meshes, and how many were built.
struct Ledger {
  uint64_t live = 0;
  int built = 0;
};

class FakeMesh : public RtMesh {
 public:
  FakeMesh(uint64_t bytes, uint64_t triangles, Ledger& l) : bytes_(bytes), tris_(triangles), l_(l) {
    l_.live += bytes_;
    ++l_.built;
  }
  ~FakeMesh() override { l_.live -= bytes_; }
  uint64_t bytes() const override { return bytes_; }
  uint64_t bvhBytes() const override { return bytes_ / 2; }
  uint64_t triangles() const override { return tris_; }

 private:
  uint64_t bytes_, tris_;
  Ledger& l_;
};

// A BVH's size is not known before the build: 64 bytes a triangle here.
RtCache::Build fakeBuild(Ledger& l) {
  return [&l](const GeometryData& g) {
    return std::make_unique<FakeMesh>(64 * g.triangleCount() + 100, g.triangleCount(), l);
  };
}

uint64_t fakeBytes(const Scene& s, uint32_t g) {
  return 64 * loadGeometry(s, g).triangleCount() + 100;
}

}  // namespace

TEST(RtCache, InstancesShareOneBuild) {
  PlantFixture& p = plant();
  HostCache host(p.scene, {});
  Ledger l;
  RtCache cache(p.scene, host, fakeBuild(l));
  auto a = cache.acquire(3);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->triangles(), loadGeometry(p.scene, 3).triangleCount());
  EXPECT_EQ(cache.acquire(3), a);
  EXPECT_EQ(l.built, 1);
  RtCacheStats s = cache.stats();
  EXPECT_EQ(s.hits, 1u);
  EXPECT_EQ(s.misses, 1u);
  EXPECT_EQ(s.resident, a->bytes());
  EXPECT_EQ(s.built_bytes, a->bytes());
}

// Frames of random geometries under a tenth of the whole: the level never
// holds more than its budget; memory alive never passes the budget by more
// than the frame's own meshes, and once a frame lets go, not at all.
TEST(RtCache, KeepsWithinItsBudgetAndFreesEvictedMeshesWhenTheFrameLetsGo) {
  PlantFixture& p = plant();
  const uint32_t n = uint32_t(p.scene.manifest.geometries);
  uint64_t all = 0, largest = 0;
  for (uint32_t g = 0; g < n; ++g) {
    all += fakeBytes(p.scene, g);
    largest = std::max(largest, fakeBytes(p.scene, g));
  }
  uint64_t budget = all / 10;
  ASSERT_LT(budget, largest) << "the test wants some meshes too large for the budget";
  HostCache host(p.scene, {});
  Ledger l;
  {
    RtCache cache(p.scene, host, fakeBuild(l), budget);
    std::mt19937 rng(11);
    uint64_t uncached = 0, acquires = 0;
    for (int frame = 0; frame < 60; ++frame) {
      cache.nextFrame();
      std::vector<std::shared_ptr<const RtMesh>> pinned;
      uint64_t pinned_bytes = 0;
      for (int i = 0; i < 8; ++i) {
        uint32_t g = uint32_t(rng() % n);
        auto m = cache.acquire(g);
        ASSERT_TRUE(m);
        ++acquires;
        uncached += m->bytes() > budget;
        ASSERT_LE(cache.stats().resident, budget);
        pinned_bytes += m->bytes();
        pinned.push_back(std::move(m));
        ASSERT_LE(l.live, budget + pinned_bytes);
      }
      pinned.clear();
      ASSERT_LE(l.live, budget) << "an evicted or uncached mesh outlived its frame";
    }
    RtCacheStats s = cache.stats();
    EXPECT_EQ(s.uncached, uncached);
    EXPECT_GT(s.uncached, 0u);
    EXPECT_GT(s.hits, 0u);
    EXPECT_EQ(s.hits + s.misses, acquires);
  }
  EXPECT_EQ(l.live, 0u) << "the level leaked meshes";
}

TEST(RtCache, AnUnreadableGeometryGivesNoMeshAndIsNamed) {
  PlantFixture& p = plant();
  TempDir d;
  fs::copy(p.scene.dir, d / "scene", fs::copy_options::recursive);
  Scene scene = loadScene(d / "scene");
  fs::resize_file(d / "scene/geometry/000002.bin", 10);
  HostCache host(scene, {});
  Ledger l;
  RtCache cache(scene, host, fakeBuild(l));
  testing::internal::CaptureStderr();
  EXPECT_EQ(cache.acquire(2), nullptr);
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("000002.bin"), std::string::npos) << err;
  EXPECT_NE(cache.acquire(0), nullptr);
  EXPECT_EQ(host.stats().skipped, 1u);
  EXPECT_EQ(l.built, 1);
}

// With the real ray tracer: what the level holds is the BVHs' and their
// attributes' bytes as each mesh reports them, and a budget bounds them.
TEST(RtCache, RealBvhBytesCountInTheBudget) {
  PlantFixture& p = plant();
  HostCache host(p.scene, {});
  RayTracer tracer(1);
  auto build = [&tracer](const GeometryData& g) { return tracer.build(g); };
  const uint32_t n = uint32_t(p.scene.manifest.geometries);
  uint64_t sum = 0;
  {
    RtCache all(p.scene, host, build);
    for (uint32_t g = 0; g < n; ++g) {
      auto m = all.acquire(g);
      ASSERT_TRUE(m);
      EXPECT_GT(m->bvhBytes(), 0u) << "geometry " << g;
      EXPECT_GE(m->bytes(), m->bvhBytes());
      sum += m->bytes();
    }
    EXPECT_EQ(all.stats().resident, sum);
    EXPECT_EQ(all.stats().built_bytes, sum);
  }
  RtCache limited(p.scene, host, build, sum / 4);
  for (int round = 0; round < 2; ++round)
    for (uint32_t g = 0; g < n; ++g) {
      limited.nextFrame();
      ASSERT_TRUE(limited.acquire(g));
      ASSERT_LE(limited.stats().resident, sum / 4);
    }
  EXPECT_GT(limited.stats().built_bytes, sum) << "evicted meshes were built again";
}
