// End to end: a replicated plant whose geometry is several times the clients'
// RAM and GPU budgets renders, with mpirun and the visibility stage on, to
// frames identical to the same run with unlimited budgets and to
// dmmr-reference. Budgets come from a run config here, as a user sets them.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <osgDB/WriteFile>
#include <sstream>

#include "compare.h"
#include "preprocess.h"
#include "scene.h"
#include "scenegen.h"
#include "test_support.h"
#include "walkthrough.h"

namespace fs = std::filesystem;
using namespace dmmr;
using dmmr::test::TempDir;

namespace {

const std::string kSize = " --width 192 --height 144";

struct ReplicatedPlant {
  TempDir dir;
  std::string scene, path, reference;
  uint64_t geometry_bytes = 0;
  ReplicatedPlant() {
    scenegen::PlantParams params;
    params.seed = 21;
    params.triangles = 120'000;
    params.geodes = 1500;
    osg::ref_ptr<osg::Node> plant = scenegen::makePlant(params);
    osg::ref_ptr<osg::Node> copies = scenegen::replicate(plant.get(), 3, 10.0);
    std::string model = dir / "plants.osgb";
    EXPECT_TRUE(osgDB::writeNodeFile(*copies, model));
    PreprocessOptions o;
    o.inputs = {model};
    o.out = scene = dir / "scene";
    o.progress = false;
    preprocess(o);
    geometry_bytes = loadScene(scene).manifest.geometry_bytes;
    writeWalkthrough(path = dir / "fly.path",
                     scenegen::makeWalkthrough(scenegen::sceneBounds(*copies), 12,
                                               scenegen::PathKind::FlyThrough));
    reference = dir / "reference";
    int status = 0;
    std::string log =
        test::runCapture(test::tool("dmmr-reference") + " --no-progress" + kSize + " --scene " +
                             scene + " --walkthrough " + path + " --out " + reference,
                         &status);
    EXPECT_EQ(status, 0) << log;
  }
  // Runs `clients` clients; returns the per-client sums of the stats CSV's
  // columns ("c1_disk_bytes" -> sum over frames) and each column's maximum.
  test::Columns<std::pair<uint64_t, uint64_t>> render(const std::string& out,
                                                      const std::string& extra, int clients = 2) {
    int status = 0;
    std::string log = test::runCapture("timeout 120 " + test::mpirun(clients + 1) + " " +
                                           test::tool("dmmr-render") + " --no-progress" + kSize +
                                           " --scene " + scene + " --walkthrough " + path +
                                           " --out " + out + " --stats " + out + ".csv " + extra,
                                       &status);
    EXPECT_NE(status, 124) << "timed out\n" << log;
    EXPECT_EQ(status, 0) << log;
    test::Columns<std::pair<uint64_t, uint64_t>> cols(out + ".csv");
    for (const auto& row : test::readCsv(out + ".csv"))
      for (const auto& [name, value] : row) {
        if (name.find("_ms") != std::string::npos) continue;
        auto& [sum, max] = cols.entry(name);
        sum += uint64_t(value);
        max = std::max(max, uint64_t(value));
      }
    return cols;
  }
};

ReplicatedPlant& scene() {
  static ReplicatedPlant s;  // removed (its temporary directory too) at exit
  return s;
}

}  // namespace

class SmallBudgets : public testing::TestWithParam<bool> {};

TEST_P(SmallBudgets, FramesEqualUnlimitedBudgets) {
  ReplicatedPlant& s = scene();
  bool ramdisk = GetParam();
  uint64_t ram = s.geometry_bytes / 5, gpu = s.geometry_bytes / 12;
  ASSERT_GT(ram, 64u << 10) << "scene too small for a meaningful test";
  std::string name = ramdisk ? "ramdisk" : "small";
  std::string config = s.dir / (name + ".toml");
  std::ofstream(config) << "# budgets for the cache test\n"
                        << "gpu-budget = \"" << gpu << "\"\n"
                        << "ram-budget = \"" << ram << "\"\n";
  std::string extra = "--config " + config;
  TempDir ramdir;
  if (ramdisk) extra += " --ram-dir " + ramdir.path();

  auto unlimited = s.render(s.dir / (name + "-unlimited"), "");
  auto limited = s.render(s.dir / name, extra);
  std::vector<FrameDiff> diffs = compareDirectories(s.dir / (name + "-unlimited"), s.dir / name);
  ASSERT_EQ(diffs.size(), 12u);
  for (const FrameDiff& d : diffs) EXPECT_EQ(d.diff.differing_pixels, 0) << d.name << " " << d.diff;
  for (const FrameDiff& d : compareDirectories(s.reference, s.dir / name))
    EXPECT_EQ(d.diff.differing_pixels, 0) << d.name << " " << d.diff;

  uint64_t disk_limited = 0, disk_unlimited = 0, misses_limited = 0, misses_unlimited = 0;
  for (const char* c : {"c1_", "c2_"}) {
    std::string k(c);
    // The budgets held in every frame (GPU: two contexts per client).
    EXPECT_LE(limited[k + "ram_resident"].second, ram);
    EXPECT_LE(limited[k + "gpu_resident"].second, 2 * gpu);
    EXPECT_GT(limited[k + "ram_resident"].second, 0u);
    EXPECT_GT(limited[k + "gpu_hits"].first, 0u);
    EXPECT_EQ(limited[k + "skipped"].first, 0u);
    disk_limited += limited[k + "disk_bytes"].first;
    disk_unlimited += unlimited[k + "disk_bytes"].first;
    misses_limited += limited[k + "gpu_misses"].first;
    misses_unlimited += unlimited[k + "gpu_misses"].first;
    // Each client read more than its RAM level can hold, so it gave some up.
    EXPECT_GT(limited[k + "disk_bytes"].first, ram);
  }
  std::printf(
      "geometry %llu bytes, RAM budget %llu, GPU budget %llu; read from disk %llu "
      "(unlimited %llu); GPU misses %llu (unlimited %llu)\n",
      (unsigned long long)s.geometry_bytes, (unsigned long long)ram, (unsigned long long)gpu,
      (unsigned long long)disk_limited, (unsigned long long)disk_unlimited,
      (unsigned long long)misses_limited, (unsigned long long)misses_unlimited);
  // Without budgets a mesh is uploaded once per context; with them, evicted
  // meshes came back: the budgets really were too small.
  EXPECT_GT(misses_limited, misses_unlimited);
  EXPECT_LE(disk_unlimited, 2 * s.geometry_bytes);  // each client reads a file at most once
}

INSTANTIATE_TEST_SUITE_P(RamLevel, SmallBudgets, testing::Values(false, true),
                         [](const auto& info) { return info.param ? "RamDisk" : "Memory"; });

// Tiles and the frame-aware eviction (lru.h). The stages start a "frame" for
// the caches per job, so under tiles each tile is one. That is deliberate:
// issue 14 suspected it (a frame's working set above the budget would then
// see plain LRU's cyclic misses), but tiles revisit the objects spanning
// neighbouring tiles, which LRU keeps and which the whole frame as one
// eviction frame gives up (it evicts the mesh just drawn once the frame
// overflows): that doubled the GPU misses here (docs/architecture.md,
// "Geometry cache"). What must hold: at budgets below a frame's working set,
// tiles upload and read from disk no more than frustum division. One client
// and no culling, so that both draw every object in the frustum each frame.
TEST(TiledFrames, MissNoMoreThanFrustumDivision) {
  ReplicatedPlant& s = scene();
  uint64_t gpu = s.geometry_bytes / 12, ram = s.geometry_bytes / 6;
  std::string common = " --visibility off --gpu-budget " + std::to_string(gpu) + " --ram-budget " +
                       std::to_string(ram);
  struct Misses {
    uint64_t gpu, ram;
  };
  auto run = [&](const std::string& name, const std::string& extra) {
    auto c = s.render(s.dir / name, extra, 1);
    Misses m{c["c1_gpu_misses"].first, c["c1_ram_misses"].first};
    std::printf("%-12s GPU misses %llu (hits %llu), RAM misses %llu (hits %llu)\n", name.c_str(),
                (unsigned long long)m.gpu, (unsigned long long)c["c1_gpu_hits"].first,
                (unsigned long long)m.ram, (unsigned long long)c["c1_ram_hits"].first);
    return m;
  };
  Misses frustum = run("frustum", common);
  Misses frustum_lru = run("frustum-lru", common + " --eviction lru");
  Misses tiled = run("tiles", common + " --balance tiles-static --tile 32x32");
  for (const FrameDiff& d : compareDirectories(s.reference, s.dir / "tiles"))
    EXPECT_EQ(d.diff.differing_pixels, 0) << d.name << " " << d.diff;
  // The budgets are below a frame's working set: plain LRU misses more there.
  ASSERT_GT(frustum_lru.gpu, frustum.gpu);
  EXPECT_LT(tiled.gpu, frustum.gpu);
  EXPECT_LT(tiled.ram, frustum.ram);
}

TEST(CacheOptions, ABadBudgetIsRefusedWithItsReason) {
  ReplicatedPlant& s = scene();
  int status = 0;
  std::string log = test::runCapture(test::tool("dmmr-reference") + " --no-progress --scene " +
                                         s.scene + " --walkthrough " + s.path + " --out " +
                                         (s.dir / "bad") + " --ram-budget 12X",
                                     &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(log.find("unknown unit"), std::string::npos) << log;
}

TEST(CacheOptions, AConfigWithAnUnknownKeyIsRefusedNamingTheFile) {
  ReplicatedPlant& s = scene();
  std::string config = s.dir / "typo.toml";
  std::ofstream(config) << "ram-budjet = \"1M\"\n";
  int status = 0;
  std::string log = test::runCapture(test::tool("dmmr-reference") + " --no-progress --scene " +
                                         s.scene + " --walkthrough " + s.path + " --out " +
                                         (s.dir / "typo") + " --config " + config,
                                     &status);
  EXPECT_NE(status, 0);
  EXPECT_NE(log.find(config + ": "), std::string::npos) << log;
  EXPECT_NE(log.find("ram-budjet"), std::string::npos) << log;
}

// What CLI11's reader let through, each refused naming the file and line: a
// string without its closing quote (it became part of the value), a table,
// a key set twice, a switch given a word, a line without NAME = VALUE. The
// shipped config still reads.
TEST(CacheOptions, AMalformedConfigIsRefusedNamingTheFileAndLine) {
  ReplicatedPlant& s = scene();
  const std::pair<const char*, const char*> cases[] = {
      {"width = 64\nscene = \"scenes/skull\n", "line 2: scene: a string without its closing quote"},
      {"[cache]\nram-budget = \"1M\"\n", "line 1: tables ([cache]) are not run config keys"},
      {"width = 64\nwidth = 65\n", "line 2: width set again (first on line 1)"},
      {"no-progress = \"maybe\"\n", "line 1: no-progress: a switch takes true or false"},
      {"# a comment\nwidth 64\n", "line 2: expected NAME = VALUE"},
      {"width = \"abc\"\n", "--width"},  // a bad value, named with the file
  };
  int k = 0;
  for (const auto& [text, want] : cases) {
    std::string config = s.dir / ("bad" + std::to_string(k++) + ".toml");
    std::ofstream(config) << text;
    int status = 0;
    std::string log = test::runCapture(test::tool("dmmr-reference") + " --no-progress --scene " +
                                           s.scene + " --walkthrough " + s.path + " --out " +
                                           (s.dir / "badcfg") + " --config " + config,
                                       &status);
    EXPECT_NE(status, 0) << text;
    EXPECT_NE(log.find(config + ": "), std::string::npos) << log;
    EXPECT_NE(log.find(want), std::string::npos) << want << "\n" << log;
  }
  int status = 0;
  std::string log = test::runCapture(
      test::tool("dmmr-reference") + " --scene " + s.scene + " --walkthrough " + s.path +
          " --out " + (s.dir / "shipped") + " --config " + std::string(DMMR_SOURCE_DIR) +
          "/configs/small-cache.toml --no-progress --width 64 --height 48",
      &status);
  EXPECT_EQ(status, 0) << log;
}
