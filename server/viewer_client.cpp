#include "viewer_client.h"

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <optional>

#include "error.h"

namespace dmmr {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

double steadyMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

bool parseServeUrl(const std::string& url, ServeUrl* out) {
  const std::string scheme = "http://";
  if (url.rfind(scheme, 0) != 0) return false;
  std::string rest = url.substr(scheme.size());
  size_t slash = rest.find_first_of("/?");
  std::string hostport = rest.substr(0, slash);
  std::string tail = slash == std::string::npos ? "" : rest.substr(slash);
  size_t colon = hostport.rfind(':');
  if (colon == std::string::npos || colon + 1 == hostport.size()) return false;
  ServeUrl u;
  u.host = hostport.substr(0, colon);
  if (u.host.size() >= 2 && u.host.front() == '[') u.host = u.host.substr(1, u.host.size() - 2);
  u.port = hostport.substr(colon + 1);
  if (size_t t = tail.find("token="); t != std::string::npos) {
    u.token = tail.substr(t + 6);
    u.token = u.token.substr(0, u.token.find('&'));
  }
  *out = u;
  return true;
}

namespace {

// Runs `ioc` until `done` or the timeout; false on timeout.
bool runUntil(net::io_context& ioc, const bool& done, double timeout_s) {
  auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  ioc.restart();
  while (!done) {
    auto left = deadline - std::chrono::steady_clock::now();
    if (left <= std::chrono::steady_clock::duration::zero()) return false;
    ioc.run_one_for(std::chrono::duration_cast<std::chrono::steady_clock::duration>(left));
  }
  return true;
}

}  // namespace

std::pair<int, std::string> httpGet(const ServeUrl& at, const std::string& target,
                                    double timeout_s) {
  net::io_context ioc;
  beast::tcp_stream stream(ioc);
  beast::flat_buffer buf;
  http::response<http::string_body> res;
  beast::error_code failed;
  bool done = false;
  tcp::resolver resolver(ioc);
  stream.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(timeout_s)));
  auto req = std::make_shared<http::request<http::empty_body>>(http::verb::get, target, 11);
  req->set(http::field::host, at.host);
  resolver.async_resolve(
      at.host, at.port, [&](beast::error_code ec, tcp::resolver::results_type r) {
        if (ec) return void((failed = ec, done = true));
        stream.async_connect(r, [&](beast::error_code ec, const tcp::endpoint&) {
          if (ec) return void((failed = ec, done = true));
          http::async_write(stream, *req, [&](beast::error_code ec, size_t) {
            if (ec) return void((failed = ec, done = true));
            http::async_read(stream, buf, res, [&](beast::error_code ec, size_t) {
              failed = ec;
              done = true;
            });
          });
        });
      });
  if (!runUntil(ioc, done, timeout_s + 1) || failed)
    throw Error("GET http://" + at.host + ":" + at.port + target + ": " +
                (failed ? failed.message() : std::string("timed out")));
  return {int(res.result_int()), res.body()};
}

struct ViewerClient::Impl {
  net::io_context ioc;
  websocket::stream<beast::tcp_stream> ws{ioc};
  beast::flat_buffer buf;
  bool reading = false, read_done = false;
  beast::error_code read_ec;
  bool text = false;

  void startRead() {
    reading = true;
    read_done = false;
    ws.async_read(buf, [this](beast::error_code ec, size_t) {
      read_ec = ec;
      text = ws.got_text();
      read_done = true;
    });
  }
};

ViewerClient::ViewerClient(const ServeUrl& at, double timeout_s)
    : ViewerClient(at, at.token, timeout_s) {}

ViewerClient::ViewerClient(const ServeUrl& at, const std::string& token, double timeout_s)
    : impl_(std::make_unique<Impl>()) {
  Impl& c = *impl_;
  tcp::resolver resolver(c.ioc);
  beast::error_code failed;
  bool done = false;
  websocket::response_type res;
  std::string target = "/ws?token=" + token;
  std::string where = "ws://" + at.host + ":" + at.port + "/ws";
  resolver.async_resolve(
      at.host, at.port, [&](beast::error_code ec, tcp::resolver::results_type r) {
        if (ec) return void((failed = ec, done = true));
        beast::get_lowest_layer(c.ws).async_connect(
            r, [&](beast::error_code ec, const tcp::endpoint&) {
              if (ec) return void((failed = ec, done = true));
              beast::error_code ignored;  // no Nagle delay on poses and acks
              beast::get_lowest_layer(c.ws).socket().set_option(tcp::no_delay(true), ignored);
              c.ws.async_handshake(res, at.host + ":" + at.port, target, [&](beast::error_code ec) {
                failed = ec;
                done = true;
              });
            });
      });
  if (!runUntil(c.ioc, done, timeout_s)) throw Error(where + ": no answer within the timeout");
  if (failed == websocket::error::upgrade_declined)
    throw Error(where + ": refused with HTTP " + std::to_string(res.result_int()) + " (" +
                res.body() + ")");
  if (failed) throw Error(where + ": " + failed.message());
  c.ws.read_message_max(64 << 20);
  Received hello = receive(timeout_s);
  if (hello.kind != Received::Kind::Frame || !hello.header.is_object() ||
      hello.header.value("type", "") != "hello")
    throw Error(where + ": no hello from the server");
  hello_ = hello.header;
}

ViewerClient::~ViewerClient() = default;

// Writes are asynchronous too (Beast does not mix a blocking write with the
// pending read); a frame that arrives meanwhile waits for receive().
void ViewerClient::sendBytes(const std::vector<uint8_t>& bytes, bool binary) {
  Impl& c = *impl_;
  c.ws.binary(binary);
  bool done = false;
  beast::error_code failed;
  c.ws.async_write(net::buffer(bytes), [&](beast::error_code ec, size_t) {
    failed = ec;
    done = true;
  });
  if (!runUntil(c.ioc, done, 10)) throw Error("viewer: a send did not complete within 10 s");
  if (failed) throw Error("viewer: send failed: " + failed.message());
}

void ViewerClient::sendPose(const Pose& p) {
  sendBytes(encodePose(p));
}

void ViewerClient::sendAck(uint32_t frame) {
  sendBytes(encodeAck(frame));
}

ViewerClient::Received ViewerClient::receive(double timeout_s) {
  Impl& c = *impl_;
  if (!c.reading) c.startRead();
  Received r;
  if (!runUntil(c.ioc, c.read_done, timeout_s)) return r;  // Timeout, read still pending
  c.reading = false;
  r.at_ms = steadyMs();
  if (c.read_ec) {
    r.kind = Received::Kind::Closed;
    r.close_code = int(c.ws.reason().code);
    r.close_reason = std::string(c.ws.reason().reason.data(), c.ws.reason().reason.size());
    return r;
  }
  auto data = c.buf.cdata();
  const auto* p = static_cast<const uint8_t*>(data.data());
  r.kind = Received::Kind::Frame;
  if (c.text) {  // the hello
    r.header = nlohmann::json::parse(std::string(reinterpret_cast<const char*>(p), data.size()),
                                     nullptr, /*allow_exceptions=*/false);
  } else {
    r.frame = decodeFrameMessage(p, data.size());
    r.header = nlohmann::json::parse(r.frame.header, nullptr, false);
    if (r.header.is_discarded()) throw Error("frame message: header is not JSON");
  }
  c.buf.consume(c.buf.size());
  return r;
}

void ViewerClient::close() {
  Impl& c = *impl_;
  if (!c.reading) c.startRead();  // the read sees the server's close frame
  bool done = false;
  c.ws.async_close(websocket::close_code::normal, [&](beast::error_code) { done = true; });
  runUntil(c.ioc, done, 5);
  runUntil(c.ioc, c.read_done, 1);
  c.reading = false;
}

void ViewerClient::abort() {
  beast::error_code ignored;
  beast::get_lowest_layer(impl_->ws).socket().close(ignored);
}

}  // namespace dmmr
