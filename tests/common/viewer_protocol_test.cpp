// Viewer messages (interactive mode): round trips, and a named rejection for
// each way a pose, an ack or a frame message can be malformed. They come from
// a browser or a device over the network: never a crash.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "bytes.h"
#include "error.h"
#include "jpeg.h"
#include "test_support.h"
#include "viewer_protocol.h"
#include "walkthrough.h"

using namespace dmmr;
using dmmr::test::errorOf;

namespace {

Pose samplePose() {
  Pose p;
  p.seq = 4000000000u;
  p.time_ms = 123456.789;
  p.position = {1e6 + 0.125, -2.5, 3e-7};  // far from the origin: doubles all the way
  p.rotation = {0.1, 0.2, 0.3, 0.927};     // near unit, as a browser's may be
  p.fovy_deg = 60;
  p.width = 1920;
  p.height = 1080;
  p.quality = 75;
  return p;
}

// Rewrites the CRC after a change, so the check under test is the one that
// fires.
void reseal(std::vector<uint8_t>& b) {
  uint32_t crc = crc32(b.data(), b.size() - 4);
  for (int i = 0; i < 4; ++i) b[b.size() - 4 + size_t(i)] = uint8_t(crc >> (8 * i));
}

void putF64(std::vector<uint8_t>& b, size_t at, double v) {
  uint64_t u;
  std::memcpy(&u, &v, 8);
  for (int i = 0; i < 8; ++i) b[at + size_t(i)] = uint8_t(u >> (8 * i));
}

std::string decodeError(std::vector<uint8_t> b) {
  return errorOf([&] { decodeViewerMessage(b.data(), b.size()); });
}

// Byte offsets in a pose message (docs/interactive.md).
constexpr size_t kRotationX = 4 + 2 + 2 + 4 + 8 + 24, kFovy = kRotationX + 32, kWidth = kFovy + 8,
                 kQuality = kWidth + 8;

}  // namespace

TEST(ViewerProtocol, PoseRoundTripsBitForBit) {
  Pose p = samplePose();
  std::vector<uint8_t> b = encodePose(p);
  EXPECT_EQ(b.size(), kPoseMessageBytes);
  ViewerMessage m = decodeViewerMessage(b.data(), b.size());
  EXPECT_EQ(m.type, ViewerMessageType::Pose);
  EXPECT_EQ(m.pose, p);  // the rotation as sent; the server renormalises it
}

TEST(ViewerProtocol, AckRoundTrips) {
  std::vector<uint8_t> b = encodeAck(77);
  EXPECT_EQ(b.size(), kAckMessageBytes);
  ViewerMessage m = decodeViewerMessage(b.data(), b.size());
  EXPECT_EQ(m.type, ViewerMessageType::Ack);
  EXPECT_EQ(m.ack_frame, 77u);
}

TEST(ViewerProtocol, PoseRotationIsRenormalisedAsAWalkthroughLineIs) {
  // A pose written to an AnimationPath and read back must give the camera
  // the server used: both go through unitRotation.
  Pose p = samplePose();
  Walkthrough w;
  w.points.push_back({0, p.position, p.rotation});
  Walkthrough back = parseWalkthrough(formatWalkthrough(w), "pose.path");
  Quatd server;
  ASSERT_TRUE(unitRotation(p.rotation, &server));
  EXPECT_EQ(back.points[0].rotation, server);
  EXPECT_EQ(back.points[0].position, p.position);
}

TEST(ViewerProtocol, RejectsWrongMagic) {
  auto b = encodePose(samplePose());
  b[0] = 'X';
  reseal(b);
  EXPECT_NE(decodeError(b).find("wrong magic"), std::string::npos);
}

TEST(ViewerProtocol, RejectsBadCrc) {
  auto b = encodePose(samplePose());
  b[20] ^= 1;
  EXPECT_NE(decodeError(b).find("CRC mismatch"), std::string::npos);
}

TEST(ViewerProtocol, RejectsUnknownVersion) {
  auto b = encodePose(samplePose());
  b[4] = 2;
  reseal(b);
  EXPECT_NE(decodeError(b).find("version 2"), std::string::npos);
}

TEST(ViewerProtocol, RejectsUnknownType) {
  auto b = encodeAck(1);
  b[6] = 9;
  reseal(b);
  EXPECT_NE(decodeError(b).find("unknown type 9"), std::string::npos);
}

TEST(ViewerProtocol, RejectsTruncationAndTrailingBytes) {
  auto b = encodePose(samplePose());
  auto shorter = b;
  shorter.erase(shorter.end() - 5);
  reseal(shorter);
  EXPECT_NE(decodeError(shorter).find("Pose of 96 bytes, expected 97"), std::string::npos);
  auto longer = b;
  longer.insert(longer.end() - 4, 0);
  reseal(longer);
  EXPECT_NE(decodeError(longer).find("Pose of 98 bytes"), std::string::npos);
  EXPECT_NE(decodeError({'D', 'M'}).find("shorter than the smallest"), std::string::npos);
  EXPECT_NE(decodeError({}).find("shorter than the smallest"), std::string::npos);
}

TEST(ViewerProtocol, RejectsOversizedMessages) {
  std::vector<uint8_t> big(kMaxViewerMessageBytes + 1, 0);
  EXPECT_NE(decodeError(big).find("more than the limit"), std::string::npos);
}

TEST(ViewerProtocol, RejectsNonFiniteNumbers) {
  for (double bad : {std::nan(""), std::numeric_limits<double>::infinity()}) {
    auto b = encodePose(samplePose());
    putF64(b, 4 + 2 + 2 + 4 + 8, bad);  // position x
    reseal(b);
    EXPECT_NE(decodeError(b).find("position x is not a finite number"), std::string::npos);
  }
}

TEST(ViewerProtocol, RejectsRotationOffUnitLength) {
  for (double x : {0.0, 0.5}) {
    Pose p = samplePose();
    p.rotation = {x, 0, 0, 0};
    auto b = encodePose(p);
    EXPECT_NE(decodeError(b).find("not unit length"), std::string::npos) << x;
  }
}

TEST(ViewerProtocol, RejectsFieldOfViewOutsideTheOpenRange) {
  for (double f : {0.0, -5.0, 180.0, 400.0}) {
    auto b = encodePose(samplePose());
    putF64(b, kFovy, f);
    reseal(b);
    EXPECT_NE(decodeError(b).find("outside (0, 180)"), std::string::npos) << f;
  }
}

TEST(ViewerProtocol, RejectsImageSidesAndQualityOutOfRange) {
  Pose p = samplePose();
  p.width = 0;
  EXPECT_NE(decodeError(encodePose(p)).find("image side 0"), std::string::npos);
  p.width = kMaxPoseImageSide + 1;
  EXPECT_NE(decodeError(encodePose(p)).find("image side 16385"), std::string::npos);
  p = samplePose();
  p.quality = 101;
  EXPECT_NE(decodeError(encodePose(p)).find("quality 101"), std::string::npos);
  p.quality = 0;  // lossless: allowed
  EXPECT_EQ(decodeError(encodePose(p)), "");
  static_assert(kQuality == kPoseMessageBytes - 5);
}

TEST(FrameMessage, RoundTrips) {
  FrameMessage f{FrameEncoding::Png, R"({"frame":3})", {1, 2, 3, 4, 5}};
  auto b = encodeFrameMessage(f);
  EXPECT_EQ(decodeFrameMessage(b.data(), b.size()), f);
  FrameMessage empty{FrameEncoding::Jpeg, "", {}};
  b = encodeFrameMessage(empty);
  EXPECT_EQ(decodeFrameMessage(b.data(), b.size()), empty);
}

TEST(FrameMessage, RejectsEachMalformation) {
  FrameMessage f{FrameEncoding::Jpeg, R"({"frame":3})", {9, 9, 9}};
  auto err = [](std::vector<uint8_t> b) {
    return errorOf([&] { decodeFrameMessage(b.data(), b.size()); });
  };
  auto b = encodeFrameMessage(f);
  auto bad = b;
  bad[1] = 'X';
  reseal(bad);
  EXPECT_NE(err(bad).find("wrong magic"), std::string::npos);
  bad = b;
  bad[bad.size() - 6] ^= 0x10;
  EXPECT_NE(err(bad).find("CRC mismatch"), std::string::npos);
  bad = b;
  bad[6] = 3;  // encoding
  reseal(bad);
  EXPECT_NE(err(bad).find("unknown encoding 3"), std::string::npos);
  bad = b;
  bad[8] = 200;  // header length past the end
  reseal(bad);
  EXPECT_NE(err(bad).find("past the end"), std::string::npos);
  bad.assign(b.begin(), b.begin() + 10);
  EXPECT_NE(err(bad).find("shorter than the smallest"), std::string::npos);
}

TEST(Jpeg, RoundTripsCloseToTheImageAndRejectsGarbage) {
  Image img = Image::blank(64, 48);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      uint8_t* p = img.pixel(x, y);
      p[0] = uint8_t(x * 4);
      p[1] = uint8_t(y * 5);
      p[2] = uint8_t(128 + 60 * std::sin(x * 0.2));
      p[3] = 255;
    }
  std::vector<uint8_t> jpeg = encodeJpeg(img, 95);
  Image back = decodeJpeg(jpeg, "frame.jpg");
  ASSERT_EQ(back.width, img.width);
  ASSERT_EQ(back.height, img.height);
  double se = 0;
  for (size_t i = 0; i < img.rgba.size(); ++i) {
    double d = double(img.rgba[i]) - double(back.rgba[i]);
    se += d * d;
  }
  double psnr = 10 * std::log10(255.0 * 255.0 / (se / double(img.rgba.size())));
  EXPECT_GT(psnr, 30) << "quality 95 should be close to the image";
  EXPECT_LT(encodeJpeg(img, 10).size(), jpeg.size());
  EXPECT_NE(errorOf([&] {
              decodeJpeg(std::vector<uint8_t>{1, 2, 3}, "x.jpg");
            }).find("x.jpg"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { encodeJpeg(img, 0); }).find("quality 0"), std::string::npos);
}
