// The one checked wrapper over MPI: every call's return code is checked and
// turned into an Error naming the call; messages carry a Tag from one enum,
// with a name for logs.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace dmmr {

enum class Tag : int {
  Hello = 1,     // client -> server at start: ready, or why not
  Job = 2,       // server -> client: a frame's camera, region and objects
  SubFrame = 3,  // client -> server: compressed pixels and stats
  Error = 4,     // client -> server: a stage failed (text)
  Shutdown = 5,  // server -> client: no more jobs
  Bye = 6,       // client -> server: acknowledged shutdown, nothing more follows
  Ping = 7,      // server -> client: echo these bytes (link probe for --balance auto)
  Pong = 8,      // client -> server: the echo
};
const char* tagName(Tag t);
inline constexpr int kAnySource = -1;

struct Message {
  int source = -1;
  Tag tag = Tag::Hello;
  std::vector<uint8_t> bytes;
};

class Comm {
 public:
  // Initialises MPI with MPI_THREAD_MULTIPLE (the server sends and receives
  // on two threads); throws Error when the library cannot provide it.
  Comm(int* argc, char*** argv);
  ~Comm();  // MPI_Finalize
  Comm(const Comm&) = delete;
  Comm& operator=(const Comm&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }

  // Returns once `dest` has taken the message (above the eager limit) or it
  // is buffered, asleep between polls meanwhile; a rank that must not wait
  // for one receiver after another posts a SendBatch instead.
  void send(int dest, Tag tag, const std::vector<uint8_t>& bytes);
  // Blocks for the next message from `source` (or kAnySource), any tag.
  Message recv(int source);
  // The same, giving up after `timeout_s` seconds (then empty).
  std::optional<Message> recvFor(int source, double timeout_s);
  void broadcast(int root, int* value);
  // Ends every rank of the job at once; for when orderly shutdown is impossible.
  [[noreturn]] void abort(int code);

 private:
  int rank_ = 0, size_ = 1;
};

// Sends in flight together (MPI_Isend), each buffer owned here until its send
// completes. A blocking send of a message above the eager limit waits until
// the receiver takes it, one receiver after another, and Open MPI spins a
// core (sched_yield) while it waits: a server handing 16 clients their jobs
// waited for each client's next poll in turn. Posted together, the waits
// overlap, and wait() sleeps between polls as Comm::recvFor does. Messages
// to one destination are received in the order posted. A batch is used by
// one thread at a time; other threads may use the Comm meanwhile
// (MPI_THREAD_MULTIPLE).
class SendBatch {
 public:
  // `comm`: the initialised MPI its sends go on; it outlives the batch.
  explicit SendBatch(Comm& comm);
  // Waits for what is still in flight; should that fail (MPI failing), the
  // buffers are kept alive for the rest of the process, never freed under a
  // send.
  ~SendBatch();
  SendBatch(const SendBatch&) = delete;
  SendBatch& operator=(const SendBatch&) = delete;

  void post(int dest, Tag tag, std::vector<uint8_t> bytes);
  // Frees the buffers of completed sends; true when none is in flight.
  bool poll();
  // Returns once every send posted has completed. `waiting_for`, if given,
  // hears the destination of the oldest send still in flight before each
  // sleep (for a watchdog's message).
  void wait(const std::function<void(int dest)>& waiting_for = {});
  size_t inFlight() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dmmr
