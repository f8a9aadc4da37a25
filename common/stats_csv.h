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
std::string resumeStatsCsv(const std::string& path, const std::string& header, uint32_t from_frame);

}  // namespace dmmr
