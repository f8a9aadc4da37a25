// libFuzzer target for decodeGeometry (common/formats.h), every encoding.
#include <cstddef>
#include <cstdint>

#include "formats.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  dmmr::fuzz::fuzzContainerReader(
      data, size,
      [](const std::vector<uint8_t>& f, const std::string& p) {
        // Whatever a reader accepts, every encoder must write a file that
        // decodes again; the exact encodings must give it back unchanged
        // (compared as float32 files, so that NaNs compare too).
        dmmr::GeometryData g = dmmr::decodeGeometry(f, p);
        std::vector<uint8_t> raw = dmmr::encodeGeometry(g);
        for (dmmr::Encoding e : dmmr::kEncodings) {
          dmmr::GeometryData back = dmmr::decodeGeometry(dmmr::encodeGeometry(g, e), "fuzz/re.bin");
          if (dmmr::isLossless(e)) FUZZ_CHECK(dmmr::encodeGeometry(back) == raw);
          FUZZ_CHECK(back.indices == g.indices && back.submeshes == g.submeshes);
        }
        return g;
      },
      [](const auto& v) { return dmmr::encodeGeometry(v); });
  return 0;
}
