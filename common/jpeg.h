// JPEG frames for the interactive mode (libjpeg-turbo): lossy, so only for
// frames shown while the camera moves; exact frames stay PNG (image.h).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "image.h"

namespace dmmr {

// Encodes `image` (consistent, not empty) at `quality` 1..100 with 4:2:0
// chroma subsampling; the alpha channel is dropped. Throws Error on failure.
std::vector<uint8_t> encodeJpeg(const Image& image, int quality);

// Decodes a JPEG into an opaque RGBA image. Throws Error naming `name` for
// anything libjpeg-turbo rejects, or an image larger than 16384 on a side.
Image decodeJpeg(std::span<const uint8_t> bytes, const std::string& name);

}  // namespace dmmr
