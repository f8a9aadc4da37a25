// libFuzzer target for decodePng (common/image.h), the reader behind readPng.
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz_support.h"
#include "image.h"

namespace {

// The input with every complete chunk's CRC recomputed, so that mutations
// reach the decoder instead of failing libpng's chunk checksums.
std::vector<uint8_t> withValidChunkCrcs(std::vector<uint8_t> f) {
  size_t at = 8;
  while (at + 12 <= f.size()) {
    uint32_t len = uint32_t(f[at]) << 24 | uint32_t(f[at + 1]) << 16 | uint32_t(f[at + 2]) << 8 |
                   uint32_t(f[at + 3]);
    if (len > f.size() - at - 12) break;
    uint32_t c = uint32_t(crc32(0, f.data() + at + 4, uInt(len + 4)));
    size_t p = at + 8 + len;
    for (int i = 0; i < 4; ++i) f[p + size_t(i)] = uint8_t(c >> (24 - 8 * i));
    at = p + 4;
  }
  return f;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<uint8_t> raw(data, data + size);
  for (const std::vector<uint8_t>& file : {raw, withValidChunkCrcs(raw)}) {
    dmmr::Image image;
    try {
      image = dmmr::decodePng(file, "fuzz/in.png");
    } catch (const dmmr::Error& e) {
      FUZZ_CHECK(std::string(e.what()).find("fuzz/in.png") != std::string::npos);
      continue;
    }
    FUZZ_CHECK(image.consistent() && !image.empty());
    // Decoded images round-trip bit for bit.
    FUZZ_CHECK(dmmr::decodePng(dmmr::encodePng(image), "fuzz/again.png") == image);
  }
  return 0;
}
