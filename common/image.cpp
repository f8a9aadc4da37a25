#include "image.h"

#include <png.h>

#include <algorithm>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <new>
#include <sstream>

#include "atomic_file.h"
#include "error.h"

// libpng reports errors by longjmp to the last setjmp. A longjmp that skips a
// frame holding C++ objects with destructors is undefined behaviour, so every
// libpng call that may fail runs inside a small "guarded" function below whose
// locals are all trivial; it returns false after an error. Buffers and the
// libpng structs are owned by the (unguarded) callers, which throw Error.

namespace dmmr {

namespace {

// Shared with the libpng callbacks through the error and io pointers.
struct PngIo {
  // Reading: the encoded bytes and how far libpng has consumed them.
  const uint8_t* data = nullptr;
  size_t size = 0;
  size_t pos = 0;
  // Writing: where the encoded bytes go.
  std::vector<uint8_t>* out = nullptr;
  // libpng's message for the last error, copied before the longjmp.
  char message[200] = "unknown libpng error";
};

void onPngError(png_structp png, png_const_charp msg) {
  auto* io = static_cast<PngIo*>(png_get_error_ptr(png));
  std::snprintf(io->message, sizeof io->message, "%s", msg);
  png_longjmp(png, 1);
}

// Warnings concern ancillary chunks that do not affect the pixels: stay quiet.
void onPngWarning(png_structp, png_const_charp) {}

void readFromMemory(png_structp png, png_bytep out, size_t n) {
  auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
  if (n > io->size - io->pos) png_error(png, "file is truncated");
  std::memcpy(out, io->data + io->pos, n);
  io->pos += n;
}

// Kept apart from writeToMemory so that png_error never runs inside a catch
// block (the longjmp would skip destroying the exception).
bool appendBytes(std::vector<uint8_t>& out, const uint8_t* p, size_t n) noexcept {
  try {
    out.insert(out.end(), p, p + n);
    return true;
  } catch (...) {
    return false;
  }
}

void writeToMemory(png_structp png, png_bytep data, size_t n) {
  auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
  if (!appendBytes(*io->out, data, n)) png_error(png, "out of memory");
}

void flushNothing(png_structp) {}

struct ReadStructs {
  png_structp png = nullptr;
  png_infop info = nullptr;
  ReadStructs(const ReadStructs&) = delete;
  ReadStructs& operator=(const ReadStructs&) = delete;
  explicit ReadStructs(PngIo* io) {
    png = png_create_read_struct(PNG_LIBPNG_VER_STRING, io, onPngError, onPngWarning);
    if (png) info = png_create_info_struct(png);
    if (!info) {  // the destructor will not run
      png_destroy_read_struct(&png, nullptr, nullptr);
      throw std::bad_alloc();
    }
    png_set_read_fn(png, io, readFromMemory);
  }
  ~ReadStructs() { png_destroy_read_struct(&png, &info, nullptr); }
};

struct WriteStructs {
  png_structp png = nullptr;
  png_infop info = nullptr;
  WriteStructs(const WriteStructs&) = delete;
  WriteStructs& operator=(const WriteStructs&) = delete;
  explicit WriteStructs(PngIo* io) {
    png = png_create_write_struct(PNG_LIBPNG_VER_STRING, io, onPngError, onPngWarning);
    if (png) info = png_create_info_struct(png);
    if (!info) {  // the destructor will not run
      png_destroy_write_struct(&png, nullptr);
      throw std::bad_alloc();
    }
    png_set_write_fn(png, io, writeToMemory, flushNothing);
  }
  ~WriteStructs() { png_destroy_write_struct(&png, &info); }
};

struct PngHeader {
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, color_type = 0;
  size_t file_row_bytes = 0;  // one row as stored, before our transforms
};

// Guarded: see the comment at the top.
bool guardedReadHeader(png_structp png, png_infop info, PngHeader* h) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_info(png, info);
  h->width = png_get_image_width(png, info);
  h->height = png_get_image_height(png, info);
  h->bit_depth = png_get_bit_depth(png, info);
  h->color_type = png_get_color_type(png, info);
  h->file_row_bytes = png_get_rowbytes(png, info);
  return true;
}

// Guarded. Converts every accepted colour type to RGBA8 and reads the pixels
// into `rows`, each width * 4 bytes, then reads on to IEND so that a
// truncated file is an error.
bool guardedReadPixels(png_structp png, png_infop info, png_bytepp rows, size_t row_bytes) {
  if (setjmp(png_jmpbuf(png))) return false;
  int type = png_get_color_type(png, info);
  if (!(type & PNG_COLOR_MASK_COLOR)) png_set_gray_to_rgb(png);
  if (png_get_valid(png, info, PNG_INFO_tRNS)) {
    png_set_tRNS_to_alpha(png);
  } else if (!(type & PNG_COLOR_MASK_ALPHA)) {
    png_set_filler(png, 0xff, PNG_FILLER_AFTER);
  }
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  if (png_get_rowbytes(png, info) != row_bytes) png_error(png, "unexpected row size");
  png_read_image(png, rows);
  png_read_end(png, nullptr);
  return true;
}

// Guarded.
bool guardedWrite(png_structp png, png_infop info, const Image& image, int level) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_IHDR(png, info, png_uint_32(image.width), png_uint_32(image.height), 8,
               PNG_COLOR_TYPE_RGB_ALPHA, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, level);
  // libpng's adaptive filtering tries all five filters per row, about 4x the
  // cost of "up" alone, which suits rendered frames (rows repeat) nearly as well.
  if (level <= 3) png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
  png_write_info(png, info);
  for (int y = 0; y < image.height; ++y) png_write_row(png, image.row(y));
  png_write_end(png, nullptr);
  return true;
}

void checkSupported(const PngHeader& h, const std::string& name) {
  bool known_type = h.color_type == PNG_COLOR_TYPE_RGB || h.color_type == PNG_COLOR_TYPE_RGBA ||
                    h.color_type == PNG_COLOR_TYPE_GRAY ||
                    h.color_type == PNG_COLOR_TYPE_GRAY_ALPHA;
  if (!known_type || h.bit_depth != 8) {
    throw Error(fileError(name, "unsupported PNG format (colour type " +
                                    std::to_string(h.color_type) + ", " +
                                    std::to_string(h.bit_depth) +
                                    "-bit); only 8-bit RGB, RGBA, gray and gray+alpha are read"));
  }
}

// zlib inflates at most ~1032:1, so a header promising far more pixel data
// than the file could hold is corrupt: reject it before allocating the image.
void checkPlausibleSize(const PngHeader& h, size_t file_size, const std::string& name) {
  double raw = double(h.height) * double(h.file_row_bytes + 1);
  if (raw > 1100.0 * double(file_size) + 4096.0) {
    throw Error(fileError(name, "image data too short for " + std::to_string(h.width) + "x" +
                                    std::to_string(h.height) + " pixels (corrupt or truncated)"));
  }
}

}  // namespace

Image Image::blank(int width, int height) {
  DMMR_CHECK(width >= 0 && height >= 0);
  return Image{width, height, std::vector<uint8_t>(size_t(width) * size_t(height) * 4, 0)};
}

bool Image::consistent() const {
  return width >= 0 && height >= 0 && rgba.size() == size_t(width) * size_t(height) * 4;
}

std::vector<uint8_t> encodePng(const Image& image, int compression_level) {
  DMMR_CHECK(image.consistent());
  DMMR_CHECK(compression_level >= 0 && compression_level <= 9);
  if (image.empty()) throw Error("cannot encode an empty image as PNG");
  std::vector<uint8_t> out;
  out.reserve(image.rgba.size() / 4 + 1024);
  PngIo io;
  io.out = &out;
  WriteStructs s(&io);
  if (!guardedWrite(s.png, s.info, image, compression_level))
    throw Error(std::string("PNG encoding failed: ") + io.message);
  return out;
}

void writePng(const std::string& path, const Image& image, int compression_level) {
  if (image.empty()) throw Error(fileError(path, "cannot write an empty image as PNG"));
  writeFileAtomic(path, encodePng(image, compression_level));
}

Image decodePng(std::span<const uint8_t> bytes, const std::string& name) {
  if (bytes.size() < 8 || png_sig_cmp(bytes.data(), 0, 8) != 0)
    throw Error(fileError(name, "not a PNG file"));
  PngIo io;
  io.data = bytes.data();
  io.size = bytes.size();
  ReadStructs s(&io);
  PngHeader h;
  if (!guardedReadHeader(s.png, s.info, &h)) throw Error(fileError(name, io.message));
  checkSupported(h, name);
  checkPlausibleSize(h, bytes.size(), name);
  // libpng's default user limit (1e6 pixels a side) keeps width * 4 in an int.
  Image image = Image::blank(int(h.width), int(h.height));
  std::vector<png_bytep> rows(h.height);
  for (int y = 0; y < image.height; ++y) rows[size_t(y)] = image.row(y);
  if (!guardedReadPixels(s.png, s.info, rows.data(), image.rowBytes()))
    throw Error(fileError(name, io.message));
  return image;
}

Image readPng(const std::string& path) {
  std::vector<uint8_t> bytes = readFileBytes(path);
  return decodePng(bytes, path);
}

Image flipRows(const Image& image) {
  Image out = image;
  flipRowsInPlace(out);
  return out;
}

void flipRowsInPlace(Image& image) {
  DMMR_CHECK(image.consistent());
  for (int top = 0, bottom = image.height - 1; top < bottom; ++top, --bottom)
    std::swap_ranges(image.row(top), image.row(top) + image.rowBytes(), image.row(bottom));
}

void placeRgbRegion(Image& frame, const Rect& r, std::span<const uint8_t> rgb) {
  DMMR_CHECK(frame.consistent());
  if (!insideFrame(r, frame.width, frame.height)) {
    std::ostringstream os;
    os << "region " << r << " is not inside the " << frame.width << "x" << frame.height << " frame";
    throw Error(os.str());
  }
  if (uint64_t(rgb.size()) != uint64_t(r.area()) * 3)
    throw Error("sub-frame holds " + std::to_string(rgb.size()) + " bytes, its region " +
                std::to_string(r.area() * 3));
  for (int y = 0; y < r.h; ++y) {
    uint8_t* dst = frame.pixel(r.x, frame.height - 1 - (r.y + y));
    const uint8_t* src = rgb.data() + size_t(y) * size_t(r.w) * 3;
    for (int x = 0; x < r.w; ++x, dst += 4, src += 3) {
      dst[0] = src[0];
      dst[1] = src[1];
      dst[2] = src[2];
      dst[3] = 255;
    }
  }
}

void rgbaToRgb(const uint8_t* rgba, size_t pixels, uint8_t* rgb) {
  if (pixels == 0) return;
  // One 4-byte copy per pixel (a plain load and store; a loop over the three
  // channels is not vectorised and costs ~4x more): its fourth byte lands
  // where the next pixel's red goes, and is overwritten by it. The last
  // pixel is copied byte by byte so that nothing past 3 * pixels is written.
  for (size_t i = 0; i + 1 < pixels; ++i) std::memcpy(rgb + i * 3, rgba + i * 4, 4);
  std::memcpy(rgb + (pixels - 1) * 3, rgba + (pixels - 1) * 4, 3);
}

}  // namespace dmmr
