// dmmr-compare's command line: exit 0 when every frame meets the thresholds
// (exact identity by default), 1 when one does not, 2 for unusable input.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "image.h"
#include "test_support.h"

using namespace dmmr;
using dmmr::test::TempDir;

namespace {

Image gradient(int w, int h, int bump) {
  Image img = Image::blank(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = img.pixel(x, y);
      p[0] = uint8_t(x * 7 + bump);
      p[1] = uint8_t(y * 5);
      p[2] = 100;
      p[3] = 255;
    }
  return img;
}

int compare(const std::string& args, std::string* out = nullptr) {
  int status = 0;
  std::string log = test::runCapture(test::tool("dmmr-compare") + " " + args, &status);
  if (out) *out = log;
  return status;
}

}  // namespace

TEST(CompareCli, IdenticalDirectoriesPassDifferingOnesFail) {
  TempDir d;
  std::filesystem::create_directories(d / "a");
  std::filesystem::create_directories(d / "b");
  writePng(d / "a/frame_000000.png", gradient(32, 16, 0));
  writePng(d / "b/frame_000000.png", gradient(32, 16, 0));
  writePng(d / "a/frame_000001.png", gradient(32, 16, 0));
  Image changed = gradient(32, 16, 0);
  changed.pixel(3, 4)[0] ^= 0x10;  // one pixel off by 16 in red
  writePng(d / "b/frame_000001.png", changed);

  std::string log;
  EXPECT_EQ(compare(d / "a/frame_000000.png " + d / "b/frame_000000.png"), 0);
  EXPECT_EQ(compare(d / "a " + d / "b", &log), 1) << log;
  EXPECT_NE(log.find("frame_000001.png"), std::string::npos) << log;
  // One pixel of 512 off by 16 in one channel: MSE = 256 / (512 * 3).
  double psnr = 10 * std::log10(255.0 * 255.0 / (256.0 / (512 * 3)));
  EXPECT_EQ(compare(d / "a " + d / "b --max-diff-pixels 1"), 0);
  EXPECT_EQ(compare(d / "a " + d / "b --min-psnr " + std::to_string(psnr - 0.01)), 0);
  EXPECT_EQ(compare(d / "a " + d / "b --min-psnr " + std::to_string(psnr + 0.01)), 1);
}

TEST(CompareCli, MissingInputIsAUsageError) {
  TempDir d;
  std::string log;
  EXPECT_EQ(compare(d / "nope " + d / "nope2", &log), 2);
  EXPECT_NE(log.find("dmmr-compare:"), std::string::npos) << log;
  // A directory against a missing path names the missing one.
  std::filesystem::create_directories(d / "frames");
  EXPECT_EQ(compare(d / "frames " + d / "gone", &log), 2);
  EXPECT_NE(log.find(d / "gone" + ": no such file or directory"), std::string::npos) << log;
}

TEST(CompareCli, ANanThresholdIsAUsageError) {
  TempDir d;
  std::string log;
  EXPECT_EQ(compare(d / "a " + d / "b --min-psnr nan", &log), 2);
  EXPECT_NE(log.find("NaN"), std::string::npos) << log;
}
