// Per-frame stats CSVs that survive an interrupted run: what a run resumed
// with --from-frame K starts from.
#pragma once

#include <cstdint>
#include <string>

namespace dmmr {

// The CSV text a run resumed at `from_frame` starts with: `header` (one line,
// with its newline) followed by the rows of frames before `from_frame` from
// the existing file at `path`. With from_frame 0, or no file there, just
// the header. Throws Error naming the file when its header differs (another
// run's stats, other options) or a row does not start with a frame number.
// A last line without its newline is a row torn by an interrupted append
// (StatsCsvAppender) and is dropped.
std::string resumeStatsCsv(const std::string& path, const std::string& header, uint32_t from_frame);

// The stats CSV as a run writes it: `start` (header and kept rows) written
// atomically once, then one append per finished frame, a whole row each. Rewriting the file per
// frame costs O(frames^2) bytes over a run; appending costs each row once. A row torn by a kill is
// the file's last line, without its newline, and resumeStatsCsv drops it; every row before it is
// whole. An empty path writes nothing.
class StatsCsvAppender {
 public:
  StatsCsvAppender(const std::string& path, const std::string& start);
  ~StatsCsvAppender();
  StatsCsvAppender(const StatsCsvAppender&) = delete;
  StatsCsvAppender& operator=(const StatsCsvAppender&) = delete;
  // `row` with its newline. Throws Error naming the file when it cannot.
  void append(const std::string& row);

 private:
  std::string path_;
  int fd_ = -1;
};

}  // namespace dmmr
