#include "bytes.h"

#include <zlib.h>

namespace dmmr {

uint32_t manifestCrc(const std::vector<uint8_t>& file) {
  return crc32(file.data(), file.size() < 4 ? file.size() : file.size() - 4);
}

uint32_t crc32(const uint8_t* data, size_t size, uint32_t seed) {
  uLong c = seed;
  while (size > 0) {  // zlib takes uInt lengths
    uInt n = size > (1u << 30) ? (1u << 30) : uInt(size);
    c = ::crc32(c, data, n);
    data += n;
    size -= n;
  }
  return uint32_t(c);
}

void ByteWriter::str(std::string_view s) {
  u32(uint32_t(s.size()));
  out_.insert(out_.end(), s.begin(), s.end());
}

std::string ByteReader::str(const char* field, size_t max_len) {
  uint32_t n = u32(field);
  if (n > max_len) fail(std::string(field) + ": string length " + std::to_string(n) + " too large");
  need(n, 1, field);
  std::string s(reinterpret_cast<const char*>(p_), n);
  p_ += n;
  return s;
}

void ByteReader::need(uint64_t count, size_t elem, const char* field) {
  if (count > remaining() / elem)
    fail(std::string("truncated: ") + field + " needs " + std::to_string(count * elem) +
         " bytes, " + std::to_string(remaining()) + " left");
}

void ByteReader::finish() const {
  if (p_ != end_) fail(std::to_string(remaining()) + " trailing bytes after the payload");
}

void ByteReader::fail(const std::string& what) const {
  throw Error(fileError(path_, what));
}

std::vector<uint8_t> wrapContainer(const FileKind& kind, const std::vector<uint8_t>& payload) {
  ByteWriter w;
  w.array(reinterpret_cast<const uint8_t*>(kind.magic), 8);
  w.u32(kind.version);
  w.u64(payload.size());
  auto& out = w.bytes();
  out.reserve(kContainerOverhead + payload.size());
  out.insert(out.end(), payload.begin(), payload.end());
  w.u32(crc32(out.data(), out.size()));
  return std::move(out);
}

std::pair<const uint8_t*, size_t> openContainer(const FileKind& kind,
                                                const std::vector<uint8_t>& file,
                                                const std::string& path, uint32_t* version_out) {
  auto fail = [&](const std::string& what) { throw Error(fileError(path, what)); };
  if (file.size() < 8 || std::memcmp(file.data(), kind.magic, 8) != 0)
    fail(std::string("not a dmmr ") + kind.label + " file (wrong magic)");
  if (file.size() < kContainerOverhead)
    fail("truncated: " + std::to_string(file.size()) + " bytes is shorter than the header");
  ByteReader h(file.data() + 8, 12, path);
  uint32_t version = h.u32("version");
  uint64_t size = h.u64("payload size");
  if (version < kind.oldestRead() || version > kind.version)
    fail(std::string("unsupported ") + kind.label + " version " + std::to_string(version) +
         " (this build reads version " +
         (kind.oldestRead() == kind.version
              ? std::to_string(kind.version)
              : std::to_string(kind.oldestRead()) + " to " + std::to_string(kind.version)) +
         ")");
  uint64_t expected = kContainerOverhead + size;
  if (size > file.size() || file.size() < expected)
    fail("truncated: header promises " + std::to_string(size) + " payload bytes, file has " +
         std::to_string(file.size()) + " bytes in all");
  if (file.size() > expected)
    fail(std::to_string(file.size() - expected) + " trailing bytes after the checksum");
  ByteReader t(file.data() + file.size() - 4, 4, path);
  uint32_t stored = t.u32("checksum");
  if (crc32(file.data(), file.size() - 4) != stored) fail("checksum mismatch (file is corrupt)");
  if (version_out) *version_out = version;
  return {file.data() + 20, size_t(size)};
}

}  // namespace dmmr
