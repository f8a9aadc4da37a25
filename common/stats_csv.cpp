#include "stats_csv.h"

#include <filesystem>
#include <fstream>

#include "error.h"

namespace dmmr {

std::string resumeStatsCsv(const std::string& path, const std::string& header,
                           uint32_t from_frame) {
  if (from_frame == 0 || path.empty() || !std::filesystem::exists(path)) return header;
  std::ifstream in(path);
  if (!in) throw Error(fileError(path, "cannot be read to resume its stats"));
  std::string line, out = header;
  std::getline(in, line);
  if (line + "\n" != header)
    throw Error(fileError(path, 1,
                          "header differs from this run's columns: it holds another run's stats "
                          "(resume with the same options, or give a new --stats file)"));
  for (int number = 2; std::getline(in, line); ++number) {
    size_t comma = line.find(',');
    std::string first = line.substr(0, comma);
    if (first.empty() || first.size() > 9 ||
        first.find_first_not_of("0123456789") != std::string::npos)
      throw Error(fileError(path, number, "row does not start with a frame number"));
    if (std::stoull(first) < from_frame) out += line + "\n";
  }
  return out;
}

}  // namespace dmmr
