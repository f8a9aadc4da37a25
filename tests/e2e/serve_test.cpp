// End to end, interactive mode: `mpirun dmmr-render --serve` on a small
// scene, driven by C++ viewers (server/viewer_client.h). The still frame must
// equal dmmr-reference's frame for its pose (tolerance zero), and a viewer
// that misbehaves (wrong token, malformed, oversized or too many messages,
// vanishing mid-frame) is cut off while the run and the other viewers go on.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include "image.h"
#include "jpeg.h"
#include "test_support.h"
#include "viewer_client.h"
#include "walkthrough.h"

using namespace dmmr;
using dmmr::test::TempDir;
using Kind = ViewerClient::Received::Kind;

namespace {

constexpr int kSide = 160;

// A generated plant, preprocessed once for every test here.
struct PlantScene {
  TempDir dir;
  std::string scene, path;
  Walkthrough walk;
  PlantScene() {
    std::string model = dir / "plant.osgb";
    path = dir / "plant.path";
    EXPECT_EQ(test::run(test::tool("dmmr-scenegen") + " plant --seed 3 --triangles 30000 -o " +
                        model + " --walkthrough " + path + " --frames 12 > /dev/null"),
              0);
    scene = dir / "scene";
    EXPECT_EQ(
        test::run(test::tool("dmmr-preprocess") + " " + model + " -o " + scene + " > /dev/null"),
        0);
    walk = readWalkthrough(path);
  }
};

PlantScene& plant() {
  static PlantScene s;
  return s;
}

// One `dmmr-render --serve` run in the background, stopped when destroyed.
class Served {
 public:
  explicit Served(int clients, const std::string& extra = "") {
    log_ = dir_ / "log";
    std::string cmd = "exec " + test::mpirun(clients + 1) + " " + test::tool("dmmr-render") +
                      " --scene " + plant().scene + " --serve 127.0.0.1:0 --width " +
                      std::to_string(kSide) + " --height " + std::to_string(kSide) + " " + extra +
                      " > " + log_ + " 2>&1";
    pid_ = ::fork();
    if (pid_ == 0) {
      ::setpgid(0, 0);  // its own group: the destructor ends mpirun and ranks
      ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    std::regex line(R"(serving (http://\S+) \(server pid (\d+))");
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < deadline) {
      std::smatch m;
      std::string text = log();
      if (std::regex_search(text, m, line)) {
        parseServeUrl(m[1], &url);
        server_pid_ = std::stoi(m[2]);
        return;
      }
      if (exited()) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ADD_FAILURE() << "no URL from dmmr-render --serve:\n" << log();
  }

  ~Served() {
    if (!done_) {
      ::kill(-pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }

  std::string log() const {
    std::ifstream f(log_);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }

  // SIGTERM to the server rank; the run's exit status (-1: it did not end
  // within `timeout_s`).
  int stop(double timeout_s = 30) {
    ::kill(server_pid_, SIGTERM);
    auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < deadline) {
      if (exited()) return status_;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return -1;
  }

  ServeUrl url;

 private:
  bool exited() {
    if (done_) return true;
    int s = 0;
    if (::waitpid(pid_, &s, WNOHANG) != pid_) return false;
    done_ = true;
    status_ = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
    return true;
  }

  TempDir dir_;
  std::string log_;
  pid_t pid_ = -1;
  int server_pid_ = 0;
  bool done_ = false;
  int status_ = -1;
};

Pose poseAt(const ControlPoint& cp, uint32_t seq, uint8_t quality = 80) {
  Pose p;
  p.seq = seq;
  p.time_ms = steadyMs();
  p.position = cp.position;
  p.rotation = cp.rotation;
  p.fovy_deg = 45;
  p.width = p.height = kSide;
  p.quality = quality;
  return p;
}

// Receives until a frame comes (acking it) or `timeout_s` passes.
ViewerClient::Received frameWithin(ViewerClient& v, double timeout_s, bool ack = true) {
  double end = steadyMs() + timeout_s * 1000;
  for (double now = steadyMs(); now < end; now = steadyMs()) {
    ViewerClient::Received r = v.receive((end - now) / 1000);
    if (r.kind == Kind::Frame && ack) v.sendAck(r.header.value("frame", 0u));
    if (r.kind != Kind::Timeout) return r;
  }
  return {};
}

// Receives frames (acking each) until the still frame comes.
ViewerClient::Received stillWithin(ViewerClient& v, double timeout_s) {
  double end = steadyMs() + timeout_s * 1000;
  while (steadyMs() < end) {
    ViewerClient::Received r = frameWithin(v, (end - steadyMs()) / 1000);
    if (r.kind != Kind::Frame || r.header.value("still", false)) return r;
  }
  return {};
}

// dmmr-reference's frame for one pose.
Image referenceFor(const Pose& p, const TempDir& dir, const std::string& name) {
  Walkthrough w;
  w.points.push_back({0, p.position, p.rotation});
  writeWalkthrough(dir / (name + ".path"), w);
  EXPECT_EQ(
      test::run(test::tool("dmmr-reference") + " --no-progress --width " + std::to_string(kSide) +
                " --height " + std::to_string(kSide) + " --scene " + plant().scene +
                " --walkthrough " + dir / (name + ".path") + " --out " + dir / name),
      0);
  return readPng(dir / name + "/frame_000000.png");
}

Image decoded(const ViewerClient::Received& r) {
  return r.frame.encoding == FrameEncoding::Png ? decodePng(r.frame.image, "still.png") : Image{};
}

}  // namespace

TEST(Serve, PageAndSocketRefuseAWrongOrMissingToken) {
  Served s(1);
  auto [ok, page] = httpGet(s.url, "/?token=" + s.url.token);
  EXPECT_EQ(ok, 200);
  EXPECT_NE(page.find("<html"), std::string::npos);
  EXPECT_EQ(httpGet(s.url, "/?token=0123").first, 403);
  EXPECT_EQ(httpGet(s.url, "/").first, 403);
  EXPECT_EQ(httpGet(s.url, "/nothing?token=" + s.url.token).first, 404);
  std::string err = test::errorOf([&] { ViewerClient v(s.url, "not-the-token"); });
  EXPECT_NE(err.find("HTTP 403"), std::string::npos) << err;
  // The run is unharmed: a viewer with the token gets its hello.
  ViewerClient v(s.url);
  EXPECT_EQ(v.hello().value("width", 0), kSide);
  EXPECT_EQ(s.stop(), 0) << s.log();
}

TEST(Serve, MovingFramesAreJpegAndTheStillFrameEqualsTheReference) {
  TempDir out;
  Served s(2);
  ViewerClient v(s.url);
  EXPECT_EQ(v.hello().value("clients", 0), 2);
  const auto& pts = plant().walk.points;
  Pose last;
  for (uint32_t i = 0; i < 3; ++i) {
    last = poseAt(pts[i * 4], i + 1);
    v.sendPose(last);
    ViewerClient::Received r = frameWithin(v, 30);
    // On a slow machine (TSan) a frame can take longer than the still delay,
    // so the previous pose's still frame may come first: it is not this pose's.
    while (r.kind == Kind::Frame && r.header.value("still", false) &&
           r.header.value("seq", 0u) == i)
      r = frameWithin(v, 30);
    ASSERT_EQ(r.kind, Kind::Frame) << s.log();
    EXPECT_EQ(r.frame.encoding, FrameEncoding::Jpeg);
    EXPECT_FALSE(r.header.value("still", true));
    EXPECT_EQ(r.header.value("seq", 0u), i + 1) << "one pose at a time: each is rendered";
    EXPECT_EQ(r.header.value("time_ms", 0.0), last.time_ms) << "echoed bit for bit";
    EXPECT_EQ(r.header["clients"].size(), 2u);
    EXPECT_GT(r.header.value("triangles", 0u), 0u);
    Image jpeg = decodeJpeg(r.frame.image, "moving.jpg");
    EXPECT_EQ(jpeg.width, kSide);
  }
  ViewerClient::Received still = stillWithin(v, 30);
  ASSERT_EQ(still.kind, Kind::Frame) << s.log();
  EXPECT_EQ(still.frame.encoding, FrameEncoding::Png);
  EXPECT_EQ(still.header.value("seq", 0u), last.seq);
  // The header's pose, written to a walkthrough, is the one to render.
  std::vector<double> pos = still.header["pose"]["position"],
                      rot = still.header["pose"]["rotation"];
  EXPECT_EQ(pos, (std::vector<double>{last.position.x, last.position.y, last.position.z}));
  EXPECT_EQ(rot, (std::vector<double>{last.rotation.x, last.rotation.y, last.rotation.z,
                                      last.rotation.w}));
  Image ref = referenceFor(last, out, "ref");
  Image got = decoded(still);
  EXPECT_TRUE(got == ref) << "the still frame differs from dmmr-reference's (tolerance 0)";
  EXPECT_EQ(s.stop(), 0) << s.log();
}

TEST(Serve, AViewerHasOneFrameInFlightAndGetsTheLatestWhenItAcks) {
  Served s(1);
  ViewerClient v(s.url);
  const auto& pts = plant().walk.points;
  v.sendPose(poseAt(pts[0], 1));
  ViewerClient::Received first = frameWithin(v, 30, /*ack=*/false);
  ASSERT_EQ(first.kind, Kind::Frame) << s.log();
  // Unacknowledged: newer poses render, but nothing more is sent.
  for (uint32_t seq = 2; seq <= 5; ++seq) {
    v.sendPose(poseAt(pts[seq], seq));
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
  }
  EXPECT_EQ(frameWithin(v, 1.5, false).kind, Kind::Timeout) << "a second frame in flight";
  v.sendAck(first.header.value("frame", 0u));
  ViewerClient::Received next = frameWithin(v, 30);
  ASSERT_EQ(next.kind, Kind::Frame);
  EXPECT_EQ(next.header.value("seq", 0u), 5u) << "the latest pose's frame, older ones dropped";
  // A stale pose (seq not above the latest) is dropped: no frame for it.
  v.sendPose(poseAt(pts[1], 3));
  ViewerClient::Received after = frameWithin(v, 1.5);
  if (after.kind == Kind::Frame) {
    EXPECT_TRUE(after.header.value("still", false));
  }
  EXPECT_EQ(s.stop(), 0) << s.log();
}

// dmmr-render's ray-traced walkthrough frame for one pose, `extra` added.
Image rayTracedFor(const Pose& p, const TempDir& dir, const std::string& name,
                   const std::string& extra) {
  Walkthrough w;
  w.points.push_back({0, p.position, p.rotation});
  writeWalkthrough(dir / (name + ".path"), w);
  EXPECT_EQ(test::run(test::mpirun(2) + " " + test::tool("dmmr-render") +
                      " --no-progress --renderer raytrace --width " + std::to_string(kSide) +
                      " --height " + std::to_string(kSide) + " --scene " + plant().scene +
                      " --walkthrough " + dir / (name + ".path") + " --out " + dir / name + " " +
                      extra + " > /dev/null 2>&1"),
            0);
  return readPng(dir / name + "/frame_000000.png");
}

// With a ray stride the moving frame traces fewer rays; the still frame is
// the same pose rendered again with every ray, not the moving frame re-sent.
TEST(Serve, WithARayStrideTheStillIsRenderedAgainExact) {
  Served s(2, "--renderer raytrace --ray-stride 3");
  ViewerClient v(s.url);
  Pose pose = poseAt(plant().walk.points[4], 1, /*quality=*/0);  // 0: moving frames as PNG
  v.sendPose(pose);
  ViewerClient::Received moving = frameWithin(v, 30);
  ASSERT_EQ(moving.kind, Kind::Frame) << s.log();
  EXPECT_FALSE(moving.header.value("still", true));
  ViewerClient::Received still = stillWithin(v, 30);
  ASSERT_EQ(still.kind, Kind::Frame) << s.log();
  EXPECT_EQ(still.header.value("seq", 0u), 1u);
  EXPECT_EQ(still.header.value("frame", 0u), moving.header.value("frame", 1u))
      << "sent under the id the viewer's schedule holds in flight";
  TempDir out;
  Image strided = rayTracedFor(pose, out, "strided", "--ray-stride 3");
  Image exact = rayTracedFor(pose, out, "exact", "");
  EXPECT_TRUE(decoded(moving) == strided) << "the moving frame is the strided one";
  EXPECT_TRUE(decoded(still) == exact) << "the still frame is every ray's (tolerance 0)";
  EXPECT_FALSE(strided == exact);
  EXPECT_EQ(s.stop(), 0) << s.log();
}

TEST(Serve, APoseThatComesWhileTheViewersFrameRendersIsRenderedNext) {
  // The second pose arrives while the first renders (the viewer's one slot
  // in the pipeline taken); when that frame is done it must go at once, not
  // wait for a third pose.
  Served s(1);
  ViewerClient v(s.url);
  const auto& pts = plant().walk.points;
  v.sendPose(poseAt(pts[0], 1));
  v.sendPose(poseAt(pts[6], 2));
  ViewerClient::Received a = frameWithin(v, 30);
  ASSERT_EQ(a.kind, Kind::Frame) << s.log();
  // Both poses may arrive before the first render starts; then pose 1 is
  // stale and dropped, and the next message is already the still frame.
  if (a.header.value("seq", 0u) == 1u) {
    ViewerClient::Received b = frameWithin(v, 10);
    ASSERT_EQ(b.kind, Kind::Frame) << "no frame for the pose that came during a render";
    EXPECT_EQ(b.header.value("seq", 0u), 2u);
    EXPECT_FALSE(b.header.value("still", true));
  }
  ViewerClient::Received still = stillWithin(v, 10);
  ASSERT_EQ(still.kind, Kind::Frame) << s.log();
  EXPECT_EQ(still.header.value("seq", 0u), 2u);
  EXPECT_EQ(s.stop(), 0) << s.log();
}

TEST(Serve, MalformedOversizedAndTooFastViewersAreCutOffWhileTheRunGoesOn) {
  Served s(1, "--serve-max-rate 30");
  const auto& pts = plant().walk.points;
  ViewerClient good(s.url);

  ViewerClient malformed(s.url);
  malformed.sendBytes({'D', 'M', 'V', 'W', 1, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0});
  ViewerClient::Received r = malformed.receive(10);
  ASSERT_EQ(r.kind, Kind::Closed);
  EXPECT_EQ(r.close_code, 1007);
  EXPECT_NE(r.close_reason.find("viewer message"), std::string::npos) << r.close_reason;

  ViewerClient oversized(s.url);
  oversized.sendBytes(std::vector<uint8_t>(kMaxViewerMessageBytes + 1, 7));
  r = oversized.receive(10);
  ASSERT_EQ(r.kind, Kind::Closed);
  EXPECT_EQ(r.close_code, 1009);

  // Poses and acks count apart: 25 of each in a second, each under the
  // limit of 30, keep the viewer (it was cut off when they counted together).
  ViewerClient busy(s.url);
  for (int i = 0; i < 25; ++i) {
    busy.sendPose(poseAt(pts[size_t(i) % pts.size()], uint32_t(i + 1)));
    busy.sendAck(uint32_t(i));
  }

  ViewerClient fast(s.url);
  for (int i = 0; i < 40; ++i) fast.sendAck(uint32_t(i));
  r = fast.receive(10);
  ASSERT_EQ(r.kind, Kind::Closed);
  EXPECT_EQ(r.close_code, 1008);
  EXPECT_NE(r.close_reason.find("too many messages"), std::string::npos) << r.close_reason;

  ViewerClient text(s.url);
  text.sendBytes({'h', 'i'}, /*binary=*/false);
  EXPECT_EQ(text.receive(10).kind, Kind::Closed);

  // The busy viewer is still served: a frame comes, not a close.
  r = frameWithin(busy, 30);
  EXPECT_EQ(r.kind, Kind::Frame) << r.close_reason << s.log();

  // The good viewer is served all along.
  good.sendPose(poseAt(pts[2], 1));
  r = frameWithin(good, 30);
  ASSERT_EQ(r.kind, Kind::Frame) << s.log();
  EXPECT_EQ(r.header.value("seq", 0u), 1u);
  EXPECT_EQ(s.stop(), 0) << s.log();
}

TEST(Serve, AViewerVanishingMidFrameLeavesTheRunAndOthersGoing) {
  Served s(2);
  const auto& pts = plant().walk.points;
  {
    ViewerClient gone(s.url);
    gone.sendPose(poseAt(pts[0], 1));
    gone.abort();  // TCP dropped while its frame renders
  }
  {
    ViewerClient closing(s.url);
    closing.sendPose(poseAt(pts[1], 1));
    closing.close();  // a clean close mid-frame
  }
  ViewerClient v(s.url);
  v.sendPose(poseAt(pts[3], 1));
  ViewerClient::Received r = frameWithin(v, 30);
  ASSERT_EQ(r.kind, Kind::Frame) << s.log();
  EXPECT_EQ(r.header.value("seq", 0u), 1u);
  EXPECT_EQ(s.stop(), 0) << s.log();
}

TEST(Serve, TwoViewersAtOnceEachGetTheirOwnFramesFairly) {
  TempDir out;
  Served s(2);
  const auto& pts = plant().walk.points;
  ViewerClient a(s.url), b(s.url);
  // Both stream poses at 30 Hz, 20 of them and on until each has had two
  // frames (a slow machine, or a sanitizer, renders fewer in 20); each acks
  // what it gets.
  std::map<char, int> frames;
  std::map<char, Pose> last;
  uint32_t seq = 0;
  const double deadline = steadyMs() + 60000;
  for (int i = 0; i < 20 || ((frames['a'] < 2 || frames['b'] < 2) && steadyMs() < deadline); ++i) {
    ++seq;
    last['a'] = poseAt(pts[size_t(i) % pts.size()], seq);
    last['b'] = poseAt(pts[pts.size() - 1 - size_t(i) % pts.size()], seq);
    a.sendPose(last['a']);
    b.sendPose(last['b']);
    double end = steadyMs() + 33;
    for (auto* v : {&a, &b}) {
      char name = v == &a ? 'a' : 'b';
      for (double now = steadyMs(); now < end; now = steadyMs()) {
        ViewerClient::Received r = v->receive((end - now) / 2000);
        if (r.kind == Kind::Closed) FAIL() << "viewer " << name << " closed: " << r.close_reason;
        if (r.kind != Kind::Frame) break;
        v->sendAck(r.header.value("frame", 0u));
        ++frames[name];
      }
    }
  }
  // Each viewer's still frame is its own last pose, exact.
  for (auto* v : {&a, &b}) {
    char name = v == &a ? 'a' : 'b';
    ViewerClient::Received still = stillWithin(*v, 30);
    ASSERT_EQ(still.kind, Kind::Frame) << name << "\n" << s.log();
    EXPECT_EQ(still.header.value("seq", 0u), last[name].seq);
    EXPECT_TRUE(decoded(still) == referenceFor(last[name], out, std::string(1, name)))
        << "viewer " << name << "'s still frame";
  }
  EXPECT_GE(frames['a'], 2);
  EXPECT_GE(frames['b'], 2);
  // Taking turns: neither gets more than about twice the other's frames.
  EXPECT_LE(frames['a'], 2 * frames['b'] + 2);
  EXPECT_LE(frames['b'], 2 * frames['a'] + 2);
  EXPECT_EQ(s.stop(), 0) << s.log();
}

TEST(Serve, SigtermToTheServerEndsTheRunInOrderAndTellsTheViewers) {
  Served s(1);
  ViewerClient v(s.url);
  EXPECT_EQ(s.stop(), 0) << s.log();
  ViewerClient::Received r = v.receive(10);
  ASSERT_EQ(r.kind, Kind::Closed);
  EXPECT_EQ(r.close_code, 1001);
  EXPECT_NE(r.close_reason.find("server stopping"), std::string::npos);
}

TEST(Serve, BadServeAddressesAreUsageErrors) {
  for (const char* spec : {"99999", "abc", "1.2.3:80", "127.0.0.1:", ""}) {
    int status = 0;
    std::string out = test::runCapture(test::mpirun(2) + " " + test::tool("dmmr-render") +
                                           " --scene " + plant().scene + " --serve '" + spec + "'",
                                       &status);
    EXPECT_NE(status, 0) << spec;
    EXPECT_NE(out.find("--serve"), std::string::npos) << spec << ": " << out;
  }
}
