// Tests for camera paths in AnimationPath text (common/walkthrough.h).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <string>

#include "error.h"
#include "test_support.h"
#include "walkthrough.h"

namespace dmmr {
namespace {

namespace fs = std::filesystem;

using dmmr::test::errorOf;

// Expects parseWalkthrough(text, "paths/w.path") to fail with a message that
// starts "paths/w.path:LINE: " and holds `needle`.
void expectLineError(const std::string& text, long line, const std::string& needle) {
  std::string msg = errorOf([&] { parseWalkthrough(text, "paths/w.path"); });
  ASSERT_FALSE(msg.empty()) << "accepted:\n" << text;
  std::string prefix = "paths/w.path:" + std::to_string(line) + ": ";
  EXPECT_EQ(msg.substr(0, prefix.size()), prefix) << msg;
  EXPECT_NE(msg.find(needle), std::string::npos) << msg << "\nlacks: " << needle;
}

Quatd randomUnitQuat(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  Quatd q{n(rng), n(rng), n(rng), n(rng)};
  double len = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  return {q.x / len, q.y / len, q.z / len, q.w / len};
}

double quatNorm(const Quatd& q) {
  return std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
}

const char* kLine0 = "0 1 2 3 0 0 0 1\n";

// ---- parsing ---------------------------------------------------------------------

TEST(WalkthroughParse, ReadsFieldsInOrder) {
  Walkthrough w = parseWalkthrough(
      "0 1 2 3 0 0 0 1\n"
      "2.5 -1e3 0.125 7 0.5 -0.5 0.5 0.5\n",
      "w.path");
  ASSERT_EQ(w.points.size(), 2u);
  EXPECT_EQ(w.points[0], (ControlPoint{0, {1, 2, 3}, {0, 0, 0, 1}}));
  EXPECT_EQ(w.points[1], (ControlPoint{2.5, {-1000, 0.125, 7}, {0.5, -0.5, 0.5, 0.5}}));
}

TEST(WalkthroughParse, SkipsCommentsAndBlankLines) {
  Walkthrough w = parseWalkthrough(
      "# a camera path\n"
      "\n"
      "   \t\n"
      "  # indented comment 1 2 3 4 5 6 7 8\n"
      "0 1 2 3 0 0 0 1\n"
      "#\n"
      "1 1 2 3 0 0 0 1",  // no final newline
      "w.path");
  ASSERT_EQ(w.points.size(), 2u);
  EXPECT_EQ(w.points[1].time, 1);
}

TEST(WalkthroughParse, AcceptsCrlfAndExtraWhitespace) {
  std::string lf = "0 1 2 3 0 0 0 1\n# c\n1 4 5 6 0 1 0 0\n";
  std::string crlf = "0 1 2 3 0 0 0 1\r\n# c\r\n\r\n1\t4  5 6 0 1 0 0 \r\n";
  Walkthrough a = parseWalkthrough(lf, "lf"), b = parseWalkthrough(crlf, "crlf");
  EXPECT_EQ(a.points, b.points);
  // Line numbers count CRLF lines too.
  expectLineError("0 1 2 3 0 0 0 1\r\n\r\n0 1 2\r\n", 3, "got 3");
}

TEST(WalkthroughParse, EqualTimesAreAllowed) {
  Walkthrough w = parseWalkthrough("1 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n", "w");
  EXPECT_EQ(w.points.size(), 2u);
}

TEST(WalkthroughParse, RenormalisesNearUnitQuaternion) {
  Walkthrough w = parseWalkthrough("0 0 0 0 0 0 0 1.0009\n1 0 0 0 0.6 0 0 0.7995\n", "w");
  EXPECT_EQ(w.points[0].rotation, (Quatd{0, 0, 0, 1}));
  EXPECT_NEAR(quatNorm(w.points[1].rotation), 1.0, 1e-15);
  EXPECT_NEAR(w.points[1].rotation.x / w.points[1].rotation.w, 0.6 / 0.7995, 1e-14);
}

TEST(WalkthroughParse, RejectsWrongFieldCount) {
  expectLineError(std::string(kLine0) + "# c\n1 1 2 3 0 0 1\n", 3, "got 7");
  expectLineError(std::string(kLine0) + "1 1 2 3 0 0 0 1 9\n", 2, "got more");
  expectLineError("5\n", 1, "got 1");
}

TEST(WalkthroughParse, RejectsNonNumber) {
  for (std::string bad : {"abc", "1.0x", "0x10", "1,5", "--1", "1e", "+"})
    expectLineError(std::string(kLine0) + "\n1 2 " + bad + " 3 0 0 0 1\n", 3, "field 3");
}

TEST(WalkthroughParse, RejectsNaNAndInfinity) {
  for (std::string bad : {"nan", "NaN", "inf", "-inf", "infinity", "1e400", "-1e999"})
    expectLineError("# c\n\n\n0 " + bad + " 2 3 0 0 0 1\n", 4, "not a finite number");
  expectLineError("0 0 0 0 0 0 nan 1\n", 1, "field 7");
}

TEST(WalkthroughParse, RejectsNonUnitQuaternion) {
  for (std::string q : {"0 0 0 0", "0 0 0 2", "0 0 0 1.0011", "0.5 0.5 0.5 0.49", "1e200 0 0 1"})
    expectLineError(std::string(kLine0) + kLine0 + "1 0 0 0 " + q + "\n", 3, "not unit length");
}

TEST(WalkthroughParse, RejectsTimeGoingBackwards) {
  expectLineError("0 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n\n1.999 0 0 0 0 0 0 1\n", 4, "backwards");
}

TEST(WalkthroughParse, RejectsEmptyFile) {
  for (std::string text : {"", "\n", "# nothing\n\n  \r\n"}) {
    std::string msg = errorOf([&] { parseWalkthrough(text, "paths/e.path"); });
    EXPECT_EQ(msg.substr(0, 14), "paths/e.path: ") << msg;
    EXPECT_NE(msg.find("no control points"), std::string::npos) << msg;
  }
}

// ---- formatting ------------------------------------------------------------------

TEST(WalkthroughFormat, RoundTripIsExactForUnitNormQuaternions) {
  Walkthrough w;
  w.points = {{0, {0.1, -2.5e-7, 1e12}, {0, 0, 0, 1}},
              {0.1, {1.0 / 3, 2.0 / 3, -4.0 / 3}, {0.5, 0.5, -0.5, 0.5}},
              {0.1, {-0.0, 5, 6}, {0, -1, 0, 0}},
              {1e9, {1e-300, 1.7976931348623157e308, 3}, {1, 0, 0, 0}}};
  Walkthrough back = parseWalkthrough(formatWalkthrough(w), "w");
  EXPECT_EQ(back.points, w.points);
}

TEST(WalkthroughFormat, RandomRoundTrip) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1e4, 1e4), dt(0, 2);
  Walkthrough w;
  double t = 0;
  for (int i = 0; i < 500; ++i) {
    t += (i % 7 == 3) ? 0 : dt(rng);
    w.points.push_back({t, {u(rng), u(rng), u(rng)}, randomUnitQuat(rng)});
  }
  Walkthrough back = parseWalkthrough(formatWalkthrough(w), "w");
  ASSERT_EQ(back.points.size(), w.points.size());
  for (size_t i = 0; i < w.points.size(); ++i) {
    const auto &a = w.points[i], &b = back.points[i];
    EXPECT_EQ(a.time, b.time);
    EXPECT_EQ(a.position, b.position);
    // Renormalisation may move the last bit.
    EXPECT_NEAR(a.rotation.x, b.rotation.x, 1e-15);
    EXPECT_NEAR(a.rotation.y, b.rotation.y, 1e-15);
    EXPECT_NEAR(a.rotation.z, b.rotation.z, 1e-15);
    EXPECT_NEAR(a.rotation.w, b.rotation.w, 1e-15);
  }
}

TEST(WalkthroughFormat, OneLinePerPointWithEightFields) {
  Walkthrough w;
  w.points = {{0, {1, 2, 3}, {0, 0, 0, 1}}, {1, {4, 5, 6}, {0, 0, 0, 1}}};
  std::string text = formatWalkthrough(w);
  EXPECT_EQ(text, "0 1 2 3 0 0 0 1\n1 4 5 6 0 0 0 1\n");
}

TEST(WalkthroughFile, WriteThenReadRoundTrips) {
  fs::path dir = fs::temp_directory_path() / ("dmmr_walkthrough_test_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::string file = (dir / "cam.path").string();
  Walkthrough w;
  w.points = {{0, {1, 2, 3}, {0, 0, 0, 1}}, {0.5, {4, 5, 6}, {0.5, 0.5, 0.5, 0.5}}};
  writeWalkthrough(file, w);
  EXPECT_EQ(readWalkthrough(file).points, w.points);
  std::string missing = (dir / "missing.path").string();
  std::string msg = errorOf([&] { readWalkthrough(missing); });
  EXPECT_NE(msg.find(missing), std::string::npos) << msg;
  fs::remove_all(dir);
}

// ---- lookAtRotation ---------------------------------------------------------------

TEST(LookAt, CanonicalViewIsIdentity) {
  Quatd q = lookAtRotation({0, 0, 0}, {0, 0, -5}, {0, 1, 0});
  EXPECT_NEAR(std::fabs(q.w), 1.0, 1e-15);
  EXPECT_NEAR(q.x, 0, 1e-15);
  EXPECT_NEAR(q.y, 0, 1e-15);
  EXPECT_NEAR(q.z, 0, 1e-15);
}

TEST(LookAt, KnownDirections) {
  struct Case {
    Vec3d dir, up, right;
  };
  // Camera right = forward x up.
  for (Case c : {Case{{0, 0, 1}, {0, 1, 0}, {-1, 0, 0}}, Case{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},
                 Case{{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}}, Case{{0, -1, 0}, {0, 0, -1}, {1, 0, 0}},
                 Case{{0, 1, 0}, {1, 0, 0}, {0, 0, -1}}}) {
    Vec3d eye{3, -2, 7};
    Quatd q = lookAtRotation(eye, eye + c.dir * 4.0, c.up);
    Vec3d f = rotate(q, {0, 0, -1}), u = rotate(q, {0, 1, 0}), r = rotate(q, {1, 0, 0});
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(f[i], c.dir[i], 1e-14) << c.dir;
      EXPECT_NEAR(u[i], c.up[i], 1e-14) << c.dir;
      EXPECT_NEAR(r[i], c.right[i], 1e-14) << c.dir;
    }
  }
}

TEST(LookAt, RandomPairsLookAtTargetWithUpUp) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> u(-1000, 1000);
  std::normal_distribution<double> n(0, 1);
  for (int i = 0; i < 5000; ++i) {
    Vec3d eye{u(rng), u(rng), u(rng)}, target{u(rng), u(rng), u(rng)};
    Vec3d up = i % 2 ? Vec3d{0, 0, 1} : normalize(Vec3d{n(rng), n(rng), n(rng)}) * (1 + i % 5);
    Quatd q = lookAtRotation(eye, target, up);
    EXPECT_NEAR(quatNorm(q), 1.0, 1e-14);
    Vec3d want = normalize(target - eye);
    Vec3d f = rotate(q, {0, 0, -1});
    EXPECT_NEAR(length(f - want), 0.0, 1e-12) << "eye " << eye << " target " << target;
    Vec3d camUp = rotate(q, {0, 1, 0});
    Vec3d side = cross(want, up);
    if (length(side) > 1e-6 * length(up)) {
      EXPECT_GT(dot(camUp, up), 0) << "eye " << eye << " target " << target << " up " << up;
      // No roll: the camera's right axis is horizontal (perpendicular to up).
      EXPECT_NEAR(dot(rotate(q, {1, 0, 0}), up) / length(up), 0.0, 1e-12);
    }
  }
}

TEST(LookAt, UpParallelToViewStillLooksAtTarget) {
  for (Vec3d dir : {Vec3d{0, 0, 1}, Vec3d{0, 0, -1}, Vec3d{0, 1, 0}, Vec3d{1, 0, 0}}) {
    Quatd q = lookAtRotation({1, 2, 3}, Vec3d{1, 2, 3} + dir * 10.0, dir);
    EXPECT_NEAR(quatNorm(q), 1.0, 1e-14);
    Vec3d f = rotate(q, {0, 0, -1});
    EXPECT_NEAR(length(f - dir), 0.0, 1e-12) << dir;
  }
}

}  // namespace
}  // namespace dmmr
