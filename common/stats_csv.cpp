#include "stats_csv.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "atomic_file.h"
#include "error.h"

namespace dmmr {

std::string resumeStatsCsv(const std::string& path, const std::string& header,
                           uint32_t from_frame) {
  if (from_frame == 0 || path.empty() || !std::filesystem::exists(path)) return header;
  std::ifstream file(path);
  if (!file) throw Error(fileError(path, "cannot be read to resume its stats"));
  std::string text{std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
  if (size_t end = text.rfind('\n'); end != std::string::npos) text.resize(end + 1);  // torn row
  std::istringstream in(text);
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

StatsCsvAppender::StatsCsvAppender(const std::string& path, const std::string& start)
    : path_(path) {
  if (path_.empty()) return;
  writeFileAtomic(path_, start);
  fd_ = ::open(path_.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd_ < 0) throw Error(fileError(path_, std::string("cannot open: ") + std::strerror(errno)));
}

StatsCsvAppender::~StatsCsvAppender() {
  if (fd_ >= 0) ::close(fd_);
}

void StatsCsvAppender::append(const std::string& row) {
  if (fd_ < 0) return;
  if (int e = writeAll(fd_, row))
    throw Error(fileError(path_, std::string("write failed: ") + std::strerror(e)));
}

}  // namespace dmmr
