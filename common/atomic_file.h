// Atomic output: write to a temporary file beside the target, flush, rename.
// A reader never sees a half-written file, and an interrupted run leaves none.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace dmmr {

void writeFileAtomic(const std::string& path, std::string_view bytes);
// Writes all of `bytes` to `fd`, through short writes and EINTR; returns 0,
// or the errno of the write that failed.
int writeAll(int fd, std::string_view bytes);
void writeFileAtomic(const std::string& path, const std::vector<uint8_t>& bytes);
// Reads a whole file; throws Error naming it when it cannot be read.
std::vector<uint8_t> readFileBytes(const std::string& path);

}  // namespace dmmr
