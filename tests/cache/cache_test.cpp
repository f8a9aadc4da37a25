// The host (RAM, RAM disk, disk) and GPU levels of the geometry cache on a
// small generated plant, with a fake GPU backend: budgets hold, LRU order
// decides, prefetches land, unreadable files are skipped once.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <osgDB/WriteFile>
#include <random>
#include <thread>

#include "gpu_cache.h"
#include "host_cache.h"
#include "preprocess.h"
#include "scenegen.h"
#include "test_support.h"

namespace fs = std::filesystem;
using namespace dmmr;
using dmmr::test::TempDir;

namespace {

struct PlantFixture {
  TempDir dir;
  Scene scene;
  std::vector<uint64_t> sizes;  // geometry file bytes
  PlantFixture() {
    scenegen::PlantParams params;
    params.seed = 5;
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
    for (uint32_t g = 0; g < scene.manifest.geometries; ++g)
      sizes.push_back(geometryFileBytes(scene, g));
  }
  uint32_t geometries() const { return uint32_t(sizes.size()); }
  uint64_t total() const {
    uint64_t t = 0;
    for (uint64_t s : sizes) t += s;
    return t;
  }
};

PlantFixture& plant() {
  static PlantFixture p;  // removed (its temporary directory too) at exit
  return p;
}

// GPU memory as a counter: what is live now and at most.
class FakeBackend : public MeshBackend {
 public:
  GpuMesh upload(const GeometryData& g) override {
    GpuMesh m;
    m.vao = ++next_;
    m.bytes = gpuBytes(g);
    m.triangles = g.triangleCount();
    live_ += m.bytes;
    ++uploads;
    return m;
  }
  void release(GpuMesh& m) override {
    live_ -= m.bytes;
    m = GpuMesh{};
    ++releases;
  }
  GLuint uploadTexture(const TextureData& t) override {
    live_ += gpuBytes(t);
    return ++next_;
  }
  void releaseTexture(GLuint) override {}
  uint64_t live() const { return live_; }
  int uploads = 0, releases = 0;

 private:
  GLuint next_ = 0;
  uint64_t live_ = 0;
};

}  // namespace

TEST(HostCache, UnlimitedReadsEachFileOnceAndDecodesAsLoadGeometry) {
  PlantFixture& p = plant();
  HostCache cache(p.scene, {});
  for (int pass = 0; pass < 2; ++pass)
    for (uint32_t g = 0; g < p.geometries(); ++g) {
      std::optional<GeometryData> data = cache.get(g);
      ASSERT_TRUE(data);
      if (pass == 0) {
        EXPECT_EQ(*data, loadGeometry(p.scene, g)) << g;
      }
    }
  HostCacheStats s = cache.stats();
  EXPECT_EQ(s.misses, p.geometries());
  EXPECT_EQ(s.hits, p.geometries());
  EXPECT_EQ(s.disk_bytes, p.total());
  EXPECT_EQ(s.resident, p.total());
  EXPECT_EQ(s.skipped, 0u);
}

// A fixed-seed random access sequence under a quarter of the geometry:
// every hit and miss is the one a plain LRU model predicts, and the
// resident bytes never pass the budget.
TEST(HostCache, FollowsLruUnderABudget) {
  PlantFixture& p = plant();
  uint64_t budget = p.total() / 4;
  HostCache cache(p.scene, {budget, "", Eviction::Lru});
  std::vector<uint32_t> model;  // least recently used first
  uint64_t hits = 0, misses = 0, used = 0;
  std::mt19937 rng(7);
  for (int i = 0; i < 600; ++i) {
    // Skewed towards low indices, so that there are hits to count.
    uint32_t g = std::min<uint32_t>(p.geometries() - 1, uint32_t(rng() % p.geometries()) % 25);
    auto it = std::find(model.begin(), model.end(), g);
    if (it != model.end()) {
      ++hits;
      model.erase(it);
    } else {
      ++misses;
      if (p.sizes[g] > budget) {
        ASSERT_TRUE(cache.get(g));
        continue;
      }
      while (budget - used < p.sizes[g]) {
        used -= p.sizes[model.front()];
        model.erase(model.begin());
      }
      used += p.sizes[g];
    }
    model.push_back(g);
    ASSERT_TRUE(cache.get(g));
    HostCacheStats s = cache.stats();
    ASSERT_EQ(s.hits, hits) << "access " << i;
    ASSERT_EQ(s.misses, misses) << "access " << i;
    ASSERT_EQ(s.resident, used);
    ASSERT_LE(s.resident, budget);
  }
  EXPECT_GT(hits, 0u);
  EXPECT_GT(misses, p.geometries() / 2);
}

TEST(HostCache, AFileLargerThanTheBudgetIsUsedUncached) {
  PlantFixture& p = plant();
  uint64_t smallest = *std::min_element(p.sizes.begin(), p.sizes.end());
  HostCache cache(p.scene, {smallest - 1, ""});
  std::optional<GeometryData> data = cache.get(0);
  ASSERT_TRUE(data);
  EXPECT_EQ(*data, loadGeometry(p.scene, 0));
  ASSERT_TRUE(cache.get(0));
  HostCacheStats s = cache.stats();
  EXPECT_EQ(s.uncached, 2u);
  EXPECT_EQ(s.misses, 2u);
  EXPECT_EQ(s.resident, 0u);
}

TEST(HostCache, UrgentPrefetchBringsGeometryInAhead) {
  PlantFixture& p = plant();
  HostCache cache(p.scene, {});
  std::vector<uint32_t> wanted = {3, 1, 4, 1, 5, 9, 2, 6};
  cache.prefetch(wanted, /*urgent=*/true);
  cache.drain();
  EXPECT_EQ(cache.stats().prefetched, 7u);  // 1 asked twice, read once
  for (uint32_t g : wanted) ASSERT_TRUE(cache.get(g));
  HostCacheStats s = cache.stats();
  EXPECT_EQ(s.misses, 0u);
  EXPECT_EQ(s.hits, wanted.size());
}

TEST(HostCache, OtherPrefetchesOnlyFillFreeSpace) {
  PlantFixture& p = plant();
  uint64_t budget = p.sizes[0] + p.sizes[1];
  HostCache cache(p.scene, {budget, ""});
  ASSERT_TRUE(cache.get(0));
  ASSERT_TRUE(cache.get(1));  // the budget is now full
  std::vector<uint32_t> others;
  for (uint32_t g = 2; g < p.geometries(); ++g) others.push_back(g);
  cache.prefetch(others, /*urgent=*/false);
  cache.drain();
  HostCacheStats s = cache.stats();
  EXPECT_EQ(s.prefetched, 0u);
  EXPECT_EQ(s.resident, budget);
  ASSERT_TRUE(cache.get(0));
  ASSERT_TRUE(cache.get(1));
  EXPECT_EQ(cache.stats().hits, 2u) << "a prefetch pushed out what was in use";
}

TEST(HostCache, RamDiskDirectoryHoldsTheFilesAndIsRemovedAfter) {
  PlantFixture& p = plant();
  TempDir ramdisk;
  {
    HostCache cache(p.scene, {LruBudget::kUnlimited, ramdisk.path()});
    for (uint32_t g = 0; g < p.geometries(); ++g) ASSERT_TRUE(cache.get(g));
    size_t files = 0;
    for (auto& e : fs::recursive_directory_iterator(ramdisk.path())) files += e.is_regular_file();
    EXPECT_EQ(files, p.geometries());
    for (uint32_t g = 0; g < p.geometries(); ++g) {
      std::optional<GeometryData> data = cache.get(g);
      ASSERT_TRUE(data);
      EXPECT_EQ(*data, loadGeometry(p.scene, g));
    }
    EXPECT_EQ(cache.stats().hits, p.geometries());
  }
  EXPECT_TRUE(fs::is_empty(ramdisk.path()));
}

TEST(HostCache, AnUnusableRamDiskDirectoryIsAClearError) {
  PlantFixture& p = plant();
  TempDir d;
  std::string file = d / "plain-file";
  std::ofstream(file) << "x";
  std::string error = test::errorOf([&] { HostCache cache(p.scene, {1 << 20, file}); });
  EXPECT_NE(error.find("plain-file"), std::string::npos) << error;
  EXPECT_NE(error.find("cannot create the RAM cache directory"), std::string::npos) << error;
}

TEST(HostCache, ACorruptFileIsSkippedOnceAndNeverReadAgain) {
  PlantFixture& p = plant();
  TempDir d;
  fs::copy(p.scene.dir, d / "scene", fs::copy_options::recursive);
  Scene scene = loadScene(d / "scene");
  test::flipByte(d / "scene/geometry/000002.bin", 40);
  HostCache cache(scene, {});
  testing::internal::CaptureStderr();
  EXPECT_FALSE(cache.get(2));
  EXPECT_FALSE(cache.get(2));
  cache.prefetch({2}, true);
  cache.drain();
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("geometry/000002.bin"), std::string::npos) << err;
  EXPECT_NE(err.find("checksum"), std::string::npos) << err;
  EXPECT_EQ(err.find("skipping", err.find("skipping") + 1), std::string::npos)
      << "warned more than once:\n"
      << err;
  HostCacheStats s = cache.stats();
  EXPECT_EQ(s.skipped, 1u);
  EXPECT_EQ(s.disk_bytes, 0u);
  EXPECT_TRUE(cache.get(3)) << "one bad file stops nothing else";
}

TEST(HostCache, AGeometryFileSwappedForAnotherIntactOneIsCaught) {
  PlantFixture& p = plant();
  TempDir d;
  fs::copy(p.scene.dir, d / "scene", fs::copy_options::recursive);
  // Two geometry files of the same size, each intact, traded places.
  uint32_t a = 0, b = 0;
  for (uint32_t i = 0; i < p.geometries() && !b; ++i)
    for (uint32_t j = 0; j < i && !b; ++j)
      if (p.sizes[i] == p.sizes[j] && loadGeometry(p.scene, i) != loadGeometry(p.scene, j)) {
        a = j;
        b = i;
      }
  ASSERT_NE(b, 0u) << "no two different geometries of one size to swap";
  std::string fa = d / ("scene/" + geometryFileName(a)), fb = d / ("scene/" + geometryFileName(b));
  fs::rename(fa, d / "tmp.bin");
  fs::rename(fb, fa);
  fs::rename(d / "tmp.bin", fb);
  Scene scene = loadScene(d / "scene");
  HostCache cache(scene, {});
  testing::internal::CaptureStderr();
  EXPECT_FALSE(cache.get(a));
  EXPECT_FALSE(cache.get(b));
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("checksum differs from the manifest"), std::string::npos) << err;
}

TEST(HostCache, AGeometryFileInAnotherEncodingThanTheManifestsIsCaught) {
  PlantFixture& p = plant();
  TempDir d;
  fs::copy(p.scene.dir, d / "scene", fs::copy_options::recursive);
  std::string manifest = d / "scene/manifest.json";
  std::ifstream in(manifest);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string from = "\"encoding\": \"float32\"";
  size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << text.substr(0, 400);
  text.replace(at, from.size(), "\"encoding\": \"meshopt\"");
  std::ofstream(manifest) << text;
  Scene scene = loadScene(d / "scene");
  HostCache cache(scene, {});
  testing::internal::CaptureStderr();
  EXPECT_FALSE(cache.get(0));
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("encoding float32 differs from the manifest's meshopt"), std::string::npos)
      << err;
}

// Two stages' worth of threads reading through one small cache while the
// loader prefetches: every geometry decodes as on disk, the budget holds.
TEST(HostCache, ConcurrentGetsAndPrefetchesAgree) {
  PlantFixture& p = plant();
  uint64_t budget = p.total() / 5;
  HostCache cache(p.scene, {budget, ""});
  std::vector<GeometryData> truth;
  for (uint32_t g = 0; g < p.geometries(); ++g) truth.push_back(loadGeometry(p.scene, g));
  auto worker = [&](unsigned seed) {
    std::mt19937 rng(seed);
    for (int i = 0; i < 200; ++i) {
      uint32_t g = uint32_t(rng() % p.geometries());
      if (i % 10 == 0) cache.prefetch({g, (g + 1) % p.geometries()}, i % 20 == 0);
      std::optional<GeometryData> data = cache.get(g);
      ASSERT_TRUE(data);
      ASSERT_EQ(*data, truth[g]);
      ASSERT_LE(cache.stats().resident, budget);
    }
  };
  std::thread a(worker, 1), b(worker, 2);
  a.join();
  b.join();
}

// The store is read and written outside the cache's lock (with --ram-dir,
// file I/O). Threads getting overlapping geometries through a small budget,
// so that entries are written, read and evicted at once, with the loader
// prefetching: every geometry decodes as on disk, and no entry is ever found
// short or missing (read while written, or erased while read). TSan runs it
// (CMakePresets.json) for the memory store's slots.
TEST(HostCache, ConcurrentGetsNeverSeeAPartialEntry) {
  PlantFixture& p = plant();
  std::vector<GeometryData> truth;
  for (uint32_t g = 0; g < p.geometries(); ++g) truth.push_back(loadGeometry(p.scene, g));
  for (bool ramdisk : {false, true}) {
    TempDir ramdir;
    HostCache cache(p.scene, {p.total() / 5, ramdisk ? ramdir.path() : ""});
    auto worker = [&](unsigned seed) {
      std::mt19937 rng(seed);
      for (int i = 0; i < 300; ++i) {
        // Half the gets from a few geometries, so that threads meet on one.
        uint32_t g = uint32_t(rng() % (i % 2 ? 6 : p.geometries()));
        if (i % 25 == 0) cache.prefetch({(g + 1) % p.geometries()}, true);
        std::optional<GeometryData> data = cache.get(g);
        ASSERT_TRUE(data);
        ASSERT_EQ(*data, truth[g]);
      }
    };
    std::vector<std::thread> threads;
    for (unsigned t = 1; t <= 3; ++t) threads.emplace_back(worker, t);
    for (auto& t : threads) t.join();
    cache.drain();
    HostCacheStats s = cache.stats();
    EXPECT_EQ(s.lost, 0u) << (ramdisk ? "RAM disk" : "memory");
    EXPECT_GT(s.hits, 0u);
    EXPECT_GT(s.misses, p.geometries()) << "the budget should make entries come and go";
    EXPECT_LE(s.resident, p.total() / 5);
  }
}

TEST(GpuCache, InstancesShareOneUpload) {
  PlantFixture& p = plant();
  HostCache host(p.scene, {});
  FakeBackend gpu;
  GpuCache cache(p.scene, host, gpu);
  const GpuMesh* a = cache.acquire(4);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->triangles, loadGeometry(p.scene, 4).triangleCount());
  EXPECT_EQ(cache.acquire(4), a);
  EXPECT_EQ(gpu.uploads, 1);
  GpuCacheStats s = cache.stats();
  EXPECT_EQ(s.hits, 1u);
  EXPECT_EQ(s.misses, 1u);
  EXPECT_EQ(s.resident, a->bytes);
}

// Random acquires under a tenth of the geometry: what the cache keeps never
// passes the budget, and GPU memory in use never passes it by more than the
// one uncached mesh being drawn.
TEST(GpuCache, KeepsWithinItsBudget) {
  PlantFixture& p = plant();
  HostCache host(p.scene, {});
  uint64_t all = 0, largest = 0;
  for (uint32_t g = 0; g < p.geometries(); ++g) {
    uint64_t b = gpuBytes(loadGeometry(p.scene, g));
    all += b;
    largest = std::max(largest, b);
  }
  uint64_t budget = all / 10;
  ASSERT_LT(budget, largest) << "the test wants some meshes too large for the budget";
  FakeBackend gpu;
  {
    GpuCache cache(p.scene, host, gpu, budget);
    std::mt19937 rng(3);
    uint64_t uncached = 0;
    for (int i = 0; i < 500; ++i) {
      uint32_t g = uint32_t(rng() % p.geometries());
      const GpuMesh* m = cache.acquire(g);
      ASSERT_TRUE(m);
      bool over = m->bytes > budget;
      uncached += over;
      ASSERT_LE(cache.stats().resident, budget);
      ASSERT_LE(gpu.live(), budget + (over ? m->bytes : 0));
    }
    GpuCacheStats s = cache.stats();
    EXPECT_EQ(s.uncached, uncached);
    EXPECT_GT(s.uncached, 0u);
    EXPECT_GT(s.hits, 0u);
    EXPECT_EQ(s.hits + s.misses, 500u);
  }
  EXPECT_EQ(gpu.live(), 0u) << "the cache leaked GPU memory";
  EXPECT_EQ(gpu.uploads, gpu.releases);
}

TEST(GpuCache, AnUnreadableGeometryGivesNoMesh) {
  PlantFixture& p = plant();
  TempDir d;
  fs::copy(p.scene.dir, d / "scene", fs::copy_options::recursive);
  Scene scene = loadScene(d / "scene");
  // Truncate it: the manifest's size check catches it.
  fs::resize_file(d / "scene/geometry/000001.bin", 10);
  HostCache host(scene, {});
  FakeBackend gpu;
  GpuCache cache(scene, host, gpu);
  testing::internal::CaptureStderr();
  EXPECT_EQ(cache.acquire(1), nullptr);
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("000001.bin"), std::string::npos) << err;
  EXPECT_NE(cache.acquire(0), nullptr);
  EXPECT_EQ(host.stats().skipped, 1u);
  EXPECT_EQ(gpu.uploads, 1);
}
