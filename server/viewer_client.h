// The viewer's side of the interactive protocol (docs/interactive.md) in C++:
// what dmmr-pose-replay and the protocol tests use to talk to `dmmr-render
// --serve`. One thread; every wait has a timeout.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "viewer_protocol.h"

namespace dmmr {

// "http://HOST:PORT/PATH?token=T" split up; false when it is not such a URL.
struct ServeUrl {
  std::string host, port, token;
};
bool parseServeUrl(const std::string& url, ServeUrl* out);

// GET `target` (e.g. "/?token=..."): the status code and body. Throws Error
// when the server cannot be reached.
std::pair<int, std::string> httpGet(const ServeUrl& at, const std::string& target,
                                    double timeout_s = 10);

class ViewerClient {
 public:
  // Opens /ws with `token` (the URL's unless given) and reads the hello.
  // Throws Error, with the HTTP status when the upgrade is refused.
  explicit ViewerClient(const ServeUrl& at, double timeout_s = 10);
  ViewerClient(const ServeUrl& at, const std::string& token, double timeout_s = 10);
  ~ViewerClient();

  const nlohmann::json& hello() const { return hello_; }

  void sendPose(const Pose& p);
  void sendAck(uint32_t frame);
  void sendBytes(const std::vector<uint8_t>& bytes, bool binary = true);

  struct Received {
    enum class Kind { Frame, Closed, Timeout } kind = Kind::Timeout;
    FrameMessage frame;     // Frame
    nlohmann::json header;  // Frame: its header, parsed
    double at_ms = 0;       // when it arrived (steady clock, ms)
    int close_code = 0;     // Closed: the server's code (0: none) and reason
    std::string close_reason;
  };
  // Waits up to timeout_s for the next message. A Timeout leaves the read
  // pending, so a later call goes on waiting for the same message. Throws
  // Error for a frame message that does not decode.
  Received receive(double timeout_s);

  // Closes the connection from this side (a clean WebSocket close).
  void close();
  // Drops the TCP connection without a close handshake.
  void abort();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  nlohmann::json hello_;
};

// The steady clock in ms, the clock poses' time_ms and Received::at_ms use.
double steadyMs();

}  // namespace dmmr
