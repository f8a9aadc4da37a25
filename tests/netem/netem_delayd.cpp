// dmmr-netem-delayd: a delay line for kernels without sch_netem.
//
// Binds an NFQUEUE (nfnetlink_queue, raw netlink, no libnetfilter_queue) in
// the network namespace it runs in and holds every packet queued to it for
// DELAY (+ uniform jitter in [-JITTER, +JITTER]) before accepting it. Release
// order is arrival order (a packet never leaves before the one queued ahead of
// it), so jitter does not reorder a TCP stream; a packet's release time is
// max(arrival + delay + jitter, release time of the packet ahead). Only packet
// metadata crosses to user space (NFQNL_COPY_META, GSO packets queued whole),
// and releases are batch verdicts (NFQNL_MSG_VERDICT_BATCH: every id up to K).
//
// scripts/netem/netem.sh starts one per namespace, after
//   iptables -A OUTPUT -o eth0 -j NFQUEUE --queue-num 0
// usage: dmmr-netem-delayd --delay-us D [--jitter-us J] [--queue Q] [--ready FILE] [--seed S]
// Runs until SIGTERM/SIGINT, then accepts what it still holds, prints its
// counts on stderr and exits 0.
#include <arpa/inet.h>
#include <linux/netfilter.h>
#include <linux/netfilter/nfnetlink.h>
#include <linux/netfilter/nfnetlink_queue.h>
#include <linux/netlink.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <random>
#include <string>
#include <vector>

namespace {

volatile sig_atomic_t g_stop = 0;
void onSignal(int) {
  g_stop = 1;
}

int64_t nowNs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

[[noreturn]] void die(const char* what) {
  std::fprintf(stderr, "dmmr-netem-delayd: %s: %s\n", what, std::strerror(errno));
  std::exit(1);
}

// Builds one nfnetlink message: nlmsghdr + nfgenmsg + attributes.
class Message {
 public:
  Message(uint16_t type, uint16_t flags, uint16_t queue) {
    buf_.resize(NLMSG_HDRLEN + NLMSG_ALIGN(sizeof(nfgenmsg)));
    auto* nlh = reinterpret_cast<nlmsghdr*>(buf_.data());
    nlh->nlmsg_type = type;
    nlh->nlmsg_flags = flags;
    nlh->nlmsg_seq = ++seq_;
    auto* g = reinterpret_cast<nfgenmsg*>(buf_.data() + NLMSG_HDRLEN);
    g->nfgen_family = AF_UNSPEC;
    g->version = NFNETLINK_V0;
    g->res_id = htons(queue);
  }
  void attr(uint16_t type, const void* data, size_t len) {
    size_t at = buf_.size();
    buf_.resize(at + NLA_ALIGN(NLA_HDRLEN + len));
    auto* a = reinterpret_cast<nlattr*>(buf_.data() + at);
    a->nla_type = type;
    a->nla_len = uint16_t(NLA_HDRLEN + len);
    std::memcpy(buf_.data() + at + NLA_HDRLEN, data, len);
  }
  void attrU32(uint16_t type, uint32_t v) {
    uint32_t be = htonl(v);
    attr(type, &be, sizeof be);
  }
  const char* data() {
    reinterpret_cast<nlmsghdr*>(buf_.data())->nlmsg_len = uint32_t(buf_.size());
    return buf_.data();
  }
  size_t size() const { return buf_.size(); }

 private:
  std::vector<char> buf_;
  static inline uint32_t seq_ = 0;
};

void sendMsg(int fd, Message& m) {
  sockaddr_nl to{};
  to.nl_family = AF_NETLINK;
  const char* p = m.data();
  while (sendto(fd, p, m.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to) < 0) {
    if (errno == EINTR) continue;
    if (errno == ENOBUFS || errno == EAGAIN) {
      usleep(50);
      continue;
    }
    die("sendto");
  }
}

// Sends a config request and waits for its ack (errors are fatal).
void configure(int fd, Message& m, const char* what) {
  sendMsg(fd, m);
  char buf[8192];
  for (;;) {
    ssize_t n = recv(fd, buf, sizeof buf, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      die(what);
    }
    for (auto* h = reinterpret_cast<nlmsghdr*>(buf); NLMSG_OK(h, n); h = NLMSG_NEXT(h, n)) {
      if (h->nlmsg_type != NLMSG_ERROR) continue;
      int err = -reinterpret_cast<nlmsgerr*>(NLMSG_DATA(h))->error;
      if (err != 0) {
        errno = err;
        die(what);
      }
      return;
    }
  }
}

int64_t argValue(int& i, int argc, char** argv) {
  if (i + 1 >= argc) {
    std::fprintf(stderr, "dmmr-netem-delayd: %s needs a value\n", argv[i]);
    std::exit(2);
  }
  return std::strtoll(argv[++i], nullptr, 10);
}

struct Held {
  int64_t due;
  uint32_t id;
};

}  // namespace

int main(int argc, char** argv) {
  int64_t delayUs = -1, jitterUs = 0, seed = 1;
  uint16_t queue = 0;
  std::string ready;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--delay-us") {
      delayUs = argValue(i, argc, argv);
    } else if (a == "--jitter-us") {
      jitterUs = argValue(i, argc, argv);
    } else if (a == "--queue") {
      queue = uint16_t(argValue(i, argc, argv));
    } else if (a == "--seed") {
      seed = argValue(i, argc, argv);
    } else if (a == "--ready" && i + 1 < argc) {
      ready = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: dmmr-netem-delayd --delay-us D [--jitter-us J] [--queue Q] "
                   "[--ready FILE] [--seed S]\n");
      return 2;
    }
  }
  if (delayUs < 0 || jitterUs < 0) {
    std::fprintf(stderr, "dmmr-netem-delayd: --delay-us D >= 0 is required, jitter >= 0\n");
    return 2;
  }

  // Timer precision matters at 0.1 ms; real-time priority keeps busy-polling
  // MPI ranks on the same cores from delaying the releases (best effort).
  prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
  sched_param sp{};
  sp.sched_priority = 50;
  bool realtime = sched_setscheduler(0, SCHED_FIFO, &sp) == 0;

  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);

  int fd = socket(AF_NETLINK, SOCK_RAW, NETLINK_NETFILTER);
  if (fd < 0) die("socket(NETLINK_NETFILTER)");
  sockaddr_nl local{};
  local.nl_family = AF_NETLINK;
  if (bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof local) < 0) die("bind");
  int rcvbuf = 8 << 20;
  if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &rcvbuf, sizeof rcvbuf) < 0)
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
  int one = 1;
  setsockopt(fd, SOL_NETLINK, NETLINK_NO_ENOBUFS, &one, sizeof one);

  const uint16_t cfgType = (NFNL_SUBSYS_QUEUE << 8) | NFQNL_MSG_CONFIG;
  {
    Message m(cfgType, NLM_F_REQUEST | NLM_F_ACK, queue);
    nfqnl_msg_config_cmd cmd{};
    cmd.command = NFQNL_CFG_CMD_BIND;
    cmd.pf = htons(AF_INET);
    m.attr(NFQA_CFG_CMD, &cmd, sizeof cmd);
    configure(fd, m, "bind queue");
  }
  {
    Message m(cfgType, NLM_F_REQUEST | NLM_F_ACK, queue);
    nfqnl_msg_config_params params{};
    params.copy_range = htonl(0);
    params.copy_mode = NFQNL_COPY_META;
    m.attr(NFQA_CFG_PARAMS, &params, sizeof params);
    m.attrU32(NFQA_CFG_QUEUE_MAXLEN, 65536);
    m.attrU32(NFQA_CFG_MASK, NFQA_CFG_F_GSO);
    m.attrU32(NFQA_CFG_FLAGS, NFQA_CFG_F_GSO);
    configure(fd, m, "configure queue");
  }
  if (!ready.empty()) {
    FILE* f = std::fopen(ready.c_str(), "w");
    if (f) {
      std::fprintf(f, "pid %d realtime %d\n", int(getpid()), realtime ? 1 : 0);
      std::fclose(f);
    }
  }

  std::mt19937_64 rng{uint64_t(seed)};
  std::uniform_int_distribution<int64_t> jitter(-jitterUs * 1000, jitterUs * 1000);
  const int64_t delayNs = delayUs * 1000;
  std::deque<Held> held;
  int64_t lastDue = 0;
  uint64_t packets = 0, releases = 0, maxHeld = 0;
  int64_t lateSumNs = 0, lateMaxNs = 0;  // how long after its due time a release went out
  std::vector<char> buf(1 << 16);
  const uint16_t pktType = (NFNL_SUBSYS_QUEUE << 8) | NFQNL_MSG_PACKET;

  auto release = [&](bool all) {
    int64_t now = nowNs();
    uint32_t last = 0;
    bool any = false;
    while (!held.empty() && (all || held.front().due <= now)) {
      last = held.front().id;
      if (!all) {
        lateSumNs += now - held.front().due;
        lateMaxNs = std::max(lateMaxNs, now - held.front().due);
      }
      any = true;
      held.pop_front();
    }
    if (!any) return;
    Message m((NFNL_SUBSYS_QUEUE << 8) | NFQNL_MSG_VERDICT_BATCH, NLM_F_REQUEST, queue);
    nfqnl_msg_verdict_hdr v{};
    v.verdict = htonl(NF_ACCEPT);
    v.id = htonl(last);
    m.attr(NFQA_VERDICT_HDR, &v, sizeof v);
    sendMsg(fd, m);
    ++releases;
  };

  while (!g_stop) {
    timespec timeout{};
    timespec* tp = nullptr;
    if (!held.empty()) {
      int64_t wait = std::max<int64_t>(0, held.front().due - nowNs());
      timeout.tv_sec = wait / 1000000000;
      timeout.tv_nsec = wait % 1000000000;
      tp = &timeout;
    }
    pollfd p{fd, POLLIN, 0};
    int r = ppoll(&p, 1, tp, nullptr);
    if (r < 0 && errno != EINTR) die("ppoll");
    if (r > 0) {
      // Drain everything waiting, then release what is due.
      for (;;) {
        ssize_t n = recv(fd, buf.data(), buf.size(), MSG_DONTWAIT);
        if (n < 0) {
          if (errno == EINTR) continue;
          if (errno == EAGAIN || errno == EWOULDBLOCK) break;
          die("recv");
        }
        int64_t now = nowNs();
        int len = int(n);
        for (auto* h = reinterpret_cast<nlmsghdr*>(buf.data()); NLMSG_OK(h, len);
             h = NLMSG_NEXT(h, len)) {
          if (h->nlmsg_type == NLMSG_ERROR) {
            int err = -reinterpret_cast<nlmsgerr*>(NLMSG_DATA(h))->error;
            if (err) std::fprintf(stderr, "dmmr-netem-delayd: netlink error %d\n", err);
            continue;
          }
          if (h->nlmsg_type != pktType) continue;
          char* attrs = reinterpret_cast<char*>(NLMSG_DATA(h)) + NLMSG_ALIGN(sizeof(nfgenmsg));
          int left = int(h->nlmsg_len) - int(attrs - reinterpret_cast<char*>(h));
          while (left >= int(NLA_HDRLEN)) {
            auto* a = reinterpret_cast<nlattr*>(attrs);
            if (a->nla_len < NLA_HDRLEN || a->nla_len > left) break;
            if ((a->nla_type & NLA_TYPE_MASK) == NFQA_PACKET_HDR) {
              nfqnl_msg_packet_hdr ph;
              std::memcpy(&ph, attrs + NLA_HDRLEN, sizeof ph);
              int64_t due = now + delayNs + (jitterUs ? jitter(rng) : 0);
              due = std::max(due, lastDue);
              lastDue = due;
              held.push_back({due, ntohl(ph.packet_id)});
              ++packets;
              break;
            }
            attrs += NLA_ALIGN(a->nla_len);
            left -= int(NLA_ALIGN(a->nla_len));
          }
        }
        maxHeld = std::max<uint64_t>(maxHeld, held.size());
      }
    }
    release(false);
  }
  release(true);
  std::fprintf(
      stderr,
      "dmmr-netem-delayd: queue %u delay %lld us jitter %lld us: %llu packets, %llu "
      "releases, at most %llu held, release late by %.1f us mean %.1f us max, realtime %d\n",
      unsigned(queue), (long long)delayUs, (long long)jitterUs, (unsigned long long)packets,
      (unsigned long long)releases, (unsigned long long)maxHeld,
      packets ? double(lateSumNs) / double(packets) / 1e3 : 0.0, double(lateMaxNs) / 1e3,
      realtime ? 1 : 0);
  return 0;
}
