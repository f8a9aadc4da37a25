#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "compare.h"
#include "error.h"
#include "image.h"
#include "test_support.h"

namespace dmmr {
namespace {

namespace fs = std::filesystem;

// A fresh directory per test, removed afterwards.
class ImageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("dmmr_image_test_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

Image randomImage(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  Image image = Image::blank(width, height);
  for (uint8_t& b : image.rgba) b = uint8_t(byte(rng));
  return image;
}

// Expects `f` to throw dmmr::Error whose message contains `needle`.
template <typename F>
void expectErrorMentioning(F&& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no dmmr::Error thrown; expected one mentioning " << needle;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << "message: " << e.what() << "\nexpected to contain: " << needle;
  }
}

// --- A minimal PNG writer independent of libpng, so the reader is tested on
// formats writePng never produces. Deflate uses stored (uncompressed) blocks.

uint32_t crc32(const std::vector<uint8_t>& data, size_t begin) {
  uint32_t c = 0xffffffffu;
  for (size_t i = begin; i < data.size(); ++i) {
    c ^= data[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  return ~c;
}

void putBe32(std::vector<uint8_t>& out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(uint8_t(v >> shift));
}

void appendChunk(std::vector<uint8_t>& png, const char* type, const std::vector<uint8_t>& data) {
  putBe32(png, uint32_t(data.size()));
  std::vector<uint8_t> body(type, type + 4);
  body.insert(body.end(), data.begin(), data.end());
  png.insert(png.end(), body.begin(), body.end());
  putBe32(png, crc32(body, 0));
}

std::vector<uint8_t> zlibStored(const std::vector<uint8_t>& raw) {
  std::vector<uint8_t> z = {0x78, 0x01};
  size_t pos = 0;
  do {
    size_t n = std::min<size_t>(raw.size() - pos, 65535);
    z.push_back(pos + n == raw.size() ? 1 : 0);  // BFINAL, BTYPE = stored
    z.push_back(uint8_t(n));
    z.push_back(uint8_t(n >> 8));
    z.push_back(uint8_t(~n));
    z.push_back(uint8_t(~n >> 8));
    z.insert(z.end(), raw.begin() + long(pos), raw.begin() + long(pos + n));
    pos += n;
  } while (pos < raw.size());
  uint32_t a = 1, b = 0;
  for (uint8_t v : raw) a = (a + v) % 65521, b = (b + a) % 65521;
  putBe32(z, (b << 16) | a);
  return z;
}

// `rows` holds each row's bytes as stored (without the filter byte).
std::vector<uint8_t> makePng(uint32_t width, uint32_t height, int bit_depth, int color_type,
                             const std::vector<std::vector<uint8_t>>& rows,
                             const std::vector<uint8_t>& palette = {}) {
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<uint8_t> ihdr;
  putBe32(ihdr, width);
  putBe32(ihdr, height);
  ihdr.insert(ihdr.end(), {uint8_t(bit_depth), uint8_t(color_type), 0, 0, 0});
  appendChunk(png, "IHDR", ihdr);
  if (!palette.empty()) appendChunk(png, "PLTE", palette);
  std::vector<uint8_t> raw;
  for (const auto& row : rows) {
    raw.push_back(0);  // filter: none
    raw.insert(raw.end(), row.begin(), row.end());
  }
  appendChunk(png, "IDAT", zlibStored(raw));
  appendChunk(png, "IEND", {});
  return png;
}

// --- PNG reading and writing

TEST_F(ImageTest, PngRoundTripIsBitExact) {
  const int sizes[][2] = {{1, 1}, {3, 7}, {1024, 1}, {1, 1024}, {257, 33}};
  uint32_t seed = 1;
  for (const auto& size : sizes) {
    for (int level : {0, 1, 9}) {
      Image image = randomImage(size[0], size[1], seed++);
      std::string file = path("frame.png");
      writePng(file, image, level);
      EXPECT_EQ(readPng(file), image) << size[0] << "x" << size[1] << " level " << level;
    }
  }
}

TEST_F(ImageTest, HighlyCompressedImageRoundTrips) {
  // Guards the reader's "too little data for the size" check against false alarms.
  Image image = Image::blank(2048, 2048);
  image.pixel(2047, 2047)[0] = 7;
  std::string file = path("flat.png");
  writePng(file, image, 9);
  EXPECT_LT(fs::file_size(file), image.rgba.size() / 500);
  EXPECT_EQ(readPng(file), image);
}

TEST_F(ImageTest, EncodeDecodeInMemory) {
  Image image = randomImage(5, 4, 99);
  EXPECT_EQ(decodePng(encodePng(image), "mem"), image);
}

TEST_F(ImageTest, ReadsGrayRgbAndGrayAlphaAsRgba) {
  std::vector<uint8_t> gray = makePng(3, 1, 8, 0, {{10, 20, 30}});
  std::vector<uint8_t> rgb = makePng(2, 1, 8, 2, {{1, 2, 3, 4, 5, 6}});
  std::vector<uint8_t> gray_alpha = makePng(2, 1, 8, 4, {{40, 50, 60, 70}});
  EXPECT_EQ(decodePng(gray, "g"),
            (Image{3, 1, {10, 10, 10, 255, 20, 20, 20, 255, 30, 30, 30, 255}}));
  EXPECT_EQ(decodePng(rgb, "rgb"), (Image{2, 1, {1, 2, 3, 255, 4, 5, 6, 255}}));
  EXPECT_EQ(decodePng(gray_alpha, "ga"), (Image{2, 1, {40, 40, 40, 50, 60, 60, 60, 70}}));
}

TEST_F(ImageTest, RejectsUnsupportedFormatsNamingFile) {
  std::vector<std::vector<uint8_t>> pngs = {
      makePng(1, 1, 16, 2, {{0, 1, 0, 2, 0, 3}}),         // 16-bit RGB
      makePng(2, 1, 8, 3, {{0, 1}}, {9, 9, 9, 8, 8, 8}),  // palette
      makePng(8, 1, 1, 0, {{0x55}}),                      // 1-bit gray
  };
  for (size_t i = 0; i < pngs.size(); ++i) {
    std::string file = path("unsupported" + std::to_string(i) + ".png");
    writeFileAtomic(file, pngs[i]);
    expectErrorMentioning([&] { readPng(file); }, file);
  }
}

TEST_F(ImageTest, EveryTruncationThrowsNamingFile) {
  std::vector<uint8_t> png = encodePng(randomImage(6, 5, 3));
  for (size_t cut = 0; cut < png.size(); ++cut) {
    std::vector<uint8_t> prefix(png.begin(), png.begin() + long(cut));
    expectErrorMentioning([&] { decodePng(prefix, "cut.png"); }, "cut.png");
  }
  std::string file = path("truncated.png");
  writeFileAtomic(file, std::vector<uint8_t>(png.begin(), png.begin() + long(png.size() / 2)));
  expectErrorMentioning([&] { readPng(file); }, file);
}

TEST_F(ImageTest, CorruptDataThrowsNamingFile) {
  std::vector<uint8_t> png = encodePng(randomImage(6, 5, 4));
  for (size_t at : {size_t(20), png.size() / 2}) {  // inside IHDR, inside IDAT
    std::vector<uint8_t> bad = png;
    bad[at] ^= 0x40;
    std::string file = path("corrupt.png");
    writeFileAtomic(file, bad);
    expectErrorMentioning([&] { readPng(file); }, file);
  }
}

TEST_F(ImageTest, HugeHeaderInTinyFileThrowsWithoutAllocating) {
  std::vector<uint8_t> png = makePng(100000, 100000, 8, 6, {{1, 2, 3, 4}});
  expectErrorMentioning([&] { decodePng(png, "huge.png"); }, "huge.png");
}

TEST_F(ImageTest, NonPngAndMissingFilesThrowNamingFile) {
  std::string text = path("notes.png");
  writeFileAtomic(text, std::string_view("this is not a PNG file at all\n"));
  expectErrorMentioning([&] { readPng(text); }, text);
  std::string missing = path("missing.png");
  expectErrorMentioning([&] { readPng(missing); }, missing);
}

TEST_F(ImageTest, WritingEmptyImageThrowsNamingFile) {
  std::string file = path("empty.png");
  expectErrorMentioning([&] { writePng(file, Image{}); }, file);
  EXPECT_FALSE(fs::exists(file));
}

TEST_F(ImageTest, FlipRowsReversesRowOrder) {
  for (int height : {1, 2, 3, 4}) {
    Image image = randomImage(3, height, uint32_t(10 + height));
    Image flipped = flipRows(image);
    ASSERT_TRUE(flipped.consistent());
    for (int y = 0; y < height; ++y) {
      std::vector<uint8_t> want(image.row(height - 1 - y), image.row(height - 1 - y) + 12);
      EXPECT_EQ(std::vector<uint8_t>(flipped.row(y), flipped.row(y) + 12), want);
    }
    flipRowsInPlace(flipped);
    EXPECT_EQ(flipped, image);
  }
}

// --- Comparison

TEST(CompareTest, IdenticalImages) {
  Image a = randomImage(13, 9, 5);
  ImageDiff d = compareImages(a, a);
  EXPECT_EQ(d.pixels, 13 * 9);
  EXPECT_EQ(d.differing_pixels, 0);
  EXPECT_EQ(d.max_channel_diff, 0);
  EXPECT_EQ(d.mse, 0.0);
  EXPECT_TRUE(std::isinf(d.psnr) && d.psnr > 0);
  EXPECT_TRUE(meetsThresholds(d, CompareThresholds{}));
}

TEST(CompareTest, OneChangedPixel) {
  Image a = randomImage(13, 9, 6);
  Image b = a;
  uint8_t* p = b.pixel(4, 7);
  p[0] = uint8_t(p[0] >= 128 ? p[0] - 10 : p[0] + 10);
  p[2] = uint8_t(p[2] >= 128 ? p[2] - 3 : p[2] + 3);
  ImageDiff d = compareImages(a, b);
  double mse = (10.0 * 10.0 + 3.0 * 3.0) / (13.0 * 9.0 * 3.0);
  EXPECT_EQ(d.differing_pixels, 1);
  EXPECT_EQ(d.max_channel_diff, 10);
  EXPECT_DOUBLE_EQ(d.mse, mse);
  EXPECT_DOUBLE_EQ(d.psnr, 10.0 * std::log10(255.0 * 255.0 / mse));
  EXPECT_FALSE(meetsThresholds(d, CompareThresholds{}));
  EXPECT_FALSE(thresholdFailure(d, CompareThresholds{}).empty());
  EXPECT_TRUE(meetsThresholds(d, CompareThresholds{.min_psnr = 0, .max_differing = 1}));
  EXPECT_FALSE(
      meetsThresholds(d, CompareThresholds{.min_psnr = d.psnr + 0.01, .max_differing = 1}));
  EXPECT_EQ(thresholdFailure(d, CompareThresholds{.min_psnr = d.psnr, .max_differing = 1}), "");
}

TEST(CompareTest, AlphaIsIgnored) {
  Image a = randomImage(8, 8, 7);
  Image b = a;
  for (size_t i = 3; i < b.rgba.size(); i += 4) b.rgba[i] = uint8_t(~b.rgba[i]);
  ImageDiff d = compareImages(a, b);
  EXPECT_EQ(d.differing_pixels, 0);
  EXPECT_TRUE(std::isinf(d.psnr));
}

TEST(CompareTest, SizeMismatchThrows) {
  EXPECT_THROW(compareImages(Image::blank(4, 3), Image::blank(3, 4)), Error);
}

TEST(CompareTest, CombinedDiffEqualsDiffOfConcatenation) {
  Image a1 = randomImage(7, 3, 8), b1 = randomImage(7, 3, 9);
  Image a2 = randomImage(7, 5, 10), b2 = a2;
  b2.pixel(1, 1)[1] ^= 0x21;
  Image a = a1, b = b1;  // stack frame 2 below frame 1
  a.height += a2.height, b.height += b2.height;
  a.rgba.insert(a.rgba.end(), a2.rgba.begin(), a2.rgba.end());
  b.rgba.insert(b.rgba.end(), b2.rgba.begin(), b2.rgba.end());
  ImageDiff whole = compareImages(a, b);
  ImageDiff combined = combineDiffs({compareImages(a1, b1), compareImages(a2, b2)});
  EXPECT_EQ(combined.pixels, whole.pixels);
  EXPECT_EQ(combined.differing_pixels, whole.differing_pixels);
  EXPECT_EQ(combined.max_channel_diff, whole.max_channel_diff);
  EXPECT_DOUBLE_EQ(combined.mse, whole.mse);
  EXPECT_DOUBLE_EQ(combined.psnr, whole.psnr);
}

TEST_F(ImageTest, CompareImageFilesSizeMismatchNamesFile) {
  writePng(path("a.png"), Image::blank(2, 2));
  writePng(path("b.png"), Image::blank(2, 3));
  expectErrorMentioning([&] { compareImageFiles(path("a.png"), path("b.png")); }, path("b.png"));
}

class CompareDirTest : public ImageTest {
 protected:
  void SetUp() override {
    ImageTest::SetUp();
    fs::create_directories(path("a"));
    fs::create_directories(path("b"));
  }
  // Writes the same random frame to both a/ and b/.
  void writeBoth(const std::string& name, uint32_t seed) {
    Image image = randomImage(4, 3, seed);
    writePng(path("a/" + name), image);
    writePng(path("b/" + name), image);
  }
};

TEST_F(CompareDirTest, MatchesFramesByNameInSortedOrder) {
  writeBoth("f2.png", 2);
  writeBoth("f1.png", 1);
  writeBoth("f3.png", 3);
  writeFileAtomic(path("a/notes.txt"), std::string_view("ignored"));
  Image changed = readPng(path("b/f2.png"));
  changed.pixel(0, 0)[0] ^= 1;
  writePng(path("b/f2.png"), changed);

  std::vector<FrameDiff> diffs = compareDirectories(path("a"), path("b"));
  ASSERT_EQ(diffs.size(), 3u);
  EXPECT_EQ(diffs[0].name, "f1.png");
  EXPECT_EQ(diffs[1].name, "f2.png");
  EXPECT_EQ(diffs[2].name, "f3.png");
  EXPECT_EQ(diffs[0].diff.differing_pixels, 0);
  EXPECT_EQ(diffs[1].diff.differing_pixels, 1);
  EXPECT_EQ(diffs[1].diff.max_channel_diff, 1);
  EXPECT_TRUE(std::isinf(diffs[2].diff.psnr));
}

TEST_F(CompareDirTest, FrameMissingFromEitherSideThrowsNamingIt) {
  writeBoth("f1.png", 1);
  writePng(path("a/f2.png"), randomImage(4, 3, 2));
  expectErrorMentioning([&] { compareDirectories(path("a"), path("b")); }, "f2.png");
  expectErrorMentioning([&] { compareDirectories(path("b"), path("a")); }, "f2.png");
}

TEST_F(CompareDirTest, NoFramesThrows) {
  expectErrorMentioning([&] { compareDirectories(path("a"), path("b")); }, path("a"));
  expectErrorMentioning([&] { compareDirectories(path("a"), path("nope")); }, path("nope"));
}

// rgbaToRgb against the channel loop it replaced, on random pixels: the
// same bytes, and nothing written past 3 * pixels (guard bytes stay).
TEST(RgbaToRgb, MatchesAChannelLoopAndWritesNothingPastTheEnd) {
  std::mt19937 rng(14);
  for (size_t pixels : {0u, 1u, 2u, 3u, 7u, 64u, 1000u, 4099u}) {
    std::vector<uint8_t> rgba(pixels * 4);
    for (uint8_t& b : rgba) b = uint8_t(rng());
    std::vector<uint8_t> want(pixels * 3);
    for (size_t i = 0; i < pixels; ++i)
      for (size_t c = 0; c < 3; ++c) want[i * 3 + c] = rgba[i * 4 + c];
    std::vector<uint8_t> got(pixels * 3 + 8, 0xA5);
    rgbaToRgb(rgba.data(), pixels, got.data());
    EXPECT_TRUE(std::equal(want.begin(), want.end(), got.begin())) << pixels;
    EXPECT_TRUE(std::all_of(got.begin() + long(pixels * 3), got.end(), [](uint8_t b) {
      return b == 0xA5;
    })) << pixels;
  }
}

}  // namespace
}  // namespace dmmr

namespace dmmr {

// A sub-frame lands flipped (GL rows bottom first) at its place, alpha 255.
TEST(PlaceRgbRegion, CopiesASubFrameFlippedIntoPlace) {
  Image frame = Image::blank(4, 3);
  std::vector<uint8_t> rgb;
  for (int i = 0; i < 2 * 2 * 3; ++i) rgb.push_back(uint8_t(10 + i));
  placeRgbRegion(frame, Rect{1, 0, 2, 2}, rgb);  // GL rows 0, 1: image rows 2, 1
  EXPECT_EQ(std::vector<uint8_t>(frame.pixel(1, 2), frame.pixel(1, 2) + 4),
            (std::vector<uint8_t>{10, 11, 12, 255}));
  EXPECT_EQ(std::vector<uint8_t>(frame.pixel(2, 1), frame.pixel(2, 1) + 4),
            (std::vector<uint8_t>{19, 20, 21, 255}));
  EXPECT_EQ(frame.pixel(0, 0)[3], 0) << "outside the region: untouched";
  EXPECT_EQ(frame.pixel(3, 2)[3], 0);
}

// A peer's region near INT_MAX: x + w overflows int. The old check
// (`x + w > width` in int) let it through and the copy wrote outside the
// image; now it is an Error and nothing is written (ASan covers the suite).
TEST(PlaceRgbRegion, RejectsARegionWhoseEndOverflowsInt) {
  Image frame = Image::blank(64, 48);
  const Image before = frame;
  constexpr int kMax = std::numeric_limits<int>::max();
  std::vector<uint8_t> rgb(size_t(100) * 3, 7);
  std::string e = test::errorOf([&] { placeRgbRegion(frame, Rect{kMax - 10, 0, 100, 1}, rgb); });
  EXPECT_NE(e.find("not inside the 64x48 frame"), std::string::npos) << e;
  EXPECT_NE(test::errorOf([&] { placeRgbRegion(frame, Rect{0, kMax - 1, 100, 1}, rgb); }), "");
  EXPECT_EQ(frame, before);
}

TEST(PlaceRgbRegion, RejectsPixelsThatDoNotFillTheRegion) {
  Image frame = Image::blank(8, 8);
  std::vector<uint8_t> rgb(size_t(4) * 4 * 3 - 1);
  EXPECT_NE(test::errorOf([&] {
              placeRgbRegion(frame, Rect{0, 0, 4, 4}, rgb);
            }).find("bytes"),
            std::string::npos);
  EXPECT_NE(test::errorOf([&] { placeRgbRegion(frame, Rect{6, 6, 4, 4}, rgb); }), "");
}

}  // namespace dmmr
