// dmmr-compare A B: compares two rendered frames (PNG files) or two directories
// of frames matched by name. Exit status: 0 when every frame meets the
// thresholds, 1 when any does not, 2 on usage or I/O errors.
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "compare.h"
#include "error.h"

namespace {

using dmmr::CompareThresholds;
using dmmr::FrameDiff;
namespace fs = std::filesystem;

constexpr int kPass = 0, kFail = 1, kError = 2;

struct Options {
  std::string a, b, csv;
  double min_psnr = 0;
  int64_t max_diff_pixels = 0;
  bool has_min_psnr = false, has_max_diff = false;
};

// No threshold given: demand identity. Only one given: the other is unbounded,
// so that e.g. --min-psnr alone accepts many slightly differing pixels.
CompareThresholds thresholdsFrom(const Options& o) {
  CompareThresholds t;
  if (!o.has_min_psnr && !o.has_max_diff) return t;
  t.min_psnr = o.has_min_psnr ? o.min_psnr : -std::numeric_limits<double>::infinity();
  t.max_differing = o.has_max_diff ? o.max_diff_pixels : std::numeric_limits<int64_t>::max();
  return t;
}

std::vector<FrameDiff> compareInputs(const Options& o) {
  for (const std::string& p : {o.a, o.b})
    if (!fs::exists(p)) throw dmmr::Error(dmmr::fileError(p, "no such file or directory"));
  bool dir_a = fs::is_directory(o.a), dir_b = fs::is_directory(o.b);
  if (dir_a != dir_b)
    throw dmmr::Error("A and B must both be PNG files or both directories (" + o.a + " is " +
                      (dir_a ? "a directory" : "a file") + ", " + o.b + " is " +
                      (dir_b ? "a directory" : "a file") + ")");
  if (dir_a) return dmmr::compareDirectories(o.a, o.b);
  return {{fs::path(o.a).filename().string(), dmmr::compareImageFiles(o.a, o.b)}};
}

size_t nameWidth(const std::vector<FrameDiff>& frames) {
  size_t w = 5;  // "total"
  for (const FrameDiff& f : frames) w = std::max(w, f.name.size());
  return w;
}

void printTable(const std::vector<FrameDiff>& frames, const dmmr::ImageDiff& total) {
  int w = int(nameWidth(frames));
  std::printf("%-*s  %8s  %16s  %16s\n", w, "frame", "psnr", "differing_pixels",
              "max_channel_diff");
  double min_psnr = std::numeric_limits<double>::infinity();
  for (const FrameDiff& f : frames) {
    std::printf("%-*s  %8s  %16lld  %16d\n", w, f.name.c_str(),
                dmmr::formatPsnr(f.diff.psnr).c_str(),
                static_cast<long long>(f.diff.differing_pixels), f.diff.max_channel_diff);
    min_psnr = std::min(min_psnr, f.diff.psnr);
  }
  std::printf("total: frames %zu, differing pixels %lld, min psnr %s, psnr of all frames %s\n",
              frames.size(), static_cast<long long>(total.differing_pixels),
              dmmr::formatPsnr(min_psnr).c_str(), dmmr::formatPsnr(total.psnr).c_str());
}

// Quotes a CSV field when it holds a separator, quote or line break.
std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

void writeCsv(const std::string& path, const std::vector<FrameDiff>& frames,
              const CompareThresholds& t) {
  std::ostringstream os;
  os << "frame,pixels,differing_pixels,max_channel_diff,mse,psnr,pass\n";
  os.precision(17);  // mse round-trips
  for (const FrameDiff& f : frames) {
    os << csvField(f.name) << ',' << f.diff.pixels << ',' << f.diff.differing_pixels << ','
       << f.diff.max_channel_diff << ',' << f.diff.mse << ',' << dmmr::formatPsnr(f.diff.psnr)
       << ',' << (dmmr::meetsThresholds(f.diff, t) ? 1 : 0) << '\n';
  }
  dmmr::writeFileAtomic(path, os.str());
}

// Prints the failing frames; returns how many there are.
size_t reportFailures(const std::vector<FrameDiff>& frames, const CompareThresholds& t) {
  size_t failed = 0;
  for (const FrameDiff& f : frames) {
    std::string why = dmmr::thresholdFailure(f.diff, t);
    if (why.empty()) continue;
    std::printf("FAIL %s: %s\n", f.name.c_str(), why.c_str());
    ++failed;
  }
  if (failed > 0) std::printf("%zu of %zu frames fail the thresholds\n", failed, frames.size());
  return failed;
}

// CLI::NonNegativeNumber's message prints the largest double in full.
CLI::Validator nonNegative() {
  return CLI::Validator(
      [](std::string& s) { return s.starts_with('-') ? std::string("must not be negative") : ""; },
      "NONNEGATIVE");
}

int run(const Options& o) {
  CompareThresholds t = thresholdsFrom(o);
  std::vector<FrameDiff> frames = compareInputs(o);
  std::vector<dmmr::ImageDiff> diffs;
  for (const FrameDiff& f : frames) diffs.push_back(f.diff);
  printTable(frames, dmmr::combineDiffs(diffs));
  if (!o.csv.empty()) writeCsv(o.csv, frames, t);
  return reportFailures(frames, t) == 0 ? kPass : kFail;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "Compares two PNG frames, or two directories of PNG frames matched by file name, over "
      "R, G and B (alpha is ignored). With no threshold given every frame must be identical; "
      "with one given the other is unbounded.\nExit status: 0 all frames pass, 1 some fail, "
      "2 usage or I/O error.",
      "dmmr-compare"};
  app.add_option("A", o.a, "PNG file or directory of PNG files")->required();
  app.add_option("B", o.b, "PNG file or directory of PNG files (same kind as A)")->required();
  auto* psnr_opt =
      app.add_option("--min-psnr", o.min_psnr, "lowest acceptable PSNR (dB)")
          ->check(CLI::Validator(
              [](std::string& v) {
                double x = 0;
                try {
                  x = std::stod(v);
                } catch (const std::exception&) {
                  return std::string("not a number");
                }
                return std::isnan(x) ? std::string("not a number (NaN)") : std::string();
              },
              "dB", "not NaN"));
  auto* diff_opt = app.add_option("--max-diff-pixels", o.max_diff_pixels,
                                  "most pixels allowed to differ in a frame")
                       ->check(nonNegative());
  app.add_option("--csv", o.csv, "also write per-frame results to this CSV file");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help
    std::cerr << "dmmr-compare: " << e.what() << "\nRun with --help for more information.\n";
    return kError;
  }
  o.has_min_psnr = psnr_opt->count() > 0;
  o.has_max_diff = diff_opt->count() > 0;
  try {
    return run(o);
  } catch (const std::exception& e) {  // dmmr::Error and also e.g. bad_alloc
    std::fflush(stdout);
    std::cerr << "dmmr-compare: " << e.what() << '\n';
    return kError;
  }
}
