// The client's visibility stage (DMMR paper, section 3.5): occluders drawn
// into depth, every other object of the region tested with a hardware
// occlusion query on its bounding box.
//
// Conservative by default, so frames stay identical to dmmr-reference: the
// occluders are real geometry at full detail drawn by the render stage's own
// code (so their depth is the render pass's), a query passes on a single
// sample, ties in depth count as visible, query boxes are widened against
// rounding, and an object whose box reaches the camera's near plane is taken
// without a query. An object dropped by this stage has every pixel it could
// cover strictly behind geometry that the render stage draws too.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "camera.h"
#include "depth_pyramid.h"
#include "formats.h"

namespace dmmr {

// How the visibility stage tests candidate boxes against the occluders'
// depth: hardware occlusion queries (the DMMR paper's method), or the depth
// read back once per pass and tested on the CPU (depth_pyramid.h).
enum class VisibilityMethod { Off, Queries, Pyramid };
// Two contexts and threads (the paper's visibility and render stages), or
// one context that draws last frame's visible set in colour, tests the rest
// against that depth and draws what is newly visible (`fused`); `auto` times
// both on the walkthrough's first frames and keeps the faster.
enum class StageMode { Split, Fused, Auto };

struct VisibilityOptions {
  VisibilityMethod method = VisibilityMethod::Pyramid;
  StageMode stages = StageMode::Fused;
  // Let the cost model (CullingGovernor) turn culling off while it does not
  // pay. Never changes a pixel.
  bool governor = true;
  // Samples a box must pass to count as visible; 0 means any sample.
  // Anything above 0 is an approximation.
  uint32_t query_threshold = 0;
  // An object that passed stays marked visible, without queries, for this
  // many further frames (the paper's n). Any n is conservative; 0 (query
  // every frame) draws the least, and on llvmpipe, where queries are cheap
  // next to drawing, is also the fastest (docs/benchmarks.md).
  uint32_t keep_frames = 0;
  // Draw the preprocessor's potential occluders into depth every frame, or
  // only while there is no previous visible list (the first frame).
  bool potential_every_frame = false;
  // Draw occluders with the preprocessor's level of detail: cheaper, but an
  // approximation (a simplified occluder can hide what the full one shows).
  bool occluder_lod = false;
  // Objects that pass the first query pass without having been occluders are
  // drawn into depth and queried again when there are at least this many
  // (0: always; a very large value turns the second pass off).
  uint32_t second_pass_min = 1;
  // Fused stages: step 1 leaves out last frame's visible objects that last
  // frame's depth, moved to this frame's camera, all but hides
  // (reprojectDepth). A guess: those that show pass the test and are drawn
  // as new ones. Never changes a pixel. Off by default: it draws fewer
  // triangles (plant10m 1.49x the exactly visible set against 1.58x) but
  // costs client CPU where the guess sends objects to the second pass
  // (plants4 at 1024x768: 25% more; docs/benchmarks.md).
  bool predict = false;
  // Depth-pyramid tests: an object whose box passes is tested again by its
  // part boxes (parts.bin), each part's rectangle with the object's depth
  // bound; culled when none can show. Exact; needs a scene with parts.
  bool part_boxes = true;
  // Objects are drawn part by part (parts.bin, a scene whose geometries keep
  // each part's triangles together): a part whose rectangle misses the
  // region is left out, and with part_boxes and the depth pyramid so is a
  // part the tests found hidden. Exact (docs/architecture.md, "Part draws").
  bool part_draws = true;
  // Hierarchical query rounds: runs of this many consecutive objects are
  // tested by their union box, then the runs that pass at the next size; the
  // last size must be 1. Each round waits once for the query results.
  std::vector<uint32_t> run_sizes = {16, 4, 1};
};

// Objects of fewer triangles are neither tested nor drawn by their parts: a
// part test costs about the same for any object, culling saves its
// triangles (plants8 at 512x384: testing every object's parts cost 1 ms a
// frame of tests for 3.6% fewer triangles; from 256 on, plant10m keeps its
// 1.48; docs/benchmarks.md, "Part boxes").
inline constexpr uint64_t kMinPartTriangles = 256;

// Whether `o` can be drawn part by part: its geometry's parts (`g`) are
// ordered, it has kMinPartTriangles or more and a valid box.
inline bool drawnByParts(const ObjectBounds& o, const GeometryParts& g) {
  return g.ordered() && o.weight >= kMinPartTriangles && o.box.valid();
}

// The bounds of object `o`'s parts (`g`, its geometry's), under the camera
// `projector` was made for (`camera`, a frame `height` pixels high), each
// within `ob`, the object's own bound (ScreenProjector::bound of
// queryBoxBounds(o.box, camera, height)): partBound of each part's query
// box rectangle (queryPartBounds). Needs a valid o.box. Returns
// g.parts.size().
size_t partBounds(const ObjectBounds& o, const GeometryParts& g, const ScreenProjector& projector,
                  const Camera& camera, int height, const ScreenBound& ob,
                  std::array<ScreenBound, kMaxParts>* out);

// Bit k set when parts[k] reaches the near plane or its rectangle shares a
// pixel with `region`.
uint8_t partsMeeting(const ScreenBound* parts, size_t count, const Rect& region);

// The parts of `o` a draw in `region` of a width x height frame needs
// (PartDraw::mask): all (kAllParts) when it is not drawnByParts, or
// its bound `ob` (as for partBounds) reaches the near plane or lies within
// the region without touching the frame's edge (bounds are clipped to the
// frame, so one that touches it may reach beyond); otherwise those whose
// bound meets the region (none when `ob` misses it; a part wholly outside
// the frame has an empty bound). Every pixel of the region the object's
// triangles can cover is covered by a part in the mask, so drawing those
// alone changes no pixel there.
uint8_t partsInRegion(const ObjectBounds& o, const GeometryParts& g,
                      const ScreenProjector& projector, const Camera& camera, int width, int height,
                      const ScreenBound& ob, const Rect& region);

// Which objects of a region the stage draws as occluders, which it takes as
// marked, and which it queries. Pure: plain sorted lists in, out.
struct VisibilityPlan {
  std::vector<uint32_t> occluders;  // previous frame's visible + potential occluders, in the region
  std::vector<uint32_t> marked;     // passed a query recently, not occluders
  std::vector<uint32_t> queried;    // the rest
};

// `region`, `previous` and `potential` ascending; `marked_until[i]` is the
// first frame at which object i must be queried again.
VisibilityPlan planVisibility(const std::vector<uint32_t>& region,
                              const std::vector<uint32_t>& previous,
                              const std::vector<uint32_t>& potential,
                              const std::vector<uint32_t>& marked_until, uint32_t frame);

// Whether a frame's starting guess (its occluders; the fused stage's step
// 1) should take the visible list of the frame before last as well as last
// frame's: true when last frame's visible triangles are under a quarter of
// the frame before's. Then the camera stood right behind something near
// that hid most of the scene for a frame, and as it moves on, what that hid
// shows again: last frame's list alone would leave the new frame's depth
// nearly empty, and everything would pass its tests (monuments25's slowest
// frames). Any guess is exact: it changes what is drawn first, not a pixel.
bool guessCollapsed(uint64_t last_triangles, uint64_t before_triangles);

// Ascending union, without duplicates, of lists that are each ascending
// (a list may repeat a value); linear in their total size.
std::vector<uint32_t> mergeSorted(const std::vector<std::vector<uint32_t>>& lists);

// True when the box comes within reach of the near plane's rectangle, where a
// query on it would be clipped away and prove nothing.
// `height`: the frame's, for the query box's pixel margin (queryBoxBounds).
bool boxReachesNearPlane(const Box3d& box, const Camera& camera, int height);

// Whether culling pays, from the client's own measurements: a cost model in
// the spirit of Guthe et al. 2006 ("Near optimal hierarchical culling"). A
// culled frame costs its deciding (occluder pass, depth readback or query
// results, tests, redraws) on top of drawing what shows; brute force would
// have drawn every triangle of the region. When the estimated saving,
// draw time scaled to the region's triangles, stays below the deciding cost
// for `patience` culled frames in a row, culling stops for a while (doubling
// each time it turns out not to pay again) and is then tried again for one
// frame. Pure; the caller decides what "frame" is (a job).
struct CullCost {
  double decide_ms = 0;  // the visibility work of the frame
  double draw_ms = 0;    // drawing what was drawn
  uint64_t drawn_triangles = 0;
  uint64_t region_triangles = 0;  // every object of the region's list
};
// A pause is blind to what culling would save once the view changes (the
// camera turns from a view where nearly everything shows to one where
// little does), so every `probe_every` frames of a pause the caller may
// probe: test the frame it drew in full, and report what culling would have
// cost and saved (probed); a probe that pays ends the pause.
class CullingGovernor {
 public:
  explicit CullingGovernor(uint32_t min_off = 8, uint32_t max_off = 128, uint32_t patience = 3,
                           uint32_t probe_every = 4)
      : min_off_(min_off),
        max_off_(max_off),
        patience_(patience),
        probe_every_(probe_every),
        off_len_(min_off) {}
  bool culls() const { return off_left_ == 0; }
  // Whether this unculled frame should be probed: during a pause, once
  // probe_every counted frames (unculled() with triangles) have passed
  // since it began or since the last probe.
  bool probes() const { return off_left_ > 0 && since_probe_ >= probe_every_; }
  // After a frame that culled. A frame whose region holds no triangles is
  // not counted: nothing can be saved or lost there, and under tiles such
  // empty regions (background) paused culling for the full tiles after
  // them (docs/benchmarks.md, "Empty tiles and the cost model").
  void culled(const CullCost& c);
  // After a frame that did not, whose region holds `region_triangles`
  // (not counted when 0, as above).
  void unculled(uint64_t region_triangles);
  // A probe's estimate of culling the frame: ends the pause when it pays
  // (not counted when its region holds no triangles).
  void probed(const CullCost& c);
  // Before a frame is decided: its region's triangles (every object of its
  // list). A pause was decided on regions where drawing everything was cheap
  // enough; a region grown past kRegrowth times the largest of those is
  // another view (the split lines moved, the camera came near a model), and
  // the pause ends there instead of drawing it all blind until a probe.
  void region(uint64_t triangles);
  static constexpr double kRegrowth = 4;
  // Starts a pause of `frames` counted frames as if culling had not paid (the test
  // hook DMMR_CULL_PAUSE starts a client's run so), decided on regions of
  // `triangles` (0: region() never ends it).
  void pauseFor(uint32_t frames, uint64_t triangles = 0) {
    off_left_ = frames;
    since_probe_ = 0;
    paused_region_ = triangles;
  }
  // Estimated ms the frame's culling saved (negative: it cost).
  static double net(const CullCost& c);

 private:
  uint32_t min_off_, max_off_, patience_, probe_every_;
  uint32_t off_len_, off_left_ = 0, bad_ = 0, since_probe_ = 0;
  uint64_t bad_region_ = 0;     // the largest region of the frames that did not pay
  uint64_t paused_region_ = 0;  // the same, for the pause under way (0: none known)
};

// `--stages auto`: after frame 0 (which loads geometry), blocks of `block`
// frames alternate split, fused, split, fused, so that both modes see early
// and later frames of the walkthrough; each mode's figure is the median
// interval between the render stage's finished frames within its blocks,
// each block's first frame left out (the pipeline refills after a switch);
// the faster mode renders the rest. Pure: the client feeds it frame completions. Frames count from
// the run's first (0), so a resumed run (--from-frame) tries too.
class StageTrial {
 public:
  static constexpr uint32_t kBlocks = 4;
  explicit StageTrial(uint32_t block = 3) : block_(block) {}
  // The mode frame `frame` is rendered with. Before the choice: the trial's
  // schedule; frames past the trial whose result is not in yet: split.
  StageMode modeFor(uint32_t frame) const;
  // The render stage finished `frame` at `ms` (any monotonic clock).
  void finished(uint32_t frame, double ms);
  bool decided() const { return decided_; }
  StageMode chosen() const { return chosen_; }
  // The two blocks' medians (ms per frame), once decided.
  double splitMs() const { return split_ms_; }
  double fusedMs() const { return fused_ms_; }

 private:
  uint32_t block_;
  bool decided_ = false;
  StageMode chosen_ = StageMode::Split;
  double split_ms_ = 0, fused_ms_ = 0;
  std::vector<std::pair<uint32_t, double>> done_;  // trial frames finished, in order
};

}  // namespace dmmr
