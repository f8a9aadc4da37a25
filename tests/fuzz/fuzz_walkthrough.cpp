// libFuzzer target for parseWalkthrough (common/walkthrough.h).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.h"
#include "walkthrough.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::string text(reinterpret_cast<const char*>(data), size);
  dmmr::Walkthrough w;
  try {
    w = dmmr::parseWalkthrough(text, "fuzz/w.path");
  } catch (const dmmr::Error& e) {
    FUZZ_CHECK(std::string(e.what()).rfind("fuzz/w.path:", 0) == 0);
    return 0;
  }
  // Formatting and parsing again keeps times and positions exactly and
  // rotations up to renormalisation.
  dmmr::Walkthrough back = dmmr::parseWalkthrough(dmmr::formatWalkthrough(w), "fuzz/again.path");
  FUZZ_CHECK(back.points.size() == w.points.size());
  for (size_t i = 0; i < w.points.size(); ++i) {
    const auto &a = w.points[i], &b = back.points[i];
    FUZZ_CHECK(a.time == b.time && a.position == b.position);
    FUZZ_CHECK(std::fabs(a.rotation.x - b.rotation.x) <= 1e-15 &&
               std::fabs(a.rotation.y - b.rotation.y) <= 1e-15 &&
               std::fabs(a.rotation.z - b.rotation.z) <= 1e-15 &&
               std::fabs(a.rotation.w - b.rotation.w) <= 1e-15);
  }
  return 0;
}
