#include "obj_check.h"

#include <charconv>
#include <cstdint>
#include <vector>

#include "error.h"

namespace dmmr {

namespace {
struct Ref {
  long line;
  int kind;  // 0 v, 1 vt, 2 vn
  int64_t index;
};
const char* kKinds[] = {"vertex", "texture coordinate", "normal"};
const char* kPlurals[] = {"vertices", "texture coordinates", "normals"};
}  // namespace

void checkObjIndices(std::istream& in, const std::string& name) {
  int64_t count[3] = {0, 0, 0};
  std::vector<Ref> positive;  // checked at the end against the file's counts
  std::string line;
  for (long n = 1; std::getline(in, line); ++n) {
    size_t i = line.find_first_not_of(" \t");
    if (i == std::string::npos) continue;
    auto word = [&](const char* w) {
      size_t len = std::char_traits<char>::length(w);
      return line.compare(i, len, w) == 0 && (i + len == line.size() || line[i + len] == ' ' ||
                                              line[i + len] == '\t' || line[i + len] == '\r');
    };
    // A line cut short (a file truncated mid-line) that OSG's plugin takes
    // quietly: a position of one or two numbers gets zeros, and a face of
    // two vertices becomes a line, which no triangle comes of (checked
    // below, as its references are read).
    const int listed = word("v") ? 0 : word("vt") ? 1 : word("vn") ? 2 : -1;  // count[] index
    if (listed >= 0) {
      if (listed != 1) {  // the numbers after the keyword, up to a comment
        size_t k = 0;
        for (size_t at = i + (listed == 0 ? 1 : 2);; ++k) {
          at = line.find_first_not_of(" \t\r", at);
          if (at == std::string::npos || line[at] == '#') break;
          at = line.find_first_of(" \t\r#", at);
        }
        if (k < 3)
          throw Error(fileError(name, n,
                                std::string(listed == 0 ? "a vertex position" : "a normal") +
                                    " of " + std::to_string(k) +
                                    " coordinates (3 needed); is the file cut short?"));
      }
      ++count[listed];
    } else if (word("f") || word("l") || word("p")) {
      size_t refs = 0;
      size_t at = i + 1;
      while (at < line.size()) {
        while (at < line.size() && (line[at] == ' ' || line[at] == '\t' || line[at] == '\r')) ++at;
        if (at >= line.size() || line[at] == '#') break;
        size_t end = line.find_first_of(" \t\r#", at);
        if (end == std::string::npos) end = line.size();
        ++refs;
        // "a", "a/b", "a//c", "a/b/c"
        int kind = 0;
        for (size_t p = at; p <= end && kind < 3; ++kind) {
          size_t slash = line.find('/', p);
          size_t stop = slash == std::string::npos || slash > end ? end : slash;
          if (stop > p || kind == 0) {
            int64_t v = 0;
            auto [q, ec] = std::from_chars(line.data() + p, line.data() + stop, v);
            if (ec != std::errc() || q != line.data() + stop || v == 0)
              throw Error(fileError(name, n,
                                    "'" + line.substr(p, stop - p) + "' is not a " + kKinds[kind] +
                                        " index (1 to the count, or negative from the end)"));
            if (v < 0 && -v > count[kind])
              throw Error(fileError(name, n,
                                    std::string(kKinds[kind]) + " index " + std::to_string(v) +
                                        " reaches before the first (" +
                                        std::to_string(count[kind]) + " so far)"));
            if (v > 0) positive.push_back({n, kind, v});
          }
          if (stop == end) break;
          p = stop + 1;
        }
        at = end;
      }
      if (word("f") && refs < 3)
        throw Error(fileError(name, n,
                              "a face of " + std::to_string(refs) +
                                  " vertices (3 or more needed); is the file cut short?"));
    }
  }
  for (const Ref& r : positive)
    if (r.index > count[r.kind])
      throw Error(fileError(name, r.line,
                            std::string(kKinds[r.kind]) + " index " + std::to_string(r.index) +
                                " is past the file's " + std::to_string(count[r.kind]) + " " +
                                (count[r.kind] == 1 ? kKinds[r.kind] : kPlurals[r.kind])));
}

}  // namespace dmmr
