#include "jpeg.h"

#include <turbojpeg.h>

#include <memory>

#include "error.h"

namespace dmmr {

namespace {

struct HandleDeleter {
  void operator()(void* h) const { tjDestroy(h); }
};
using Handle = std::unique_ptr<void, HandleDeleter>;

}  // namespace

std::vector<uint8_t> encodeJpeg(const Image& image, int quality) {
  if (image.empty() || !image.consistent()) throw Error("encodeJpeg: empty or inconsistent image");
  if (quality < 1 || quality > 100)
    throw Error("encodeJpeg: quality " + std::to_string(quality) + " outside 1..100");
  Handle h(tjInitCompress());
  if (!h) throw Error("encodeJpeg: cannot start libjpeg-turbo");
  unsigned char* out = nullptr;
  unsigned long size = 0;
  if (tjCompress2(h.get(), image.rgba.data(), image.width, 0, image.height, TJPF_RGBA, &out, &size,
                  TJSAMP_420, quality, TJFLAG_FASTDCT) != 0) {
    std::string why = tjGetErrorStr2(h.get());
    tjFree(out);
    throw Error("encodeJpeg: " + why);
  }
  std::vector<uint8_t> bytes(out, out + size);
  tjFree(out);
  return bytes;
}

Image decodeJpeg(std::span<const uint8_t> bytes, const std::string& name) {
  Handle h(tjInitDecompress());
  if (!h) throw Error(name + ": cannot start libjpeg-turbo");
  int w = 0, hgt = 0, subsamp = 0, colorspace = 0;
  if (tjDecompressHeader3(h.get(), bytes.data(), static_cast<unsigned long>(bytes.size()), &w, &hgt,
                          &subsamp, &colorspace) != 0)
    throw Error(name + ": not a JPEG (" + tjGetErrorStr2(h.get()) + ")");
  if (w < 1 || hgt < 1 || w > 16384 || hgt > 16384)
    throw Error(name + ": JPEG of " + std::to_string(w) + "x" + std::to_string(hgt) +
                ", outside 1..16384 a side");
  Image img = Image::blank(w, hgt);
  if (tjDecompress2(h.get(), bytes.data(), static_cast<unsigned long>(bytes.size()),
                    img.rgba.data(), w, 0, hgt, TJPF_RGBA, 0) != 0)
    throw Error(name + ": corrupt JPEG (" + tjGetErrorStr2(h.get()) + ")");
  return img;
}

}  // namespace dmmr
