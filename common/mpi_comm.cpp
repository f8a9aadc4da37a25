#include "mpi_comm.h"

#include <mpi.h>

#include <chrono>
#include <climits>
#include <deque>
#include <thread>

#include "error.h"

// LeakSanitizer builds (the asan-ubsan preset): see ~Comm.
#if defined(__SANITIZE_ADDRESS__)
#define DMMR_LSAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define DMMR_LSAN 1
#endif
#endif
#ifdef DMMR_LSAN
#include <sanitizer/lsan_interface.h>
#endif

namespace dmmr {

namespace {

void check(int rc, const char* call) {
  if (rc == MPI_SUCCESS) return;
  char msg[MPI_MAX_ERROR_STRING] = {};
  int len = 0;
  MPI_Error_string(rc, msg, &len);
  throw Error(std::string(call) + " failed: " + msg);
}

// Sleeps between polls of something another process will do: 20 us at
// first, doubling up to 0.5 ms (negligible against frame times), so that a
// wait costs no core, where Open MPI's own blocking calls spin one.
class Backoff {
 public:
  void nap() {
    std::this_thread::sleep_for(nap_);
    nap_ = std::min(nap_ * 2, std::chrono::microseconds(500));
  }

 private:
  std::chrono::microseconds nap_{20};
};

// Whether the send behind `request` has completed (then freed).
bool completed(MPI_Request* request) {
  int done = 0;
  check(MPI_Test(request, &done, MPI_STATUS_IGNORE), "MPI_Test");
  return done != 0;
}

}  // namespace

const char* tagName(Tag t) {
  switch (t) {
    case Tag::Hello:
      return "Hello";
    case Tag::Job:
      return "Job";
    case Tag::SubFrame:
      return "SubFrame";
    case Tag::Error:
      return "Error";
    case Tag::Shutdown:
      return "Shutdown";
    case Tag::Bye:
      return "Bye";
    case Tag::Ping:
      return "Ping";
    case Tag::Pong:
      return "Pong";
  }
  return "Unknown";
}

Comm::Comm(int* argc, char*** argv) {
  int provided = 0;
  check(MPI_Init_thread(argc, argv, MPI_THREAD_MULTIPLE, &provided), "MPI_Init_thread");
  check(MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN), "MPI_Comm_set_errhandler");
  check(MPI_Comm_rank(MPI_COMM_WORLD, &rank_), "MPI_Comm_rank");
  check(MPI_Comm_size(MPI_COMM_WORLD, &size_), "MPI_Comm_size");
  if (provided < MPI_THREAD_MULTIPLE) {
    MPI_Finalize();
    throw Error("the MPI library does not provide MPI_THREAD_MULTIPLE");
  }
}

Comm::~Comm() {
#ifdef DMMR_LSAN
  // Check for leaks now, while OpenMPI's plugins are still loaded: LSan's
  // own check at exit comes after MPI_Finalize has unloaded them, and what
  // they leak would be reported with no library named, so that the
  // suppressions (tests/sanitizers/lsan.supp) could not tell it from dmmr's.
  // The whole run is over here; this check replaces the one at exit.
  __lsan_do_leak_check();
#endif
  MPI_Finalize();
}

void Comm::send(int dest, Tag tag, const std::vector<uint8_t>& bytes) {
  if (bytes.size() > size_t(INT_MAX)) throw Error(std::string(tagName(tag)) + " message too large");
  // MPI_Send would spin a core until the receiver takes a message above the
  // eager limit; this waits as long, asleep between polls (Backoff).
  MPI_Request request = MPI_REQUEST_NULL;
  check(MPI_Isend(bytes.data(), int(bytes.size()), MPI_BYTE, dest, int(tag), MPI_COMM_WORLD,
                  &request),
        "MPI_Isend");
  Backoff backoff;
  while (!completed(&request)) backoff.nap();
}

Message Comm::recv(int source) {
  return *recvFor(source, -1);
}

std::optional<Message> Comm::recvFor(int source, double timeout_s) {
  // Matched probe: the message found is the one received, even when other
  // threads receive too.
  // OpenMPI's blocking probe spins a core while it waits; on a node whose
  // cores render, that steals their time. Poll instead (Backoff).
  MPI_Status st;
  MPI_Message handle;
  int found = 0;
  Backoff backoff;
  auto start = std::chrono::steady_clock::now();
  for (;;) {
    check(MPI_Improbe(source == kAnySource ? MPI_ANY_SOURCE : source, MPI_ANY_TAG, MPI_COMM_WORLD,
                      &found, &handle, &st),
          "MPI_Improbe");
    if (found) break;
    if (timeout_s >= 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > timeout_s)
      return std::nullopt;
    backoff.nap();
  }
  int count = 0;
  check(MPI_Get_count(&st, MPI_BYTE, &count), "MPI_Get_count");
  Message m;
  m.source = st.MPI_SOURCE;
  m.tag = Tag(st.MPI_TAG);
  m.bytes.resize(size_t(count));
  check(MPI_Mrecv(m.bytes.data(), count, MPI_BYTE, &handle, MPI_STATUS_IGNORE), "MPI_Mrecv");
  return m;
}

void Comm::broadcast(int root, int* value) {
  check(MPI_Bcast(value, 1, MPI_INT, root, MPI_COMM_WORLD), "MPI_Bcast");
}

void Comm::abort(int code) {
  MPI_Abort(MPI_COMM_WORLD, code);
  std::abort();
}

struct SendBatch::Impl {
  struct Send {
    int dest = 0;
    MPI_Request request = MPI_REQUEST_NULL;
    std::vector<uint8_t> bytes;
  };
  std::deque<Send> sends;  // in the order posted
};

SendBatch::SendBatch(Comm&) : impl_(std::make_unique<Impl>()) {}

SendBatch::~SendBatch() {
  try {
    wait();
  } catch (...) {
    // MPI failed under a send: its buffer may still be read. Leaked on
    // purpose; the job is ending.
    (void)impl_.release();
  }
}

void SendBatch::post(int dest, Tag tag, std::vector<uint8_t> bytes) {
  if (bytes.size() > size_t(INT_MAX)) throw Error(std::string(tagName(tag)) + " message too large");
  Impl::Send& s = impl_->sends.emplace_back();
  s.dest = dest;
  s.bytes = std::move(bytes);
  int rc = MPI_Isend(s.bytes.data(), int(s.bytes.size()), MPI_BYTE, dest, int(tag), MPI_COMM_WORLD,
                     &s.request);
  if (rc != MPI_SUCCESS) {
    impl_->sends.pop_back();  // never started: nothing reads the buffer
    check(rc, "MPI_Isend");
  }
}

bool SendBatch::poll() {
  auto& sends = impl_->sends;
  for (auto it = sends.begin(); it != sends.end();)
    it = completed(&it->request) ? sends.erase(it) : std::next(it);
  return sends.empty();
}

void SendBatch::wait(const std::function<void(int dest)>& waiting_for) {
  Backoff backoff;
  while (!poll()) {
    if (waiting_for) waiting_for(impl_->sends.front().dest);
    backoff.nap();
  }
}

size_t SendBatch::inFlight() const {
  return impl_->sends.size();
}

}  // namespace dmmr
