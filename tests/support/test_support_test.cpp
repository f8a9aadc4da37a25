// The strict stats reader (test_support.h readCsv): every test that reads
// stats columns relies on it failing, never reading 0, when a column is
// missing or a row is malformed. Also: each mpirun job's own session dir.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "test_support.h"

using namespace dmmr;
using dmmr::test::TempDir;

namespace {

std::string write(const TempDir& dir, const std::string& name, const std::string& text) {
  std::string path = dir / name;
  std::ofstream(path) << text;
  return path;
}

}  // namespace

TEST(ReadCsv, ReadsEveryColumnOfEveryRow) {
  TempDir dir;
  std::string path = write(dir, "ok.csv", "frame,c1_triangles,frame_ms\n0,120,4.5\n1,0,-2e3\n");
  std::vector<test::CsvRow> rows = test::readCsv(path);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0]["frame"], 0);
  EXPECT_EQ(rows[0]["c1_triangles"], 120);
  EXPECT_EQ(rows[0].at("frame_ms"), 4.5);
  EXPECT_EQ(rows[1]["frame"], 1);
  EXPECT_EQ(rows[1]["frame_ms"], -2000);
  EXPECT_EQ(rows[1].size(), 3u);
  EXPECT_TRUE(rows[1].contains("c1_triangles"));
}

TEST(ReadCsv, AMissingColumnThrowsNamingTheFileAndTheColumn) {
  TempDir dir;
  std::string path = write(dir, "stats.csv", "frame,c1_triangles\n0,120\n");
  std::vector<test::CsvRow> rows = test::readCsv(path);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_FALSE(rows[0].contains("c1_triangels"));
  for (std::string e : {test::errorOf([&] { (void)rows[0]["c1_triangels"]; }),
                        test::errorOf([&] { (void)rows[0].at("c1_triangels"); })}) {
    EXPECT_NE(e.find(path + ": "), std::string::npos) << e;
    EXPECT_NE(e.find("no column \"c1_triangels\""), std::string::npos) << e;
    EXPECT_NE(e.find("c1_triangles"), std::string::npos) << "the columns it has: " << e;
  }
}

TEST(ReadCsv, ARaggedRowThrowsNamingTheFileAndLine) {
  TempDir dir;
  std::string path = write(dir, "ragged.csv", "frame,triangles\n0,1\n1,2,3\n");
  std::string e = test::errorOf([&] { test::readCsv(path); });
  EXPECT_NE(e.find(path + ":3: has 3 cells, the header 2"), std::string::npos) << e;
}

TEST(ReadCsv, ANonNumericCellThrowsNamingTheFileLineAndColumn) {
  TempDir dir;
  std::string path = write(dir, "text.csv", "frame,triangles\n0,1\n1,12x\n");
  std::string e = test::errorOf([&] { test::readCsv(path); });
  EXPECT_NE(e.find(path + ":3: "), std::string::npos) << e;
  EXPECT_NE(e.find("\"triangles\""), std::string::npos) << e;
  EXPECT_NE(e.find("\"12x\""), std::string::npos) << e;
}

TEST(ReadCsv, AMissingOrEmptyFileThrowsNamingIt) {
  TempDir dir;
  std::string missing = dir / "missing.csv";
  EXPECT_NE(test::errorOf([&] { test::readCsv(missing); }).find(missing + ": cannot open"),
            std::string::npos);
  std::string empty = write(dir, "empty.csv", "");
  EXPECT_NE(test::errorOf([&] { test::readCsv(empty); }).find(empty + ": no header line"),
            std::string::npos);
}

TEST(Columns, BuiltValuesReadStrictlyToo) {
  test::Columns<std::pair<int, int>> sums("sums of stats.csv");
  sums.entry("c1_gpu_hits").first += 3;
  EXPECT_EQ(sums["c1_gpu_hits"].first, 3);
  std::string e = test::errorOf([&] { (void)sums["c1_gpu_misses"]; });
  EXPECT_NE(e.find("sums of stats.csv: no column \"c1_gpu_misses\""), std::string::npos) << e;
}

TEST(Mpirun, EachJobGetsItsOwnSessionDirectory) {
  // Open MPI 4.1's racy mkdir of <TMPDIR>/ompi.<host>.<uid> failed a CI run
  // when two jobs started at once; each launch must name its own TMPDIR.
  auto tmpdirOf = [](const std::string& cmd) {
    size_t at = cmd.find("TMPDIR=");
    EXPECT_NE(at, std::string::npos) << cmd;
    if (at == std::string::npos) return std::string();
    at += 7;
    return cmd.substr(at, cmd.find(' ', at) - at);
  };
  std::string a = tmpdirOf(test::mpirun(2)), b = tmpdirOf(test::mpirun(3));
  EXPECT_NE(a, b);
  EXPECT_TRUE(std::filesystem::is_directory(a)) << a;
  EXPECT_TRUE(std::filesystem::is_directory(b)) << b;
}
