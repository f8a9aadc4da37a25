// libFuzzer target for parsePly (preprocess/ply_reader.h), the reader of
// models from strangers: every input either parses into a consistent mesh or
// throws an Error naming the file.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_support.h"
#include "ply_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  dmmr::PlyMesh m;
  try {
    m = dmmr::parsePly(in, "fuzz/m.ply", size);
  } catch (const dmmr::Error& e) {
    FUZZ_CHECK(std::string(e.what()).rfind("fuzz/m.ply", 0) == 0);
    return 0;
  }
  const size_t nv = m.positions.size() / 3;
  FUZZ_CHECK(m.positions.size() % 3 == 0);
  FUZZ_CHECK(m.normals.empty() || m.normals.size() == m.positions.size());
  FUZZ_CHECK(m.colors.empty() || m.colors.size() == 4 * nv);
  FUZZ_CHECK(m.uv.empty() || m.uv.size() == 2 * nv);
  for (float c : m.colors) FUZZ_CHECK(c >= 0 && c <= 1);
  FUZZ_CHECK(m.triangles.size() % 3 == 0 && m.quads.size() % 4 == 0);
  for (uint32_t i : m.triangles) FUZZ_CHECK(i < nv);
  for (uint32_t i : m.quads) FUZZ_CHECK(i < nv);
  return 0;
}
