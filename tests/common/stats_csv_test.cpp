// Resuming a stats CSV: rows before the resume frame kept, another run's
// file refused with its name and line.
#include <gtest/gtest.h>

#include <fstream>

#include "stats_csv.h"
#include "test_support.h"

using namespace dmmr;
using dmmr::test::TempDir;

namespace {
const std::string kHeader = "frame,frame_ms,triangles\n";
std::string write(const TempDir& d, const std::string& text) {
  std::string path = d / "stats.csv";
  std::ofstream(path) << text;
  return path;
}
}  // namespace

TEST(ResumeStatsCsv, KeepsTheRowsBeforeTheResumeFrame) {
  TempDir d;
  std::string path = write(d, kHeader + "0,1.5,10\n1,2.5,20\n2,3.5,30\n");
  EXPECT_EQ(resumeStatsCsv(path, kHeader, 2), kHeader + "0,1.5,10\n1,2.5,20\n");
  EXPECT_EQ(resumeStatsCsv(path, kHeader, 9), kHeader + "0,1.5,10\n1,2.5,20\n2,3.5,30\n");
}

TEST(ResumeStatsCsv, StartsFreshFromFrameZeroOrWithoutAFile) {
  TempDir d;
  std::string path = write(d, "something else entirely\n");
  EXPECT_EQ(resumeStatsCsv(path, kHeader, 0), kHeader);
  EXPECT_EQ(resumeStatsCsv(d / "missing.csv", kHeader, 5), kHeader);
  EXPECT_EQ(resumeStatsCsv("", kHeader, 5), kHeader);
}

TEST(ResumeStatsCsv, RejectsAnotherRunsColumns) {
  TempDir d;
  std::string path = write(d, "frame,frame_ms\n0,1\n");
  std::string e = test::errorOf([&] { resumeStatsCsv(path, kHeader, 1); });
  EXPECT_NE(e.find(path + ":1:"), std::string::npos) << e;
  EXPECT_NE(e.find("header differs"), std::string::npos) << e;
}

TEST(ResumeStatsCsv, RejectsARowWithoutAFrameNumber) {
  TempDir d;
  std::string path = write(d, kHeader + "0,1,2\nx,1,2\n");
  std::string e = test::errorOf([&] { resumeStatsCsv(path, kHeader, 1); });
  EXPECT_NE(e.find(path + ":3:"), std::string::npos) << e;
  EXPECT_NE(e.find("frame number"), std::string::npos) << e;
  write(d, kHeader + "99999999999999999999,1,2\n");
  EXPECT_NE(test::errorOf([&] { resumeStatsCsv(path, kHeader, 1); }).find("frame number"),
            std::string::npos);
}

// A kill during an append leaves the last row without its newline: resuming
// drops it (its frame is rendered again) and keeps every whole row.
TEST(ResumeStatsCsv, DropsARowTornByAnInterruptedAppend) {
  TempDir d;
  std::string path = write(d, kHeader + "0,1.5,10\n1,2.5,20\n2,3.");
  EXPECT_EQ(resumeStatsCsv(path, kHeader, 9), kHeader + "0,1.5,10\n1,2.5,20\n");
}

TEST(StatsCsvAppender, WritesTheStartThenAppendsWholeRows) {
  TempDir d;
  std::string path = d / "stats.csv";
  write(d, "an older run's file, replaced\n");
  {
    StatsCsvAppender csv(path, kHeader + "0,1.5,10\n");
    csv.append("1,2.5,20\n");
    csv.append("2,3.5,30\n");
    std::ifstream in(path);  // readable between appends: a run's progress
    std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    EXPECT_EQ(text, kHeader + "0,1.5,10\n1,2.5,20\n2,3.5,30\n");
  }
  EXPECT_EQ(resumeStatsCsv(path, kHeader, 2), kHeader + "0,1.5,10\n1,2.5,20\n");
}

TEST(StatsCsvAppender, AnEmptyPathWritesNothing) {
  EXPECT_NO_THROW({
    StatsCsvAppender csv("", kHeader);
    csv.append("0,1.5,10\n");
  });
}

TEST(StatsCsvAppender, AnUnwritableDirectoryIsAnErrorNamingTheFile) {
  TempDir d;
  std::string path = d / "missing-dir/stats.csv";
  EXPECT_NE(test::errorOf([&] { StatsCsvAppender csv(path, kHeader); }).find(path),
            std::string::npos);
}
