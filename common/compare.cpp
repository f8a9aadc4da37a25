#include "compare.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iterator>
#include <limits>
#include <ostream>
#include <system_error>

#include "error.h"

namespace dmmr {

namespace fs = std::filesystem;

namespace {

std::string sizeText(const Image& image) {
  return std::to_string(image.width) + "x" + std::to_string(image.height);
}

// Sorted names of the *.png regular files directly in `dir`.
std::vector<std::string> listPngs(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(fileError(dir, "not a directory"));
  std::vector<std::string> names;
  fs::directory_iterator it(dir, ec), end;
  for (; !ec && it != end; it.increment(ec)) {
    std::error_code type_ec;  // a dangling link is no frame; skip it
    if (it->path().extension() == ".png" && it->is_regular_file(type_ec))
      names.push_back(it->path().filename().string());
  }
  if (ec) throw Error(fileError(dir, "cannot list: " + ec.message()));
  std::sort(names.begin(), names.end());
  return names;
}

std::string joinPath(const std::string& dir, const std::string& name) {
  return (fs::path(dir) / name).string();
}

[[noreturn]] void throwUnmatched(const std::string& dir, const std::string& name,
                                 const std::string& other_dir) {
  throw Error(fileError(joinPath(dir, name), "no frame of that name in " + other_dir));
}

}  // namespace

std::ostream& operator<<(std::ostream& os, const ImageDiff& d) {
  return os << "pixels=" << d.pixels << " differing_pixels=" << d.differing_pixels
            << " max_channel_diff=" << d.max_channel_diff << " mse=" << d.mse
            << " psnr=" << formatPsnr(d.psnr);
}

double psnrFromMse(double mse) {
  if (mse <= 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

ImageDiff compareImages(const Image& a, const Image& b) {
  DMMR_CHECK(a.consistent() && b.consistent());
  if (a.width != b.width || a.height != b.height)
    throw Error("image sizes differ: " + sizeText(a) + " vs " + sizeText(b));
  ImageDiff d;
  d.pixels = a.pixelCount();
  uint64_t sum_sq = 0;  // exact: at most 3 * 255^2 per pixel
  const uint8_t* pa = a.rgba.data();
  const uint8_t* pb = b.rgba.data();
  for (int64_t i = 0; i < d.pixels; ++i, pa += 4, pb += 4) {
    int dr = std::abs(pa[0] - pb[0]), dg = std::abs(pa[1] - pb[1]), db = std::abs(pa[2] - pb[2]);
    d.differing_pixels += (dr | dg | db) != 0;
    d.max_channel_diff = std::max({d.max_channel_diff, dr, dg, db});
    sum_sq += uint64_t(dr * dr + dg * dg + db * db);
  }
  d.mse = d.pixels > 0 ? double(sum_sq) / (3.0 * double(d.pixels)) : 0.0;
  d.psnr = psnrFromMse(d.mse);
  return d;
}

ImageDiff compareImageFiles(const std::string& a, const std::string& b) {
  Image ia = readPng(a);
  Image ib = readPng(b);
  if (ia.width != ib.width || ia.height != ib.height) {
    throw Error(
        fileError(b, "size " + sizeText(ib) + " differs from " + a + " (" + sizeText(ia) + ")"));
  }
  return compareImages(ia, ib);
}

ImageDiff combineDiffs(const std::vector<ImageDiff>& diffs) {
  ImageDiff total;
  double weighted_mse = 0;
  for (const ImageDiff& d : diffs) {
    total.pixels += d.pixels;
    total.differing_pixels += d.differing_pixels;
    total.max_channel_diff = std::max(total.max_channel_diff, d.max_channel_diff);
    weighted_mse += d.mse * double(d.pixels);
  }
  total.mse = total.pixels > 0 ? weighted_mse / double(total.pixels) : 0.0;
  total.psnr = psnrFromMse(total.mse);
  return total;
}

bool meetsThresholds(const ImageDiff& d, const CompareThresholds& t) {
  return d.psnr >= t.min_psnr && d.differing_pixels <= t.max_differing;
}

std::string thresholdFailure(const ImageDiff& d, const CompareThresholds& t) {
  std::string why;
  if (d.differing_pixels > t.max_differing) {
    why = std::to_string(d.differing_pixels) + " differing pixels > " +
          std::to_string(t.max_differing);
  }
  if (!(d.psnr >= t.min_psnr)) {
    if (!why.empty()) why += "; ";
    why += "psnr " + formatPsnr(d.psnr) + " < " + formatPsnr(t.min_psnr);
  }
  return why;
}

std::vector<FrameDiff> compareDirectories(const std::string& a, const std::string& b) {
  std::vector<std::string> names_a = listPngs(a);
  std::vector<std::string> names_b = listPngs(b);
  if (names_a.empty() && names_b.empty())
    throw Error(fileError(a, "no *.png frames here nor in " + b));
  std::vector<std::string> only_a, only_b;
  std::set_difference(names_a.begin(), names_a.end(), names_b.begin(), names_b.end(),
                      std::back_inserter(only_a));
  std::set_difference(names_b.begin(), names_b.end(), names_a.begin(), names_a.end(),
                      std::back_inserter(only_b));
  if (!only_a.empty()) throwUnmatched(a, only_a.front(), b);
  if (!only_b.empty()) throwUnmatched(b, only_b.front(), a);

  std::vector<FrameDiff> diffs;
  diffs.reserve(names_a.size());
  for (const std::string& name : names_a)
    diffs.push_back({name, compareImageFiles(joinPath(a, name), joinPath(b, name))});
  return diffs;
}

std::string formatPsnr(double psnr) {
  if (std::isinf(psnr)) return psnr > 0 ? "inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", psnr);
  return buf;
}

}  // namespace dmmr
