// Which pose the interactive server renders next and when each viewer gets
// its frames: plain bookkeeping over viewer ids, frame ids and times, with no
// network or threads, so that the policy is tested on its own.
//
// Policy (docs/interactive.md):
// - only each viewer's latest pose counts; a pose whose seq is not above the
//   last one received is stale and dropped;
// - viewers with a pose not yet rendered take turns (round robin), each with
//   at most `max_rendering` frames in the pipeline;
// - a viewer has at most one frame in flight (sent, not acknowledged); a
//   frame finished meanwhile is held, and a newer one replaces it;
// - once a viewer's latest pose is rendered and no pose has come for
//   `still_ms`, its last frame is due once more as the exact (still) frame.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "viewer_protocol.h"

namespace dmmr {

class ViewerSchedule {
 public:
  // max_rendering >= 1, still_ms >= 0.
  ViewerSchedule(int max_rendering, double still_ms);

  void add(uint64_t viewer);
  // Forgets the viewer; frames of it still rendering are then Gone.
  void remove(uint64_t viewer);
  size_t size() const { return viewers_.size(); }

  // A pose came at `now_ms`. False (dropped) when it is stale or the viewer
  // is unknown.
  bool pose(uint64_t viewer, const Pose& p, double now_ms);

  struct Pick {
    uint64_t viewer = 0;
    Pose pose;
    double received_ms = 0;  // when the pose came (pose()'s now_ms)
    friend bool operator==(const Pick&, const Pick&) = default;
  };
  // The next pose to render, the next viewer in turn after the last one
  // picked; nothing when no viewer has an unrendered pose and room.
  std::optional<Pick> next();

  enum class Delivery { Send, Hold, Gone };
  // `frame`, picked for `viewer` with pose `seq`, is assembled. Send: it is
  // now the viewer's frame in flight. Hold: the viewer has one in flight;
  // this one waits (replacing any held before, which is dropped). Gone: the
  // viewer left.
  Delivery rendered(uint64_t viewer, uint32_t frame, uint32_t seq);

  // The viewer acknowledged `frame`. If that was its frame in flight, the
  // held frame (if any) becomes the one in flight and is returned, to send.
  // An ack of any other frame changes nothing.
  std::optional<uint32_t> acked(uint64_t viewer, uint32_t frame);

  // Viewers whose still frame is due at `now_ms`: latest pose rendered,
  // nothing rendering, held or in flight, no pose for still_ms, no still sent
  // for that pose yet. Each is marked as sent and its frame in flight; the
  // returned frame id is that of its last frame (the one to send again).
  struct Still {
    uint64_t viewer = 0;
    uint32_t frame = 0;
    friend bool operator==(const Still&, const Still&) = default;
  };
  std::vector<Still> dueStills(double now_ms);

  // The frame a viewer has in flight, if any (for tests and logs).
  std::optional<uint32_t> inFlight(uint64_t viewer) const;
  std::optional<uint32_t> held(uint64_t viewer) const;

 private:
  struct Viewer {
    std::optional<Pose> latest;
    double latest_ms = 0;
    std::optional<uint32_t> picked_seq;    // the last pose given to the renderer
    std::optional<uint32_t> rendered_seq;  // the last pose whose frame came back
    std::optional<uint32_t> last_frame;    // that frame
    std::optional<uint32_t> still_seq;     // the pose whose still was sent
    int rendering = 0;
    std::optional<uint32_t> in_flight, held;
  };
  int max_rendering_;
  double still_ms_;
  std::map<uint64_t, Viewer> viewers_;
  std::optional<uint64_t> last_picked_;
};

}  // namespace dmmr
