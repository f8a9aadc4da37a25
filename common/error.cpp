#include "error.h"

#include <cstdio>
#include <cstdlib>

namespace dmmr {

std::string fileError(const std::string& path, const std::string& what) {
  return path + ": " + what;
}

std::string fileError(const std::string& path, long line, const std::string& what) {
  return path + ":" + std::to_string(line) + ": " + what;
}

void checkFailed(const char* expr, const char* file, int line, const std::string& msg) {
  std::fprintf(stderr, "dmmr: internal check failed at %s:%d: %s%s%s\n", file, line, expr,
               msg.empty() ? "" : ": ", msg.c_str());
  std::abort();
}

}  // namespace dmmr
