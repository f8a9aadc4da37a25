// Run settings beside a run's frames (run_settings.h): written and read back,
// and what a resume is checked for.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "error.h"
#include "run_settings.h"
#include "test_support.h"
#include "walkthrough.h"

using namespace dmmr;
using dmmr::test::TempDir;

namespace {
RunSettings sample() {
  ViewOptions v;
  v.width = 256, v.height = 200, v.fovy_deg = 45.5;
  RunSettings s = baseRunSettings("scene", "walk.path", v);
  s.add("renderer", "raster");
  return s;
}
void touch(const std::string& path) {
  std::ofstream(path) << "x";
}
}  // namespace

TEST(RunSettings, FormatsAndParsesBack) {
  RunSettings s = sample();
  EXPECT_EQ(parseRunSettings(formatRunSettings(s), "f"), s);
  EXPECT_EQ(s.values[2], (std::pair<std::string, std::string>{"width", "256"}));
  EXPECT_TRUE(std::filesystem::path(s.values[0].second).is_absolute());
  // A served run has no walkthrough: none, not an error.
  EXPECT_EQ(baseRunSettings("scene", "", ViewOptions{}).values[1].second, "");
}

TEST(RunSettings, ParseRejectsAnotherFileAndBadLines) {
  std::string e = test::errorOf([] { parseRunSettings("something else\n", "d/run-settings.txt"); });
  EXPECT_NE(e.find("d/run-settings.txt:1:"), std::string::npos) << e;
  e = test::errorOf([] { parseRunSettings("dmmr run settings 1\nwidth\n", "f"); });
  EXPECT_NE(e.find("f:2: expected NAME=VALUE"), std::string::npos) << e;
}

TEST(RunSettings, ResumeNeedsEveryEarlierFrameAndTheSameSettings) {
  TempDir dir;
  RunSettings s = sample();
  writeRunSettings(dir.path(), s);
  touch(dir / frameFileName(0));
  touch(dir / frameFileName(2));
  std::string e = test::errorOf([&] { checkResume(dir.path(), s, 3); });
  EXPECT_NE(e.find(frameFileName(1) + ": missing"), std::string::npos) << e;
  EXPECT_NE(e.find("resume from frame 1 or earlier"), std::string::npos) << e;
  EXPECT_EQ(test::errorOf([&] { checkResume(dir.path(), s, 1); }), "");
  RunSettings other = s;
  other.values[2].second = "512";
  other.add("shadows", "on");
  e = test::errorOf([&] { checkResume(dir.path(), other, 1); });
  EXPECT_NE(e.find("width was 256, now 512"), std::string::npos) << e;
  EXPECT_NE(e.find("shadows was (none), now on"), std::string::npos) << e;
  std::filesystem::remove(dir / kRunSettingsFile);
  e = test::errorOf([&] { checkResume(dir.path(), s, 1); });
  EXPECT_NE(e.find("run-settings.txt: missing"), std::string::npos) << e;
}

// Frames K on into a directory holding nothing of the run: a part of a
// walkthrough rendered by itself, which mixes nothing.
TEST(RunSettings, FramesFromKIntoAnEmptyDirectoryAreNoResume) {
  TempDir dir;
  EXPECT_EQ(test::errorOf([&] { checkResume(dir.path(), sample(), 16); }), "");
  touch(dir / frameFileName(20));  // a later frame is not an earlier one
  EXPECT_EQ(test::errorOf([&] { checkResume(dir.path(), sample(), 16); }), "");
}
