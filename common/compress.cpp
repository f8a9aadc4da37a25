#include "compress.h"

#include <lz4.h>
#include <zlib.h>

#include <climits>

#include "error.h"

namespace dmmr {

Codec parseCodec(const std::string& name) {
  if (name == "none") return Codec::None;
  if (name == "lz4") return Codec::LZ4;
  if (name == "zlib") return Codec::Zlib;
  throw Error("unknown compression '" + name + "' (expected none, lz4 or zlib)");
}

const char* codecName(Codec c) {
  switch (c) {
    case Codec::None:
      return "none";
    case Codec::LZ4:
      return "lz4";
    case Codec::Zlib:
      return "zlib";
  }
  return "unknown";
}

std::vector<uint8_t> compress(Codec c, const uint8_t* data, size_t size) {
  if (c == Codec::None) return std::vector<uint8_t>(data, data + size);
  if (size > size_t(INT_MAX) / 2) throw Error("sub-frame too large to compress");
  std::vector<uint8_t> out;
  if (c == Codec::LZ4) {
    out.resize(size_t(LZ4_compressBound(int(size))));
    int n = LZ4_compress_default(reinterpret_cast<const char*>(data),
                                 reinterpret_cast<char*>(out.data()), int(size), int(out.size()));
    if (n <= 0) throw Error("lz4 compression failed");
    out.resize(size_t(n));
    return out;
  }
  uLongf n = compressBound(uLong(size));
  out.resize(n);
  if (compress2(out.data(), &n, data, uLong(size), 1) != Z_OK)
    throw Error("zlib compression failed");
  out.resize(n);
  return out;
}

std::vector<uint8_t> decompress(Codec c, const uint8_t* data, size_t size, size_t raw_size) {
  if (c == Codec::None) {
    if (size != raw_size) throw Error("uncompressed sub-frame has the wrong size");
    return std::vector<uint8_t>(data, data + size);
  }
  if (raw_size > size_t(INT_MAX) || size > size_t(INT_MAX))
    throw Error("sub-frame too large to decompress");
  std::vector<uint8_t> out(raw_size);
  if (c == Codec::LZ4) {
    int n = LZ4_decompress_safe(reinterpret_cast<const char*>(data),
                                reinterpret_cast<char*>(out.data()), int(size), int(raw_size));
    if (n != int(raw_size)) throw Error("corrupt lz4 sub-frame");
    return out;
  }
  if (c == Codec::Zlib) {
    uLongf n = uLongf(raw_size);
    if (uncompress(out.data(), &n, data, uLong(size)) != Z_OK || n != raw_size)
      throw Error("corrupt zlib sub-frame");
    return out;
  }
  throw Error("unknown sub-frame codec");
}

}  // namespace dmmr
