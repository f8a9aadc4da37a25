#include "budget.h"

#include <cctype>
#include <cstdio>

#include "error.h"

namespace dmmr {

uint64_t parseByteSize(const std::string& text) {
  if (text == "unlimited") return LruBudget::kUnlimited;
  size_t i = 0;
  uint64_t n = 0;
  while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
    if (n > (UINT64_MAX - 9) / 10) throw Error("byte size '" + text + "' is too large");
    n = n * 10 + uint64_t(text[i++] - '0');
  }
  if (i == 0) throw Error("byte size '" + text + "' does not start with a number");
  std::string suffix = text.substr(i);
  for (char& c : suffix) c = char(std::toupper(static_cast<unsigned char>(c)));
  int shift = -1;
  if (suffix.empty() || suffix == "B") shift = 0;
  const char* units = "KMGT";
  for (int u = 0; u < 4; ++u) {
    std::string s(1, units[u]);
    if (suffix == s || suffix == s + "B" || suffix == s + "IB") shift = 10 * (u + 1);
  }
  if (shift < 0)
    throw Error("byte size '" + text + "' has an unknown unit (use K, M, G, T or none)");
  if (shift > 0 && n > (UINT64_MAX >> shift)) throw Error("byte size '" + text + "' is too large");
  return n << shift;
}

std::string formatByteSize(uint64_t bytes) {
  if (bytes == LruBudget::kUnlimited) return "unlimited";
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024 && u < 4) {
    v /= 1024;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", v, units[u]);
  return buf;
}

}  // namespace dmmr
