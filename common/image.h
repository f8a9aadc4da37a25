// RGBA8 images and their PNG files. Rendered frames are written as PNG and
// compared bit for bit, so reading and writing must round-trip exactly: no
// gamma or colour management is applied in either direction.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "math.h"

namespace dmmr {

// Pixels are RGBA, 4 bytes each, rows stored top row first (as in PNG; GL
// reads back bottom-up, see flipRows). Kept an aggregate so `Image{w, h, px}`
// works; a valid image has rgba.size() == width * height * 4.
struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;

  // A width x height image of transparent black. Requires width, height >= 0.
  static Image blank(int width, int height);

  size_t rowBytes() const { return size_t(width) * 4; }
  int64_t pixelCount() const { return int64_t(width) * height; }
  bool empty() const { return width == 0 || height == 0; }
  // True when rgba holds exactly width * height * 4 bytes.
  bool consistent() const;

  // No bounds checks: these sit in per-pixel loops. Require 0 <= x < width,
  // 0 <= y < height.
  uint8_t* row(int y) { return rgba.data() + size_t(y) * rowBytes(); }
  const uint8_t* row(int y) const { return rgba.data() + size_t(y) * rowBytes(); }
  uint8_t* pixel(int x, int y) { return row(y) + size_t(x) * 4; }
  const uint8_t* pixel(int x, int y) const { return row(y) + size_t(x) * 4; }

  friend bool operator==(const Image&, const Image&) = default;
};

// Encodes as 8-bit RGBA PNG. compression_level is zlib's 0..9; the default 1
// is fast because a walkthrough writes thousands of frames. Requires a
// consistent image; an empty one (no pixels, which PNG cannot hold) throws
// Error.
std::vector<uint8_t> encodePng(const Image& image, int compression_level = 1);
// encodePng, then written atomically (temporary file, then rename). Throws
// Error naming `path` when the image is empty or the file cannot be written.
void writePng(const std::string& path, const Image& image, int compression_level = 1);

// Decodes an 8-bit PNG of colour type RGB, RGBA, gray or gray+alpha (also
// interlaced) into RGBA: gray is replicated to R, G and B, missing alpha
// becomes 255 (or 0 where a tRNS chunk marks the colour transparent).
// Throws Error naming `name` for any other format (palette, 16-bit, < 8-bit)
// and for data that is not PNG, corrupt (bad CRC of a critical chunk, bad
// zlib data) or truncated (the file must reach IEND).
Image decodePng(std::span<const uint8_t> bytes, const std::string& name);
// Reads and decodes a file; throws Error naming `path` as decodePng does, or
// when the file cannot be read.
Image readPng(const std::string& path);

// Drops the alpha channel: `pixels` RGBA pixels from `rgba` to RGB in
// `rgb` (3 * pixels bytes, written and nothing beyond).
void rgbaToRgb(const uint8_t* rgba, size_t pixels, uint8_t* rgb);

// Reverses the row order: converts GL's bottom-up glReadPixels result to
// top-down and back. Requires a consistent image.
Image flipRows(const Image& image);
void flipRowsInPlace(Image& image);

// Copies a sub-frame into `frame`: `rgb` holds region.w x region.h RGB8
// pixels, rows bottom first as GL reads them back, with region in GL's
// coordinates (origin bottom-left); alpha becomes 255. The region comes from
// a peer: throws Error when it is not inside the frame (checked in 64-bit)
// or `rgb` does not hold exactly its pixels, and writes nothing then.
void placeRgbRegion(Image& frame, const Rect& region, std::span<const uint8_t> rgb);

}  // namespace dmmr
