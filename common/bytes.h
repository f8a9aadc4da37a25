// Little-endian byte streams and the container every dmmr binary file uses:
//
//   magic[8] | version u32 | payload_size u64 | payload | crc32 u32
//
// The CRC-32 (zlib's) covers every byte before it. Readers are strict: wrong
// magic, an unknown version, a size that disagrees with the file (truncation
// or trailing bytes), a bad checksum, or a payload not consumed exactly are
// each rejected with an Error naming the file and the problem.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "error.h"

namespace dmmr {

uint32_t crc32(const uint8_t* data, size_t size, uint32_t seed = 0);

// The CRC a scene manifest lists for a file: CRC-32 of all but its last 4
// bytes, which for a container (below) is the CRC it stores. The CRC-32 of
// a whole intact container, stored CRC included, is one constant (the CRC
// residue), so it could not tell one intact file from another: a geometry
// file swapped for another would pass.
uint32_t manifestCrc(const std::vector<uint8_t>& file);

class ByteWriter {
 public:
  void u8(uint8_t v) { out_.push_back(v); }
  void u16(uint16_t v) { putLE(v); }
  void u32(uint32_t v) { putLE(v); }
  void u64(uint64_t v) { putLE(v); }
  void i32(int32_t v) { putLE(uint32_t(v)); }
  void f32(float v) { putLE(std::bit_cast<uint32_t>(v)); }
  void f64(double v) { putLE(std::bit_cast<uint64_t>(v)); }
  void str(std::string_view s);  // u32 length + bytes
  // Arrays of plain scalars, written element by element in little-endian.
  template <typename T>
  void array(const T* p, size_t n) {
    if constexpr (std::endian::native == std::endian::little) {
      const auto* b = reinterpret_cast<const uint8_t*>(p);
      out_.insert(out_.end(), b, b + n * sizeof(T));
    } else {
      for (size_t i = 0; i < n; ++i) putLE(std::bit_cast<UInt<sizeof(T)>>(p[i]));
    }
  }
  std::vector<uint8_t>& bytes() { return out_; }

 private:
  template <size_t N>
  using UInt = std::conditional_t<
      N == 1, uint8_t,
      std::conditional_t<N == 2, uint16_t, std::conditional_t<N == 4, uint32_t, uint64_t>>>;
  template <typename U>
  void putLE(U v) {
    for (size_t i = 0; i < sizeof(U); ++i) out_.push_back(uint8_t(v >> (8 * i)));
  }
  std::vector<uint8_t> out_;
};

class ByteReader {
 public:
  // `path` and `what` (e.g. "bounds") only label errors.
  ByteReader(const uint8_t* data, size_t size, std::string path)
      : p_(data), end_(data + size), path_(std::move(path)) {}
  uint8_t u8(const char* field) { return getLE<uint8_t>(field); }
  uint16_t u16(const char* field) { return getLE<uint16_t>(field); }
  uint32_t u32(const char* field) { return getLE<uint32_t>(field); }
  uint64_t u64(const char* field) { return getLE<uint64_t>(field); }
  int32_t i32(const char* field) { return int32_t(getLE<uint32_t>(field)); }
  float f32(const char* field) { return std::bit_cast<float>(getLE<uint32_t>(field)); }
  double f64(const char* field) { return std::bit_cast<double>(getLE<uint64_t>(field)); }
  std::string str(const char* field, size_t max_len = 1 << 20);
  // Reads n scalars; rejects counts that would run past the end before
  // allocating, so a hostile count cannot exhaust memory.
  template <typename T>
  void array(std::vector<T>* out, uint64_t n, const char* field) {
    need(n, sizeof(T), field);
    out->resize(size_t(n));
    if constexpr (std::endian::native == std::endian::little) {
      if (n) std::memcpy(out->data(), p_, size_t(n) * sizeof(T));
      p_ += n * sizeof(T);
    } else {
      for (auto& v : *out) v = std::bit_cast<T>(getLE<UInt<sizeof(T)>>(field));
    }
  }
  // The next n bytes in place (valid while the reader's data is), skipped.
  const uint8_t* bytes(uint64_t n, const char* field) {
    need(n, 1, field);
    const uint8_t* p = p_;
    p_ += n;
    return p;
  }
  size_t remaining() const { return size_t(end_ - p_); }
  // Throws unless every byte was consumed.
  void finish() const;
  [[noreturn]] void fail(const std::string& what) const;
  const std::string& path() const { return path_; }

 private:
  template <size_t N>
  using UInt = std::conditional_t<
      N == 1, uint8_t,
      std::conditional_t<N == 2, uint16_t, std::conditional_t<N == 4, uint32_t, uint64_t>>>;
  void need(uint64_t count, size_t elem, const char* field);
  template <typename U>
  U getLE(const char* field) {
    need(1, sizeof(U), field);
    U v = 0;
    for (size_t i = 0; i < sizeof(U); ++i) v |= U(U(p_[i]) << (8 * i));
    p_ += sizeof(U);
    return v;
  }
  const uint8_t* p_;
  const uint8_t* end_;
  std::string path_;
};

struct FileKind {
  char magic[9];      // 8 characters, NUL-terminated for convenience
  uint32_t version;   // the version this build writes and reads
  const char* label;  // e.g. "bounds", for messages
  // The oldest version this build still reads (0: only `version`), for
  // formats whose later versions only add to the earlier ones.
  uint32_t oldest = 0;
  uint32_t oldestRead() const { return oldest == 0 ? version : oldest; }
};

inline constexpr size_t kContainerOverhead = 8 + 4 + 8 + 4;

std::vector<uint8_t> wrapContainer(const FileKind& kind, const std::vector<uint8_t>& payload);
// Validates the container and returns the payload's [begin, size) within
// `file`; its version (kind.oldestRead() to kind.version) goes to *version,
// if given.
std::pair<const uint8_t*, size_t> openContainer(const FileKind& kind,
                                                const std::vector<uint8_t>& file,
                                                const std::string& path,
                                                uint32_t* version = nullptr);

}  // namespace dmmr
