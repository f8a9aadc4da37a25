// Sub-frame compression: lz4 (default, fast) or zlib (smaller).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace dmmr {

enum class Codec : uint8_t { None = 0, LZ4 = 1, Zlib = 2 };
Codec parseCodec(const std::string& name);  // "none", "lz4", "zlib"; Error otherwise
const char* codecName(Codec c);

std::vector<uint8_t> compress(Codec c, const uint8_t* data, size_t size);
// Throws Error when `data` does not decode to exactly `raw_size` bytes.
std::vector<uint8_t> decompress(Codec c, const uint8_t* data, size_t size, size_t raw_size);

}  // namespace dmmr
