// libFuzzer target for decodeManifest (common/formats.h).
#include <cstddef>
#include <cstdint>
#include <string>

#include "formats.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::string text(reinterpret_cast<const char*>(data), size);
  dmmr::Manifest m;
  try {
    m = dmmr::decodeManifest(text, "fuzz/manifest.json");
  } catch (const dmmr::Error& e) {
    FUZZ_CHECK(std::string(e.what()).find("fuzz/manifest.json") != std::string::npos);
    return 0;
  }
  // Whatever is accepted round-trips exactly.
  FUZZ_CHECK(dmmr::decodeManifest(dmmr::encodeManifest(m), "fuzz/again.json") == m);
  return 0;
}
