// libFuzzer target for decodeOccluders (common/formats.h).
#include <cstddef>
#include <cstdint>

#include "formats.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  dmmr::fuzz::fuzzContainerReader(
      data, size,
      [](const std::vector<uint8_t>& f, const std::string& p) {
        return dmmr::decodeOccluders(f, p);
      },
      [](const auto& v) { return dmmr::encodeOccluders(v); });
  return 0;
}
