// libFuzzer target for the server-client message decoders (common/protocol.h):
// the first byte picks the decoder (even: Job, odd: SubFrame batch), the rest
// is the message. What decodes must encode back to the same bytes.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz_support.h"
#include "protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  bool job = data[0] % 2 == 0;
  std::vector<uint8_t> bytes(data + 1, data + size);
  try {
    if (job) {
      FUZZ_CHECK(dmmr::encodeJob(dmmr::decodeJob(bytes)) == bytes);
    } else {
      FUZZ_CHECK(dmmr::encodeSubFrames(dmmr::decodeSubFrames(bytes)) == bytes);
    }
  } catch (const dmmr::Error& e) {
    FUZZ_CHECK(std::string(e.what()).find("message") != std::string::npos);
  }
  return 0;
}
