// The interactive mode's front door (dmmr-render --serve): an HTTP and
// WebSocket server on rank 0 that serves the viewer page, takes poses from
// viewers and sends each its frames (docs/interactive.md). The render loop
// asks it for the next pose (nextPose) and hands it each assembled frame
// (frameDone); which pose and which frame go when is ViewerSchedule's.
//
// Threads: one runs the network (Boost.Asio), one encodes frames (JPEG, PNG)
// and sends the still frames when due; the caller's planning and assembling
// threads only block in nextPose.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "image.h"
#include "math.h"
#include "viewer_protocol.h"

namespace dmmr {

struct ServeOptions {
  std::string address = "127.0.0.1";
  uint16_t port = 0;      // 0: any free port (the URL says which)
  double still_ms = 250;  // no pose for this long: the exact frame follows
  int max_rate = 240;     // poses a second a viewer may send, and as many acks
  int max_viewers = 8;    // viewers at once; more are refused (HTTP 503)
  int max_rendering = 1;  // a viewer's frames in the render pipeline at once
  // The moving frames are approximate (--ray-stride): a still frame is the
  // viewer's last pose rendered again, exact, rather than its last frame
  // sent again losslessly.
  bool render_stills = false;
};

// Parses "[ADDR:]PORT" (ADDR an IPv4 or IPv6 address, IPv6 in brackets, or
// "localhost"); false for anything else.
bool parseServeAddress(const std::string& spec, std::string* address, uint16_t* port);

// What the page needs to start: image size, field of view, the home pose,
// the scene's bounds (for navigation speeds) and the number of clients.
struct ViewerHello {
  int width = 0, height = 0;
  double fovy_deg = 45;
  int clients = 0;
  Vec3d home_position;
  Quatd home_rotation;
  Box3d bounds;
};

// A frame the render loop assembled, with what its header reports.
struct FrameDone {
  struct Client {
    uint64_t pixels = 0, triangles = 0;
    double ms = 0;  // the client's stage time on the frame
  };
  uint32_t frame = 0;
  Image image;  // RGBA, top row first
  double cull_ms = 0, divide_ms = 0, assemble_ms = 0, frame_ms = 0, latency_ms = 0;
  uint64_t triangles = 0;
  std::vector<Client> clients;
};

class ViewerHub {
 public:
  // `page`: the viewer page's HTML, served at "/".
  ViewerHub(const ServeOptions& opts, const ViewerHello& hello, std::string page);
  ~ViewerHub();  // stops, closes every connection, joins its threads
  ViewerHub(const ViewerHub&) = delete;
  ViewerHub& operator=(const ViewerHub&) = delete;

  // Binds and starts serving; returns the page's URL with the run's token.
  // Throws Error when the address cannot be bound.
  std::string start();

  // Planning thread: blocks until some viewer has a pose to render (and
  // room in the pipeline), records that `frame` renders it, and returns it
  // (rotation as sent). Nothing once stopped. `*exact` (when given) is true
  // for a still frame's render (render_stills), which must be exact.
  std::optional<Pose> nextPose(uint32_t frame, bool* exact = nullptr);

  // Assembling thread: `d.frame` (one nextPose returned) is assembled.
  void frameDone(FrameDone d);

  // Ends nextPose's waits and closes every viewer ("server stopping").
  // Idempotent; SIGINT and SIGTERM call it too.
  void stop();

  struct Impl;  // the network sessions (serve.cpp) reach it

 private:
  std::unique_ptr<Impl> impl_;
};

// The page the server serves (server/viewer/index.html, built in).
const std::string& viewerPage();

}  // namespace dmmr
