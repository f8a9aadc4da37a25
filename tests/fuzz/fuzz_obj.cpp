// libFuzzer target for checkObjIndices (preprocess/obj_check.h), which reads
// an OBJ model's text before OSG's plugin does: every input passes or
// throws an Error naming the file and line; nothing else escapes, and no
// input reads out of bounds or runs long.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_support.h"
#include "obj_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::string text(reinterpret_cast<const char*>(data), size);
  std::istringstream in(text);
  try {
    dmmr::checkObjIndices(in, "fuzz/m.obj");
  } catch (const dmmr::Error& e) {
    FUZZ_CHECK(std::string(e.what()).rfind("fuzz/m.obj:", 0) == 0);
    return 0;
  }
  return 0;
}
