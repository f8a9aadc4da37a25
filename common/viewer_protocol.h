// Messages between `dmmr-render --serve` and its viewers over a WebSocket
// (docs/interactive.md has the byte layout): poses and acks from a viewer,
// frames back. Encoded little-endian with a CRC-32, decoded strictly: a
// malformed message is an Error saying what is wrong, never a crash.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "math.h"

namespace dmmr {

// A camera pose as a viewer (browser, head-mounted display, phone) sends it.
struct Pose {
  uint32_t seq = 0;                // increasing per connection
  double time_ms = 0;              // the sender's clock, echoed back with the frame
  Vec3d position;                  // world space
  Quatd rotation;                  // camera-to-world, looks down local -Z, +Y up; as sent
  double fovy_deg = 45;            // vertical field of view, in (0, 180)
  uint32_t width = 0, height = 0;  // image size asked for, 1..kMaxPoseImageSide
  uint8_t quality = 80;            // JPEG quality 1..100 while moving; 0: every frame PNG
  friend bool operator==(const Pose&, const Pose&) = default;
};
inline constexpr uint32_t kMaxPoseImageSide = 16384;

enum class ViewerMessageType : uint16_t { Pose = 1, Ack = 2 };
const char* viewerMessageTypeName(ViewerMessageType t);

struct ViewerMessage {
  ViewerMessageType type = ViewerMessageType::Pose;
  Pose pose;               // type Pose
  uint32_t ack_frame = 0;  // type Ack: the frame the viewer has shown
  friend bool operator==(const ViewerMessage&, const ViewerMessage&) = default;
};

// Anything a viewer sends is at most this long; the server's WebSocket
// refuses longer messages before reading them.
inline constexpr size_t kMaxViewerMessageBytes = 1024;
inline constexpr size_t kPoseMessageBytes = 97, kAckMessageBytes = 16;

std::vector<uint8_t> encodePose(const Pose& p);
std::vector<uint8_t> encodeAck(uint32_t frame);
// Throws Error ("viewer message: ...") for: wrong magic, unknown version or
// type, a size other than the type's, a bad CRC, a non-finite number, a field
// of view outside (0, 180), an image side outside 1..kMaxPoseImageSide, a
// quality above 100, or a rotation off unit length by more than 1e-3 (see
// unitRotation, which the server then applies as for a walkthrough line).
ViewerMessage decodeViewerMessage(const uint8_t* data, size_t size);

enum class FrameEncoding : uint16_t { Jpeg = 1, Png = 2 };
const char* frameEncodingName(FrameEncoding e);

// A frame for a viewer: its header (JSON text, see docs/interactive.md) and
// the encoded image.
struct FrameMessage {
  FrameEncoding encoding = FrameEncoding::Jpeg;
  std::string header;
  std::vector<uint8_t> image;
  friend bool operator==(const FrameMessage&, const FrameMessage&) = default;
};
inline constexpr size_t kMaxFrameHeaderBytes = 1 << 20;

std::vector<uint8_t> encodeFrameMessage(const FrameMessage& f);
// Throws Error ("frame message: ...") for wrong magic, an unknown version or
// encoding, a header length past the end or above kMaxFrameHeaderBytes, or a
// bad CRC. The header's JSON is not parsed here.
FrameMessage decodeFrameMessage(const uint8_t* data, size_t size);

}  // namespace dmmr
