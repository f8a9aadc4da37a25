// Comparing rendered frames: per-image statistics, pass/fail thresholds, and
// matching the frames of two output directories by file name.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

#include "image.h"

namespace dmmr {

// Statistics over the R, G and B channels. Alpha is ignored: renderers differ
// in what they leave there and it does not reach the viewer.
struct ImageDiff {
  int64_t pixels = 0;
  int64_t differing_pixels = 0;                           // pixels where any of R, G, B differ
  int max_channel_diff = 0;                               // largest |a - b| over R, G, B (0..255)
  double mse = 0;                                         // mean squared error per channel
  double psnr = std::numeric_limits<double>::infinity();  // +inf when mse == 0
};
std::ostream& operator<<(std::ostream& os, const ImageDiff& d);

// 10 * log10(255^2 / mse); +infinity for mse == 0.
double psnrFromMse(double mse);

// Throws Error (without a file name) when the sizes differ. Requires
// consistent images.
ImageDiff compareImages(const Image& a, const Image& b);
// Reads both files and compares them; Errors name the offending file.
ImageDiff compareImageFiles(const std::string& a, const std::string& b);

// The statistics of all frames taken as one image (their concatenation):
// counts add, max_channel_diff is the maximum, mse is pixel-weighted.
ImageDiff combineDiffs(const std::vector<ImageDiff>& diffs);

// The defaults demand identity. A diff passes when psnr >= min_psnr and
// differing_pixels <= max_differing.
struct CompareThresholds {
  double min_psnr = std::numeric_limits<double>::infinity();
  int64_t max_differing = 0;
};
bool meetsThresholds(const ImageDiff& d, const CompareThresholds& t);
// Why `d` fails `t` ("12 differing pixels > 0; psnr 31.20 < 40.00"), or ""
// when it passes.
std::string thresholdFailure(const ImageDiff& d, const CompareThresholds& t);

struct FrameDiff {
  std::string name;  // file name, without directory
  ImageDiff diff;
};

// Compares the regular files named *.png (lower-case extension) directly in
// directories a and b, matched by file name, in sorted name order. Throws
// Error naming the file when a frame exists in only one directory, when the
// frames cannot be read or differ in size, and naming the directory when it
// cannot be listed or both hold no PNG files.
std::vector<FrameDiff> compareDirectories(const std::string& a, const std::string& b);

// Formats a PSNR with two decimals, or "inf".
std::string formatPsnr(double psnr);

}  // namespace dmmr
