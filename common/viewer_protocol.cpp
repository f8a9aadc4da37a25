#include "viewer_protocol.h"

#include <cmath>
#include <cstring>

#include "bytes.h"
#include "error.h"
#include "walkthrough.h"

namespace dmmr {

namespace {

constexpr char kViewerMagic[4] = {'D', 'M', 'V', 'W'};
constexpr char kFrameMagic[4] = {'D', 'M', 'F', 'R'};
constexpr uint16_t kVersion = 1;

void putMagic(ByteWriter& w, const char (&magic)[4]) {
  for (char c : magic) w.u8(uint8_t(c));
}

void putU16(ByteWriter& w, uint16_t v) {
  w.u8(uint8_t(v));
  w.u8(uint8_t(v >> 8));
}

uint16_t getU16(ByteReader& r, const char* field) {
  uint16_t lo = r.u8(field);
  return uint16_t(lo | uint16_t(r.u8(field)) << 8);
}

std::vector<uint8_t> sealed(ByteWriter& w) {
  std::vector<uint8_t>& b = w.bytes();
  uint32_t crc = crc32(b.data(), b.size());
  w.u32(crc);
  return std::move(b);
}

// Checks the magic and the trailing CRC; returns a reader over the bytes
// between them, which `label` names in every error.
ByteReader opened(const uint8_t* data, size_t size, const char (&magic)[4], size_t min_size,
                  const std::string& label) {
  if (size < min_size)
    throw Error(label + ": " + std::to_string(size) + " bytes, shorter than the smallest (" +
                std::to_string(min_size) + ")");
  if (std::memcmp(data, magic, 4) != 0) throw Error(label + ": wrong magic");
  uint32_t stored = 0;
  for (int i = 0; i < 4; ++i) stored |= uint32_t(data[size - 4 + size_t(i)]) << (8 * i);
  if (crc32(data, size - 4) != stored) throw Error(label + ": CRC mismatch");
  ByteReader r(data + 4, size - 8, label);
  uint16_t version = getU16(r, "version");
  if (version != kVersion)
    throw Error(label + ": version " + std::to_string(version) + ", this build reads " +
                std::to_string(kVersion));
  return r;
}

double finite(ByteReader& r, const char* field) {
  double v = r.f64(field);
  if (!std::isfinite(v)) r.fail(std::string(field) + " is not a finite number");
  return v;
}

}  // namespace

const char* viewerMessageTypeName(ViewerMessageType t) {
  switch (t) {
    case ViewerMessageType::Pose:
      return "Pose";
    case ViewerMessageType::Ack:
      return "Ack";
  }
  return "unknown";
}

const char* frameEncodingName(FrameEncoding e) {
  switch (e) {
    case FrameEncoding::Jpeg:
      return "jpeg";
    case FrameEncoding::Png:
      return "png";
  }
  return "unknown";
}

std::vector<uint8_t> encodePose(const Pose& p) {
  ByteWriter w;
  putMagic(w, kViewerMagic);
  putU16(w, kVersion);
  putU16(w, uint16_t(ViewerMessageType::Pose));
  w.u32(p.seq);
  w.f64(p.time_ms);
  for (double v : {p.position.x, p.position.y, p.position.z}) w.f64(v);
  for (double v : {p.rotation.x, p.rotation.y, p.rotation.z, p.rotation.w}) w.f64(v);
  w.f64(p.fovy_deg);
  w.u32(p.width);
  w.u32(p.height);
  w.u8(p.quality);
  return sealed(w);
}

std::vector<uint8_t> encodeAck(uint32_t frame) {
  ByteWriter w;
  putMagic(w, kViewerMagic);
  putU16(w, kVersion);
  putU16(w, uint16_t(ViewerMessageType::Ack));
  w.u32(frame);
  return sealed(w);
}

ViewerMessage decodeViewerMessage(const uint8_t* data, size_t size) {
  const std::string label = "viewer message";
  if (size > kMaxViewerMessageBytes)
    throw Error(label + ": " + std::to_string(size) + " bytes, more than the limit (" +
                std::to_string(kMaxViewerMessageBytes) + ")");
  ByteReader r = opened(data, size, kViewerMagic, kAckMessageBytes, label);
  ViewerMessage m;
  uint16_t type = getU16(r, "type");
  size_t want = type == uint16_t(ViewerMessageType::Pose)  ? kPoseMessageBytes
                : type == uint16_t(ViewerMessageType::Ack) ? kAckMessageBytes
                                                           : 0;
  if (want == 0) throw Error(label + ": unknown type " + std::to_string(type));
  m.type = ViewerMessageType(type);
  if (size != want)
    throw Error(label + ": " + viewerMessageTypeName(m.type) + " of " + std::to_string(size) +
                " bytes, expected " + std::to_string(want));
  if (m.type == ViewerMessageType::Ack) {
    m.ack_frame = r.u32("frame");
    r.finish();
    return m;
  }
  Pose& p = m.pose;
  p.seq = r.u32("seq");
  p.time_ms = finite(r, "time_ms");
  p.position = {finite(r, "position x"), finite(r, "position y"), finite(r, "position z")};
  p.rotation = {finite(r, "rotation x"), finite(r, "rotation y"), finite(r, "rotation z"),
                finite(r, "rotation w")};
  p.fovy_deg = finite(r, "fovy_deg");
  p.width = r.u32("width");
  p.height = r.u32("height");
  p.quality = r.u8("quality");
  r.finish();
  if (!(p.fovy_deg > 0 && p.fovy_deg < 180))
    throw Error(label + ": field of view " + std::to_string(p.fovy_deg) +
                " degrees, outside (0, 180)");
  for (uint32_t side : {p.width, p.height})
    if (side < 1 || side > kMaxPoseImageSide)
      throw Error(label + ": image side " + std::to_string(side) + ", outside 1.." +
                  std::to_string(kMaxPoseImageSide));
  if (p.quality > 100)
    throw Error(label + ": quality " + std::to_string(p.quality) + ", above 100");
  Quatd unit;
  if (double norm; !unitRotation(p.rotation, &unit, &norm))
    throw Error(label + ": rotation quaternion is not unit length (|q| = " + std::to_string(norm) +
                ")");
  return m;
}

std::vector<uint8_t> encodeFrameMessage(const FrameMessage& f) {
  ByteWriter w;
  putMagic(w, kFrameMagic);
  putU16(w, kVersion);
  putU16(w, uint16_t(f.encoding));
  w.u32(uint32_t(f.header.size()));
  w.array(reinterpret_cast<const uint8_t*>(f.header.data()), f.header.size());
  w.array(f.image.data(), f.image.size());
  return sealed(w);
}

FrameMessage decodeFrameMessage(const uint8_t* data, size_t size) {
  const std::string label = "frame message";
  ByteReader r = opened(data, size, kFrameMagic, 4 + 2 + 2 + 4 + 4, label);
  FrameMessage f;
  uint16_t enc = getU16(r, "encoding");
  if (enc != uint16_t(FrameEncoding::Jpeg) && enc != uint16_t(FrameEncoding::Png))
    throw Error(label + ": unknown encoding " + std::to_string(enc));
  f.encoding = FrameEncoding(enc);
  uint32_t header = r.u32("header length");
  if (header > kMaxFrameHeaderBytes || header > r.remaining())
    throw Error(label + ": header of " + std::to_string(header) + " bytes, past the end (" +
                std::to_string(r.remaining()) + " left) or above the limit");
  const uint8_t* h = r.bytes(header, "header");
  f.header.assign(reinterpret_cast<const char*>(h), header);
  size_t rest = r.remaining();
  const uint8_t* img = r.bytes(rest, "image");
  f.image.assign(img, img + rest);
  r.finish();
  return f;
}

}  // namespace dmmr
