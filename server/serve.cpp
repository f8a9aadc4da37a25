#include "serve.h"

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "error.h"
#include "jpeg.h"
#include "viewer_schedule.h"

namespace dmmr {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;
using Bytes = std::shared_ptr<const std::vector<uint8_t>>;

bool parseServeAddress(const std::string& spec, std::string* address, uint16_t* port) {
  std::string addr = "127.0.0.1", digits = spec;
  if (size_t colon = spec.rfind(':'); colon != std::string::npos) {
    addr = spec.substr(0, colon);
    digits = spec.substr(colon + 1);
    if (addr.size() >= 2 && addr.front() == '[' && addr.back() == ']')
      addr = addr.substr(1, addr.size() - 2);
    if (addr == "localhost") addr = "127.0.0.1";
    boost::system::error_code ec;
    net::ip::make_address(addr, ec);
    if (ec) return false;
  }
  if (digits.empty() || digits.size() > 5 ||
      digits.find_first_not_of("0123456789") != std::string::npos)
    return false;
  unsigned long p = std::stoul(digits);
  if (p > 65535) return false;
  *address = addr;
  *port = uint16_t(p);
  return true;
}

namespace {

double nowMs() {
  return std::chrono::duration<double, std::milli>(Clock::now().time_since_epoch()).count();
}

std::string randomToken() {
  std::random_device rd;  // the kernel's entropy: a token must not be guessable
  std::string t;
  const char* hex = "0123456789abcdef";
  for (int i = 0; i < 4; ++i) {
    uint32_t v = rd();
    for (int j = 0; j < 8; ++j) t += hex[(v >> (4 * j)) & 15];
  }
  return t;
}

// Compares without an early exit, so timing says nothing about the token.
bool sameToken(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= unsigned(a[i] ^ b[i]);
  return diff == 0;
}

// The value of `key` in the target's query string ("" when absent).
std::string queryParam(std::string_view target, std::string_view key) {
  size_t q = target.find('?');
  if (q == std::string_view::npos) return "";
  std::string_view query = target.substr(q + 1);
  while (!query.empty()) {
    size_t amp = query.find('&');
    std::string_view kv = query.substr(0, amp);
    size_t eq = kv.find('=');
    if (eq != std::string_view::npos && kv.substr(0, eq) == key)
      return std::string(kv.substr(eq + 1));
    if (amp == std::string_view::npos) break;
    query = query.substr(amp + 1);
  }
  return "";
}

std::string_view targetPath(std::string_view target) {
  return target.substr(0, target.find('?'));
}

nlohmann::json vec(const Vec3d& v) {
  return {v.x, v.y, v.z};
}
nlohmann::json quat(const Quatd& q) {
  return {q.x, q.y, q.z, q.w};
}

class WsSession;

}  // namespace

struct ViewerHub::Impl {
  ServeOptions opts;
  ViewerHello hello;
  std::string page, token;
  net::io_context ioc;
  tcp::acceptor acceptor{ioc};
  net::signal_set signals{ioc};
  std::thread io_thread, encoder_thread;

  // Network thread only.
  std::map<uint64_t, std::shared_ptr<WsSession>> sessions;
  uint64_t next_id = 1;

  // Everything below under mu.
  mutable std::mutex mu;
  std::condition_variable plan_cv, encode_cv;
  bool stopped = false;
  ViewerSchedule schedule;
  struct Picked {
    uint64_t viewer;
    Pose pose;
    double wait_ms;  // from the pose's arrival to its pick
    double picked_ms;
    // A still frame rendered again (render_stills): sent under the id of
    // the frame the schedule has in flight for it.
    bool still = false;
    uint32_t still_frame = 0;
  };
  struct StillRender {
    uint64_t viewer;
    uint32_t frame;  // the schedule's id for the still
    Pose pose;
  };
  std::deque<StillRender> still_renders;  // due, not yet picked
  std::map<uint32_t, Picked> picked;      // frame -> the viewer and pose it renders
  struct Viewer {
    uint8_t quality = 80;
    // The viewer's last frame, for its still; and an encoded frame held
    // until the viewer acknowledges the one in flight.
    std::shared_ptr<const FrameDone> last;
    Pose last_pose;
    Bytes held;
  };
  std::map<uint64_t, Viewer> viewers;
  struct Encode {
    std::shared_ptr<const FrameDone> frame;
    uint64_t viewer;
    Pose pose;
    double wait_ms, picked_ms, done_ms;
    bool still = false;
    uint32_t still_frame = 0;
  };
  std::deque<Encode> encodes;

  Impl(const ServeOptions& o, const ViewerHello& h, std::string p)
      : opts(o),
        hello(h),
        page(std::move(p)),
        token(randomToken()),
        schedule(o.max_rendering, o.still_ms) {}

  std::string helloJson() const {
    nlohmann::json j = {
        {"type", "hello"},
        {"width", hello.width},
        {"height", hello.height},
        {"fovy_deg", hello.fovy_deg},
        {"clients", hello.clients},
        {"home", {{"position", vec(hello.home_position)}, {"rotation", quat(hello.home_rotation)}}},
        {"bounds", {{"min", vec(hello.bounds.lo)}, {"max", vec(hello.bounds.hi)}}},
        {"up", {0, 0, 1}},
        {"still_ms", opts.still_ms}};
    return j.dump();
  }

  // Network thread.
  void accept();
  void added(uint64_t id, std::shared_ptr<WsSession> s);
  void removed(uint64_t id);
  void onPose(uint64_t id, const Pose& p);
  void onAck(uint64_t id, uint32_t frame);
  void sendTo(uint64_t id, Bytes bytes);  // any thread: posts to the network thread

  void encoderLoop();
  // `e`: a moving frame's timings (null for a still frame).
  Bytes encodeFrame(const FrameDone& d, const Pose& pose, uint8_t quality, bool still,
                    const Encode* e = nullptr);
};

namespace {

// One viewer's WebSocket: reads poses and acks (each checked, rate limited),
// writes the hello and frames one at a time, closes with a reason.
class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(tcp::socket&& socket, ViewerHub::Impl& hub, uint64_t id)
      : ws_(std::move(socket)), hub_(hub), id_(id) {}

  void run(http::request<http::string_body> req) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(kMaxViewerMessageBytes);
    ws_.async_accept(req, [self = shared_from_this()](beast::error_code ec) {
      if (ec) return;
      self->hub_.added(self->id_, self);
      self->queue({std::make_shared<std::vector<uint8_t>>(), false});
      self->read();
    });
  }

  // A frame (binary) or, with empty bytes, the hello (text).
  struct Out {
    Bytes bytes;
    bool binary = true;
  };
  void queue(Out o) {
    if (closing_) return;
    out_.push_back(std::move(o));
    if (out_.size() == 1) write();
  }

  // Closes with a reason; the viewer is gone for the hub at once (Beast's
  // close still reads until the viewer's close frame comes).
  void close(websocket::close_code code, const std::string& reason) {
    if (closing_) return;
    closing_ = true;
    hub_.removed(id_);
    // A write in progress still needs its buffer: keep the front.
    if (writing_)
      out_.erase(out_.begin() + 1, out_.end());
    else
      out_.clear();
    if (!writing_)
      doClose(code, reason);
    else
      close_ = websocket::close_reason(code, reason);
  }

 private:
  void read() {
    ws_.async_read(buf_,
                   [self = shared_from_this()](beast::error_code ec, size_t) { self->onRead(ec); });
  }

  void onRead(beast::error_code ec) {
    if (ec) {  // closed by the viewer, or failed (Beast sent the close for too-big)
      hub_.removed(id_);
      return;
    }
    try {
      auto data = buf_.cdata();
      ViewerMessage m = decodeViewerMessage(static_cast<const uint8_t*>(data.data()), data.size());
      buf_.consume(buf_.size());
      // Poses and acks are limited apart: a viewer streaming poses at the
      // limit also acks the frames it gets.
      const bool pose = m.type == ViewerMessageType::Pose;
      std::deque<Clock::time_point>& recent = pose ? recent_poses_ : recent_acks_;
      auto now = Clock::now();
      recent.push_back(now);
      while (now - recent.front() > std::chrono::seconds(1)) recent.pop_front();
      if (int(recent.size()) > hub_.opts.max_rate) {
        close(websocket::close_code::policy_error, "too many messages: more than " +
                                                       std::to_string(hub_.opts.max_rate) +
                                                       (pose ? " poses" : " acks") + " a second");
        return;
      }
      if (pose)
        hub_.onPose(id_, m.pose);
      else
        hub_.onAck(id_, m.ack_frame);
    } catch (const Error& e) {
      close(websocket::close_code::bad_payload, e.what());
      return;
    }
    read();
  }

  void write() {
    writing_ = true;
    Out& o = out_.front();
    bool hello = o.bytes->empty() && !o.binary;
    if (hello) hello_ = hub_.helloJson();
    ws_.binary(!hello);
    net::const_buffer buffer =
        hello ? net::const_buffer(hello_.data(), hello_.size()) : net::buffer(*o.bytes);
    ws_.async_write(buffer, [self = shared_from_this()](beast::error_code ec, size_t) {
      self->writing_ = false;
      if (ec) return;  // the read side sees the failure and removes the viewer
      if (self->close_) {
        auto reason = *self->close_;
        self->close_.reset();
        self->doClose(websocket::close_code(reason.code),
                      std::string(reason.reason.data(), reason.reason.size()));
        return;
      }
      if (!self->out_.empty()) self->out_.pop_front();
      if (!self->out_.empty()) self->write();
    });
  }

  void doClose(websocket::close_code code, const std::string& reason) {
    // RFC 6455: a close reason is at most 123 bytes.
    websocket::close_reason why(code, reason.substr(0, 123));
    ws_.async_close(why, [self = shared_from_this()](beast::error_code) {});
  }

  websocket::stream<beast::tcp_stream> ws_;
  ViewerHub::Impl& hub_;
  uint64_t id_;
  beast::flat_buffer buf_;
  std::deque<Out> out_;
  std::string hello_;
  bool writing_ = false, closing_ = false;
  std::optional<websocket::close_reason> close_;
  std::deque<Clock::time_point> recent_poses_, recent_acks_;  // the last second's
};

// One HTTP request: the page, or the upgrade to a viewer's WebSocket; both
// need the token.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket&& socket, ViewerHub::Impl& hub) : stream_(std::move(socket)), hub_(hub) {}

  void run() {
    parser_.emplace();
    parser_->header_limit(8192);
    parser_->body_limit(4096);
    stream_.expires_after(std::chrono::seconds(10));
    http::async_read(stream_, buf_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, size_t) {
                       if (!ec) self->route(self->parser_->release());
                     });
  }

 private:
  void route(http::request<http::string_body> req) {
    std::string_view target(req.target().data(), req.target().size());
    std::string_view path = targetPath(target);
    if (!sameToken(queryParam(target, "token"), hub_.token))
      return respond(http::status::forbidden, "forbidden: missing or wrong token\n", "text/plain");
    if (path == "/ws") {
      if (!websocket::is_upgrade(req))
        return respond(http::status::bad_request, "expected a WebSocket upgrade\n", "text/plain");
      if (int(hub_.sessions.size()) >= hub_.opts.max_viewers)
        return respond(http::status::service_unavailable,
                       "too many viewers (" + std::to_string(hub_.opts.max_viewers) + ")\n",
                       "text/plain");
      stream_.expires_never();
      std::make_shared<WsSession>(stream_.release_socket(), hub_, hub_.next_id++)
          ->run(std::move(req));
      return;
    }
    if (req.method() != http::verb::get)
      return respond(http::status::method_not_allowed, "GET only\n", "text/plain");
    if (path == "/" || path == "/index.html")
      return respond(http::status::ok, hub_.page, "text/html; charset=utf-8");
    respond(http::status::not_found, "not found\n", "text/plain");
  }

  void respond(http::status status, std::string body, const char* type) {
    auto res = std::make_shared<http::response<http::string_body>>(status, 11);
    res->set(http::field::server, "dmmr-render");
    res->set(http::field::content_type, type);
    res->set(http::field::cache_control, "no-store");
    res->set("Referrer-Policy", "no-referrer");  // the URL carries the token
    res->set("X-Content-Type-Options", "nosniff");
    res->keep_alive(false);
    res->body() = std::move(body);
    res->prepare_payload();
    http::async_write(stream_, *res, [self = shared_from_this(), res](beast::error_code, size_t) {
      beast::error_code ignored;
      self->stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
    });
  }

  beast::tcp_stream stream_;
  ViewerHub::Impl& hub_;
  beast::flat_buffer buf_;
  std::optional<http::request_parser<http::string_body>> parser_;
};

}  // namespace

void ViewerHub::Impl::accept() {
  acceptor.async_accept([this](beast::error_code ec, tcp::socket socket) {
    if (ec) return;  // closed: stopping
    // Small messages (poses, acks, a frame's last segment) must not wait for
    // the peer's delayed ACK (Nagle): that added 20 ms to every pose here.
    beast::error_code ignored;
    socket.set_option(tcp::no_delay(true), ignored);
    std::make_shared<HttpSession>(std::move(socket), *this)->run();
    accept();
  });
}

void ViewerHub::Impl::added(uint64_t id, std::shared_ptr<WsSession> s) {
  sessions[id] = std::move(s);
  std::lock_guard<std::mutex> lock(mu);
  schedule.add(id);
  viewers[id];
}

void ViewerHub::Impl::removed(uint64_t id) {
  sessions.erase(id);
  std::lock_guard<std::mutex> lock(mu);
  schedule.remove(id);
  viewers.erase(id);
}

void ViewerHub::Impl::onPose(uint64_t id, const Pose& p) {
  std::lock_guard<std::mutex> lock(mu);
  if (!schedule.pose(id, p, nowMs())) return;  // stale: dropped
  viewers[id].quality = p.quality;
  plan_cv.notify_all();
}

void ViewerHub::Impl::onAck(uint64_t id, uint32_t frame) {
  Bytes next;
  {
    std::lock_guard<std::mutex> lock(mu);
    if (!schedule.acked(id, frame)) return;
    next = std::move(viewers[id].held);
  }
  if (next) sendTo(id, std::move(next));
}

void ViewerHub::Impl::sendTo(uint64_t id, Bytes bytes) {
  net::post(ioc, [this, id, bytes = std::move(bytes)] {
    if (auto it = sessions.find(id); it != sessions.end()) it->second->queue({bytes, true});
  });
}

Bytes ViewerHub::Impl::encodeFrame(const FrameDone& d, const Pose& pose, uint8_t quality,
                                   bool still, const Encode* e) {
  auto t0 = Clock::now();
  bool png = still || quality == 0;
  FrameMessage m;
  m.encoding = png ? FrameEncoding::Png : FrameEncoding::Jpeg;
  m.image = png ? encodePng(d.image) : encodeJpeg(d.image, quality);
  double encode_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  uint64_t pixels = 0;
  for (const auto& c : d.clients) pixels += c.pixels;
  nlohmann::json clients = nlohmann::json::array();
  for (const auto& c : d.clients)
    clients.push_back({{"pixels", c.pixels},
                       {"share", pixels ? double(c.pixels) / double(pixels) : 0.0},
                       {"triangles", c.triangles},
                       {"ms", c.ms}});
  nlohmann::json h = {{"frame", d.frame},
                      {"seq", pose.seq},
                      {"time_ms", pose.time_ms},
                      {"still", still},
                      {"pose",
                       {{"position", vec(pose.position)},
                        {"rotation", quat(pose.rotation)},
                        {"fovy_deg", pose.fovy_deg}}},
                      {"width", d.image.width},
                      {"height", d.image.height},
                      {"encoding", frameEncodingName(m.encoding)},
                      {"quality", png ? 0 : int(quality)},
                      {"bytes", m.image.size()},
                      {"server",
                       {{"cull_ms", d.cull_ms},
                        {"divide_ms", d.divide_ms},
                        {"assemble_ms", d.assemble_ms},
                        {"encode_ms", encode_ms},
                        {"frame_ms", d.frame_ms},
                        {"latency_ms", d.latency_ms},
                        // Where a pose's time goes outside the pipeline:
                        // waiting to be picked, and from assembled to sent.
                        {"pose_wait_ms", e ? e->wait_ms : 0.0},
                        {"pick_to_done_ms", e ? e->done_ms - e->picked_ms : 0.0},
                        {"done_to_send_ms", e ? nowMs() - e->done_ms : 0.0}}},
                      {"triangles", d.triangles},
                      {"clients", clients}};
  m.header = h.dump();
  return std::make_shared<std::vector<uint8_t>>(encodeFrameMessage(m));
}

// Encodes each assembled frame for its viewer and sends or holds it; between
// frames, sends the still frames that are due.
void ViewerHub::Impl::encoderLoop() {
  std::unique_lock<std::mutex> lock(mu);
  while (!stopped) {
    encode_cv.wait_for(lock, std::chrono::milliseconds(20),
                       [&] { return stopped || !encodes.empty(); });
    if (stopped) break;
    if (!encodes.empty()) {
      Encode e = std::move(encodes.front());
      encodes.pop_front();
      auto v = viewers.find(e.viewer);
      if (v == viewers.end()) continue;  // left meanwhile
      uint8_t quality = v->second.quality;
      if (e.still) {  // already in flight for the schedule: send it
        lock.unlock();
        FrameDone d = *e.frame;
        d.frame = e.still_frame;
        sendTo(e.viewer, encodeFrame(d, e.pose, 0, true));
        lock.lock();
        continue;
      }
      lock.unlock();
      Bytes bytes = encodeFrame(*e.frame, e.pose, quality, false, &e);
      lock.lock();
      v = viewers.find(e.viewer);
      if (v == viewers.end()) continue;
      v->second.last = e.frame;
      v->second.last_pose = e.pose;
      ViewerSchedule::Delivery delivery = schedule.rendered(e.viewer, e.frame->frame, e.pose.seq);
      // The viewer has room in the pipeline again: a pose that came while
      // this frame rendered can go now.
      plan_cv.notify_all();
      switch (delivery) {
        case ViewerSchedule::Delivery::Send:
          sendTo(e.viewer, std::move(bytes));
          break;
        case ViewerSchedule::Delivery::Hold:
          v->second.held = std::move(bytes);
          break;
        case ViewerSchedule::Delivery::Gone:
          break;
      }
      continue;
    }
    for (const ViewerSchedule::Still& s : schedule.dueStills(nowMs())) {
      const Viewer& v = viewers[s.viewer];
      if (opts.render_stills) {  // rendered again, exact (nextPose)
        still_renders.push_back({s.viewer, s.frame, v.last_pose});
        plan_cv.notify_all();
        continue;
      }
      std::shared_ptr<const FrameDone> frame = v.last;
      Pose pose = v.last_pose;
      lock.unlock();
      Bytes bytes = encodeFrame(*frame, pose, 0, true);
      sendTo(s.viewer, std::move(bytes));
      lock.lock();
    }
  }
}

ViewerHub::ViewerHub(const ServeOptions& opts, const ViewerHello& hello, std::string page)
    : impl_(std::make_unique<Impl>(opts, hello, std::move(page))) {}

ViewerHub::~ViewerHub() {
  stop();
  if (impl_->encoder_thread.joinable()) impl_->encoder_thread.join();
  if (impl_->io_thread.joinable()) impl_->io_thread.join();
}

std::string ViewerHub::start() {
  Impl& h = *impl_;
  beast::error_code ec;
  tcp::endpoint at(net::ip::make_address(h.opts.address, ec), h.opts.port);
  if (!ec) h.acceptor.open(at.protocol(), ec);
  if (!ec) h.acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) h.acceptor.bind(at, ec);
  if (!ec) h.acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec)
    throw Error("--serve " + h.opts.address + ":" + std::to_string(h.opts.port) +
                ": cannot listen: " + ec.message());
  uint16_t port = h.acceptor.local_endpoint().port();
  h.accept();
  h.signals.add(SIGINT);
  h.signals.add(SIGTERM);
  h.signals.async_wait([this](beast::error_code ec, int) {
    if (!ec) stop();
  });
  h.io_thread = std::thread([&h] { h.ioc.run(); });
  h.encoder_thread = std::thread([&h] { h.encoderLoop(); });
  std::string host =
      h.opts.address.find(':') != std::string::npos ? "[" + h.opts.address + "]" : h.opts.address;
  return "http://" + host + ":" + std::to_string(port) + "/?token=" + h.token;
}

std::optional<Pose> ViewerHub::nextPose(uint32_t frame, bool* exact) {
  Impl& h = *impl_;
  std::unique_lock<std::mutex> lock(h.mu);
  if (exact) *exact = false;
  for (;;) {
    if (h.stopped) return std::nullopt;
    while (!h.still_renders.empty()) {
      Impl::StillRender r = h.still_renders.front();
      h.still_renders.pop_front();
      if (!h.viewers.count(r.viewer)) continue;  // left meanwhile
      double now = nowMs();
      h.picked[frame] = {r.viewer, r.pose, 0, now, true, r.frame};
      if (exact) *exact = true;
      return r.pose;
    }
    if (auto pick = h.schedule.next()) {
      double now = nowMs();
      h.picked[frame] = {pick->viewer, pick->pose, now - pick->received_ms, now};
      return pick->pose;
    }
    h.plan_cv.wait(lock);
  }
}

void ViewerHub::frameDone(FrameDone d) {
  Impl& h = *impl_;
  std::lock_guard<std::mutex> lock(h.mu);
  auto it = h.picked.find(d.frame);
  if (it == h.picked.end()) return;
  Impl::Encode e{std::make_shared<const FrameDone>(std::move(d)),
                 it->second.viewer,
                 it->second.pose,
                 it->second.wait_ms,
                 it->second.picked_ms,
                 nowMs(),
                 it->second.still,
                 it->second.still_frame};
  h.picked.erase(it);
  h.encodes.push_back(std::move(e));
  h.encode_cv.notify_all();
}

void ViewerHub::stop() {
  Impl& h = *impl_;
  {
    std::lock_guard<std::mutex> lock(h.mu);
    if (h.stopped) return;
    h.stopped = true;
    h.plan_cv.notify_all();
    h.encode_cv.notify_all();
  }
  net::post(h.ioc, [&h] {
    beast::error_code ignored;
    h.acceptor.close(ignored);
    h.signals.cancel(ignored);
    auto sessions = h.sessions;  // close() removes each from the map
    for (auto& [id, s] : sessions) s->close(websocket::close_code::going_away, "server stopping");
    // Give the close frames a moment to go out, then end the network thread.
    auto timer = std::make_shared<net::steady_timer>(h.ioc, std::chrono::milliseconds(200));
    timer->async_wait([&h, timer](beast::error_code) { h.ioc.stop(); });
  });
}

}  // namespace dmmr
