// libFuzzer target for decodeParts (common/formats.h).
#include <cstddef>
#include <cstdint>

#include "formats.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  dmmr::fuzz::fuzzContainerReader(
      data, size,
      [](const std::vector<uint8_t>& f, const std::string& p) { return dmmr::decodeParts(f, p); },
      [](const auto& v) { return dmmr::encodeParts(v); });
  return 0;
}
