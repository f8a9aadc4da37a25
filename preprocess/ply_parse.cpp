// parsePly (ply_reader.h): no OpenSceneGraph here, so that the fuzz target
// links it alone.
#include "ply_reader.h"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>

#include "error.h"

namespace dmmr {

namespace {

enum class Type : uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };
enum class Format { Ascii, BinaryLittle, BinaryBig };

size_t sizeOf(Type t) {
  static constexpr size_t kSizes[] = {1, 1, 2, 2, 4, 4, 4, 8};
  return kSizes[size_t(t)];
}
bool isInteger(Type t) {
  return t != Type::Float32 && t != Type::Float64;
}

bool parseType(const std::string& s, Type* t) {
  static const std::pair<const char*, Type> kNames[] = {
      {"char", Type::Int8},      {"int8", Type::Int8},       {"uchar", Type::UInt8},
      {"uint8", Type::UInt8},    {"short", Type::Int16},     {"int16", Type::Int16},
      {"ushort", Type::UInt16},  {"uint16", Type::UInt16},   {"int", Type::Int32},
      {"int32", Type::Int32},    {"uint", Type::UInt32},     {"uint32", Type::UInt32},
      {"float", Type::Float32},  {"float32", Type::Float32}, {"double", Type::Float64},
      {"float64", Type::Float64}};
  for (const auto& [name, type] : kNames)
    if (s == name) {
      *t = type;
      return true;
    }
  return false;
}

// The largest value of an integer type, for scaling colours to [0, 1].
double maxOf(Type t) {
  switch (t) {
    case Type::Int8:
      return 127;
    case Type::UInt8:
      return 255;
    case Type::Int16:
      return 32767;
    case Type::UInt16:
      return 65535;
    case Type::Int32:
      return 2147483647.0;
    case Type::UInt32:
      return 4294967295.0;
    default:
      return 1;
  }
}

struct Property {
  std::string name;
  bool list = false;
  Type count = Type::UInt8;  // a list's count type
  Type value = Type::Float32;
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> props;
  long line = 0;  // of its header line
};

// Buffered bytes from a stream, with the line count an ASCII body needs.
class Input {
 public:
  explicit Input(std::istream& in) : in_(in), buf_(1 << 16) {}
  // Copies n bytes; false if the stream ends first.
  bool get(void* dst, size_t n) {
    auto* out = static_cast<char*>(dst);
    while (n) {
      if (pos_ == end_ && !refill()) return false;
      size_t k = std::min(n, end_ - pos_);
      std::memcpy(out, buf_.data() + pos_, k);
      pos_ += k, out += k, n -= k;
    }
    return true;
  }
  // The next byte, or -1 at the end.
  int next() {
    if (pos_ == end_ && !refill()) return -1;
    return static_cast<unsigned char>(buf_[pos_++]);
  }
  int peek() {
    if (pos_ == end_ && !refill()) return -1;
    return static_cast<unsigned char>(buf_[pos_]);
  }
  long line = 1;  // 1-based, counted by the ASCII readers

 private:
  bool refill() {
    in_.read(buf_.data(), std::streamsize(buf_.size()));
    end_ = size_t(in_.gcount());
    pos_ = 0;
    return end_ > 0;
  }
  std::istream& in_;
  std::vector<char> buf_;
  size_t pos_ = 0, end_ = 0;
};

bool isSpace(int c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}

class Parser {
 public:
  Parser(std::istream& in, const std::string& name, uint64_t size_hint)
      : in_(in), name_(name), size_hint_(size_hint) {}

  PlyMesh parse() {
    readHeader();
    for (const Element& e : elements_)
      if (e.name == "vertex") vertex_count_ = e.count;
    for (const Element& e : elements_) {
      if (e.name == "vertex")
        readVertices(e);
      else if (e.name == "face")
        readFaces(e);
      else
        skipElement(e);
    }
    checkEnd();
    return std::move(mesh_);
  }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw Error(fileError(name_, what)); }
  [[noreturn]] void failAt(long line, const std::string& what) const {
    throw Error(fileError(name_, line, what));
  }

  // ---- Header ------------------------------------------------------------

  // One header line without its end of line; false at the end of the file.
  bool headerLine(std::string* s) {
    s->clear();
    for (;;) {
      int c = in_.next();
      if (c < 0) return false;  // a last line without its end is a header cut short
      if (++header_bytes_ > kMaxHeaderBytes)
        fail("header longer than " + std::to_string(kMaxHeaderBytes) + " bytes (no end_header?)");
      if (c == '\n') break;
      s->push_back(char(c));
    }
    if (!s->empty() && s->back() == '\r') s->pop_back();
    return true;
  }

  static std::vector<std::string> words(const std::string& s) {
    std::istringstream is(s);
    std::vector<std::string> w;
    for (std::string t; is >> t;) w.push_back(t);
    return w;
  }

  void readHeader() {
    std::string s;
    long line = 0;
    if (!headerLine(&s) || s != "ply") fail("not a PLY file (it does not begin with \"ply\")");
    ++line;
    bool have_format = false;
    for (;;) {
      if (!headerLine(&s)) fail("the file ends inside the header (no end_header line)");
      ++line;
      std::vector<std::string> w = words(s);
      if (w.empty()) continue;
      const std::string& key = w[0];
      if (key == "end_header") break;
      if (key == "comment" || key == "obj_info") {
        std::string text = s.substr(std::min(s.size(), s.find(key) + key.size()));
        size_t b = text.find_first_not_of(" \t");
        text = b == std::string::npos ? "" : text.substr(b);
        if (key == "comment" && text == "modified by flipply") mesh_.flipped = true;
        if (key == "comment" && w.size() >= 3 && w[1] == "TextureFile")
          mesh_.texture_file = text.substr(text.find("TextureFile") + 11 + 1);
        continue;
      }
      if (key == "format") {
        if (have_format) failAt(line, "a second format line");
        if (w.size() != 3) failAt(line, "expected \"format TYPE 1.0\"");
        if (w[1] == "ascii")
          format_ = Format::Ascii;
        else if (w[1] == "binary_little_endian")
          format_ = Format::BinaryLittle;
        else if (w[1] == "binary_big_endian")
          format_ = Format::BinaryBig;
        else
          failAt(line, "unknown format '" + w[1] + "'");
        if (w[2] != "1.0" && w[2] != "1") failAt(line, "unsupported PLY version '" + w[2] + "'");
        have_format = true;
      } else if (key == "element") {
        if (w.size() != 3) failAt(line, "expected \"element NAME COUNT\"");
        Element e;
        e.name = w[1];
        e.line = line;
        auto [p, ec] = std::from_chars(w[2].data(), w[2].data() + w[2].size(), e.count);
        if (ec != std::errc() || p != w[2].data() + w[2].size())
          failAt(line, "element '" + e.name + "' has a bad count '" + w[2] + "'");
        for (const Element& o : elements_)
          if (o.name == e.name) failAt(line, "a second element '" + e.name + "'");
        elements_.push_back(e);
      } else if (key == "property") {
        if (elements_.empty()) failAt(line, "a property before any element");
        Property p;
        if (w.size() == 5 && w[1] == "list") {
          p.list = true;
          if (!parseType(w[2], &p.count) || !isInteger(p.count))
            failAt(line, "list count type '" + w[2] + "' is not an integer type");
          if (!parseType(w[3], &p.value)) failAt(line, "unknown property type '" + w[3] + "'");
          p.name = w[4];
        } else if (w.size() == 3) {
          if (!parseType(w[1], &p.value)) failAt(line, "unknown property type '" + w[1] + "'");
          p.name = w[2];
        } else {
          failAt(line, "expected \"property TYPE NAME\" or \"property list TYPE TYPE NAME\"");
        }
        elements_.back().props.push_back(p);
      } else {
        failAt(line, "unknown header keyword '" + key + "'");
      }
    }
    if (!have_format) fail("the header has no format line");
    in_.line = line + 1;
    bool has_vertex = false;
    for (const Element& e : elements_) {
      if (e.name == "vertex") {
        has_vertex = true;
        for (const char* c : {"x", "y", "z"})
          if (find(e, c) < 0 || e.props[size_t(find(e, c))].list)
            failAt(e.line, std::string("the vertex element has no property ") + c);
      }
      if (e.name == "face") {
        int k = faceIndices(e);
        if (k < 0) failAt(e.line, "the face element has no vertex_indices list");
        if (!isInteger(e.props[size_t(k)].value))
          failAt(e.line, "the face element's vertex indices are not integers");
      }
    }
    if (!has_vertex) fail("the file has no vertex element");
  }

  static int find(const Element& e, const char* name) {
    for (size_t i = 0; i < e.props.size(); ++i)
      if (e.props[i].name == name) return int(i);
    return -1;
  }
  static int faceIndices(const Element& e) {
    for (size_t i = 0; i < e.props.size(); ++i)
      if (e.props[i].list &&
          (e.props[i].name == "vertex_indices" || e.props[i].name == "vertex_index"))
        return int(i);
    return -1;
  }

  // What `count` items of at least `min_bytes` each may reserve.
  size_t reservable(uint64_t count, size_t min_bytes) const {
    uint64_t cap = size_hint_ ? size_hint_ / std::max<size_t>(1, min_bytes) + 1 : uint64_t(1) << 16;
    return size_t(std::min(count, cap));
  }

  // ---- Values ------------------------------------------------------------

  // One value of type t, as a double (every PLY type converts exactly).
  // `what` names the item for errors: "vertex 12".
  double value(Type t, const Element& e, uint64_t item) {
    if (format_ == Format::Ascii) return asciiValue(t, e, item);
    unsigned char b[8];
    size_t n = sizeOf(t);
    if (!in_.get(b, n)) truncated(e, item);
    bool swap = (format_ == Format::BinaryBig) != (std::endian::native == std::endian::big);
    if (swap) std::reverse(b, b + n);
    switch (t) {
      case Type::Int8:
        return load<int8_t>(b);
      case Type::UInt8:
        return load<uint8_t>(b);
      case Type::Int16:
        return load<int16_t>(b);
      case Type::UInt16:
        return load<uint16_t>(b);
      case Type::Int32:
        return load<int32_t>(b);
      case Type::UInt32:
        return load<uint32_t>(b);
      case Type::Float32:
        return load<float>(b);
      case Type::Float64:
        return load<double>(b);
    }
    return 0;
  }

  // A value of type T from its bytes, already in this machine's order.
  template <typename T>
  static double load(const unsigned char* b) {
    T v;
    std::memcpy(&v, b, sizeof(T));
    return double(v);
  }

  double asciiValue(Type t, const Element& e, uint64_t item) {
    int c = in_.peek();
    while (c >= 0 && isSpace(c)) {
      if (in_.next() == '\n') ++in_.line;
      c = in_.peek();
    }
    if (c < 0) truncated(e, item);
    char tok[64];
    size_t n = 0;
    while (c >= 0 && !isSpace(c)) {
      if (n == sizeof(tok)) failAt(in_.line, "a number longer than 63 characters");
      tok[n++] = char(in_.next());
      c = in_.peek();
    }
    double v = 0;
    const char* first = tok;
    if (n > 1 && tok[0] == '+') ++first;  // from_chars takes no plus sign
    auto [p, ec] = std::from_chars(first, tok + n, v);
    if (ec == std::errc::result_out_of_range && !isInteger(t)) {
      // Denormal or huge: strtod rounds as a reader of floats should.
      v = std::strtod(std::string(tok, n).c_str(), nullptr);
    } else if (ec != std::errc() || p != tok + n) {
      failAt(in_.line, "'" + std::string(tok, n) + "' is not a number (" + e.name + " " +
                           std::to_string(item) + ")");
    }
    if (isInteger(t)) {
      bool sign = t == Type::Int8 || t == Type::Int16 || t == Type::Int32;
      double lo = sign ? -maxOf(t) - 1 : 0;
      if (!(v == std::floor(v) && v >= lo && v <= maxOf(t)))
        failAt(in_.line, "'" + std::string(tok, n) +
                             "' is not a value of the property's integer type (" + e.name + " " +
                             std::to_string(item) + ")");
    }
    return v;
  }

  [[noreturn]] void truncated(const Element& e, uint64_t item) const {
    fail("the file ends in element '" + e.name + "': " + std::to_string(item) + " of its " +
         std::to_string(e.count) + " items were read");
  }

  // A list's count: an integer from 0 up.
  uint64_t listCount(const Property& p, const Element& e, uint64_t item) {
    double c = value(p.count, e, item);
    if (c < 0) fail(e.name + " " + std::to_string(item) + ": a list of negative length");
    return uint64_t(c);
  }

  void skipProperty(const Property& p, const Element& e, uint64_t item) {
    if (!p.list) {
      value(p.value, e, item);
      return;
    }
    for (uint64_t k = listCount(p, e, item); k > 0; --k) value(p.value, e, item);
  }

  // ---- Elements ----------------------------------------------------------

  void readVertices(const Element& e) {
    const int x = find(e, "x"), y = find(e, "y"), z = find(e, "z");
    const int nx = find(e, "nx"), ny = find(e, "ny"), nz = find(e, "nz");
    // OSG's plugin: red (and alpha), else diffuse_red..., else specular_red...
    std::array<int, 4> col = {-1, -1, -1, -1};
    bool has_alpha = false;
    for (const char* prefix : {"", "diffuse_", "specular_"}) {
      std::string p = prefix;
      if (find(e, (p + "red").c_str()) < 0) continue;
      col = {find(e, (p + "red").c_str()), find(e, (p + "green").c_str()),
             find(e, (p + "blue").c_str()), p.empty() ? find(e, "alpha") : -1};
      has_alpha = col[3] >= 0;
      break;
    }
    if (find(e, "red") < 0 && find(e, "alpha") >= 0) {  // alpha alone: OSG reads RGBA
      col = {-1, -1, -1, find(e, "alpha")};
      has_alpha = true;
    }
    const bool has_colors = col[0] >= 0 || col[3] >= 0;
    const int u = find(e, "texture_u"), v = find(e, "texture_v");
    const bool has_uv = u >= 0 && v >= 0;
    size_t min_bytes = format_ == Format::Ascii ? 2 * e.props.size() : 0;
    if (format_ != Format::Ascii)
      for (const Property& p : e.props) min_bytes += p.list ? sizeOf(p.count) : sizeOf(p.value);
    size_t r = reservable(e.count, min_bytes);
    mesh_.positions.reserve(3 * r);
    if (nx >= 0) mesh_.normals.reserve(3 * r);
    if (has_colors) mesh_.colors.reserve(4 * r);
    if (has_uv) mesh_.uv.reserve(2 * r);
    std::vector<double> vals(e.props.size(), 0.0);
    for (uint64_t i = 0; i < e.count; ++i) {
      for (size_t k = 0; k < e.props.size(); ++k) {
        const Property& p = e.props[k];
        if (p.list)
          skipProperty(p, e, i);
        else
          vals[k] = value(p.value, e, i);
      }
      auto at = [&](int k) { return k >= 0 && !e.props[size_t(k)].list ? vals[size_t(k)] : 0.0; };
      mesh_.positions.insert(mesh_.positions.end(), {float(at(x)), float(at(y)), float(at(z))});
      if (nx >= 0)
        mesh_.normals.insert(mesh_.normals.end(), {float(at(nx)), float(at(ny)), float(at(nz))});
      if (has_colors) {
        for (int c = 0; c < 4; ++c) {
          if (c == 3 && !has_alpha) {
            mesh_.colors.push_back(1.0f);
            continue;
          }
          mesh_.colors.push_back(col[c] < 0 ? 0.0f
                                            : colour(at(col[c]), e.props[size_t(col[c])].value));
        }
      }
      if (has_uv) mesh_.uv.insert(mesh_.uv.end(), {float(at(u)), float(at(v))});
    }
  }

  // A colour channel in [0, 1]: integers scaled by their type's maximum
  // (uchar / 255 as OSG's plugin computed it), floats clamped.
  static float colour(double v, Type t) {
    if (isInteger(t)) return float(std::max(0.0, v) / maxOf(t));
    if (!(v >= 0)) return 0.0f;  // NaN too
    return float(std::min(v, 1.0));
  }

  void readFaces(const Element& e) {
    const int list = faceIndices(e);
    size_t r = reservable(e.count, format_ == Format::Ascii ? 8 : 4);
    mesh_.triangles.reserve(3 * r);
    std::vector<uint32_t> corners;
    for (uint64_t i = 0; i < e.count; ++i) {
      for (size_t k = 0; k < e.props.size(); ++k) {
        const Property& p = e.props[k];
        if (int(k) != list) {
          skipProperty(p, e, i);
          continue;
        }
        uint64_t n = listCount(p, e, i);
        corners.clear();
        for (uint64_t j = 0; j < n; ++j) {
          double idx = value(p.value, e, i);
          if (idx < 0 || idx >= double(vertex_count_))
            fail("face " + std::to_string(i) + ": vertex index " +
                 std::to_string(static_cast<long long>(idx)) + " is out of range (the file has " +
                 std::to_string(vertex_count_) + " vertices)");
          if (n <= 4) corners.push_back(uint32_t(idx));
        }
        if (mesh_.flipped) std::reverse(corners.begin(), corners.end());
        if (n == 3)
          mesh_.triangles.insert(mesh_.triangles.end(), corners.begin(), corners.end());
        else if (n == 4)
          mesh_.quads.insert(mesh_.quads.end(), corners.begin(), corners.end());
        else
          ++mesh_.other_faces;
      }
    }
  }

  void skipElement(const Element& e) {
    if (e.props.empty()) return;  // its items hold no bytes, however many
    for (uint64_t i = 0; i < e.count; ++i)
      for (const Property& p : e.props) skipProperty(p, e, i);
  }

  void checkEnd() {
    uint64_t extra = 0;
    bool other = false;  // than whitespace
    for (int c; (c = in_.next()) >= 0; ++extra) other = other || !isSpace(c);
    if (other)
      fail(std::to_string(extra) +
           " bytes after the last element (the header's counts do not match the file)");
  }

  static constexpr uint64_t kMaxHeaderBytes = 1 << 20;
  Input in_;
  std::string name_;
  uint64_t size_hint_;
  Format format_ = Format::Ascii;
  std::vector<Element> elements_;
  uint64_t vertex_count_ = 0;
  uint64_t header_bytes_ = 0;
  PlyMesh mesh_;
};

}  // namespace

PlyMesh parsePly(std::istream& in, const std::string& name, uint64_t size_hint) {
  return Parser(in, name, size_hint).parse();
}

}  // namespace dmmr
