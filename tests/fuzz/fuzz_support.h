// Shared pieces of the libFuzzer targets: each calls one reader inside
// try/catch(dmmr::Error). Anything else that escapes (another exception, a
// sanitizer report, a failed FUZZ_CHECK) is a bug the fuzzer reports.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bytes.h"
#include "error.h"

#define FUZZ_CHECK(cond)                                                                   \
  do {                                                                                     \
    if (!(cond)) {                                                                         \
      std::fprintf(stderr, "fuzz check failed: %s at %s:%d\n", #cond, __FILE__, __LINE__); \
      std::abort();                                                                        \
    }                                                                                      \
  } while (0)

namespace dmmr::fuzz {

// The input with its container's payload size and checksum made consistent,
// so that mutations reach the payload parser rather than stopping at the CRC.
inline std::vector<uint8_t> withValidContainer(std::vector<uint8_t> f) {
  if (f.size() < kContainerOverhead) return f;
  uint64_t payload = f.size() - kContainerOverhead;
  for (size_t i = 0; i < 8; ++i) f[12 + i] = uint8_t(payload >> (8 * i));
  uint32_t c = crc32(f.data(), f.size() - 4);
  for (size_t i = 0; i < 4; ++i) f[f.size() - 4 + i] = uint8_t(c >> (8 * i));
  return f;
}

// Decodes the raw input, then the input with a valid container. Whatever a
// reader accepts must re-encode to a file that it accepts again and that
// re-encodes to the same bytes (a decode-encode fixed point).
template <typename Decode, typename Encode>
void fuzzContainerReader(const uint8_t* data, size_t size, Decode decode, Encode encode) {
  std::vector<uint8_t> raw(data, data + size);
  for (const std::vector<uint8_t>& file : {raw, withValidContainer(raw)}) {
    bool ok = false;
    decltype(decode(file, std::string())) value;
    try {
      value = decode(file, "fuzz/input.bin");
      ok = true;
    } catch (const Error& e) {
      FUZZ_CHECK(std::string(e.what()).find("fuzz/input.bin") != std::string::npos);
    }
    if (!ok) continue;
    std::vector<uint8_t> again = encode(value);
    FUZZ_CHECK(encode(decode(again, "fuzz/again.bin")) == again);  // throws: a bug
  }
}

}  // namespace dmmr::fuzz
