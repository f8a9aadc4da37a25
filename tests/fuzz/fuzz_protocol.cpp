// libFuzzer target for the server-client message decoders (common/protocol.h):
// the first byte picks the decoder (even: Job, odd: SubFrame batch) and, for
// a Job, the scene's object count (its upper 7 bits; 127: 2^32); the rest is
// the message. What decodes must encode back to the same bytes, and a
// decoded Job must be one a client can index the scene with.
#include <algorithm>
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
      size_t objects = data[0] >> 1 == 127 ? size_t(1) << 32 : size_t(data[0] >> 1);
      dmmr::FrameJob j = dmmr::decodeJob(bytes, objects);
      FUZZ_CHECK(dmmr::encodeJob(j) == bytes);
      for (size_t i = 0; i < j.objects.size(); ++i)
        FUZZ_CHECK(j.objects[i] < objects && (i == 0 || j.objects[i - 1] < j.objects[i]));
      FUZZ_CHECK(dmmr::insideFrame(j.region, j.width, j.height));
      for (size_t i = 0; i < j.hints.size(); ++i)
        FUZZ_CHECK(std::binary_search(j.objects.begin(), j.objects.end(), j.hints[i]) &&
                   (i == 0 || j.hints[i - 1] < j.hints[i]));
    } else {
      FUZZ_CHECK(dmmr::encodeSubFrames(dmmr::decodeSubFrames(bytes)) == bytes);
    }
  } catch (const dmmr::Error& e) {
    FUZZ_CHECK(std::string(e.what()).find("message") != std::string::npos);
  }
  return 0;
}
