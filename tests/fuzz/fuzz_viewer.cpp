// libFuzzer target for the interactive mode's decoders: what a viewer sends
// (common/viewer_protocol.h), the frame messages a viewer reads, and JPEG
// frames (common/jpeg.h). The first byte picks the decoder (mod 3); the rest
// is the message. What decodes must encode back to the same bytes (messages)
// or be a consistent image (JPEG).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz_support.h"
#include "jpeg.h"
#include "viewer_protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const uint8_t* p = data + 1;
  size_t n = size - 1;
  try {
    switch (data[0] % 3) {
      case 0: {
        dmmr::ViewerMessage m = dmmr::decodeViewerMessage(p, n);
        std::vector<uint8_t> again = m.type == dmmr::ViewerMessageType::Pose
                                         ? dmmr::encodePose(m.pose)
                                         : dmmr::encodeAck(m.ack_frame);
        FUZZ_CHECK(again == std::vector<uint8_t>(p, p + n));
        break;
      }
      case 1: {
        dmmr::FrameMessage f = dmmr::decodeFrameMessage(p, n);
        FUZZ_CHECK(dmmr::encodeFrameMessage(f) == std::vector<uint8_t>(p, p + n));
        break;
      }
      case 2: {
        dmmr::Image img = dmmr::decodeJpeg({p, n}, "fuzz.jpg");
        FUZZ_CHECK(img.consistent() && !img.empty());
        break;
      }
    }
  } catch (const dmmr::Error& e) {
    std::string what = e.what();
    FUZZ_CHECK(what.find("message") != std::string::npos ||
               what.find("fuzz.jpg") != std::string::npos);
  }
  return 0;
}
