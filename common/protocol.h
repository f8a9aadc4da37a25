// Messages between the server and the clients, encoded with explicit
// little-endian fields and decoded strictly (a malformed message is an Error
// naming the message, never a crash).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "camera.h"
#include "compress.h"

namespace dmmr {

struct FrameJob {
  uint32_t frame = 0;
  Camera camera;
  int width = 0, height = 0;      // the full frame
  Rect region;                    // this client's scissor rectangle
  std::vector<uint32_t> objects;  // ascending object indices to draw
  // Send the sub-frames held so far now (with this job's). False on all but
  // the last of a client's tiles in a frame under --balance tiles-static,
  // whose clients return their tiles in one batch.
  bool flush = true;
  // Of `objects` (ascending, a subset): those some client drew lately, as
  // far as the server knows. A client takes those it did not have in its
  // own region last frame as likely visible (they start its occluder set),
  // so that a split line that moved does not make a neighbour's visible
  // objects new to it. A hint never changes a pixel, only the order of work.
  std::vector<uint32_t> hints;
  // Ray-tracing clients: one primary ray per ray_stride x ray_stride pixels,
  // the rest interpolated (1: every pixel, exact; at most kMaxJobRayStride).
  // The interactive mode's moving frames (--ray-stride); raster clients
  // ignore it.
  uint8_t ray_stride = 1;
  friend bool operator==(const FrameJob&, const FrameJob&) = default;
};
inline constexpr uint8_t kMaxJobRayStride = 8;

struct ClientStats {
  // Visibility stage (context 1).
  double prepare_ms = 0;   // occluders into depth, occlusion queries issued
  double retrieve_ms = 0;  // query results read back, visible list built
  double pass_ms = 0;      // handing the list to the render stage (waiting included)
  // Render stage (context 2).
  double load_ms = 0;      // reading and uploading geometry not yet resident
  double render_ms = 0;    // drawing the visible list (through glFinish)
  double readback_ms = 0;  // reading the region's pixels
  double compress_ms = 0;
  double send_ms = 0;  // MPI send of this client's previous sub-frame
  // CPU time of the stage threads on this job (CLOCK_THREAD_CPUTIME_ID):
  // the visibility stage's culling, and the render stage's work from load to
  // compression (fused culling included). With LP_NUM_THREADS=0 llvmpipe
  // rasterises on these threads, so they are the stages' whole cost,
  // whatever else runs on the machine.
  double vis_cpu_ms = 0, render_cpu_ms = 0;
  // Of that CPU time, the kernel's part, and the minor page faults the stage
  // threads took (threadUsage): on a virtual machine a fault's cost depends
  // on the host, so benchmarks show CPU time with and without it.
  double vis_sys_ms = 0, render_sys_ms = 0;
  uint64_t vis_faults = 0, render_faults = 0;
  uint64_t objects = 0;  // objects in the region's list from the server
  uint64_t occluders = 0, queried = 0, visible = 0;
  uint64_t triangles = 0;  // triangles drawn by the render stage
  // Triangles the render stage handed to the GL, every pass (depth and
  // colour) counted, after the triangle cull (Renderer::trianglesSubmitted):
  // what the rasteriser set up, where `triangles` counts each drawn object's
  // selected triangles once.
  uint64_t submitted = 0;
  uint64_t bytes_raw = 0, bytes_sent = 0;
  // Geometry cache, this frame: hits and misses per level, bytes read from
  // disk, meshes too large for a level (used uncached), objects skipped for
  // unreadable geometry; and bytes resident now (GPU: both contexts).
  uint64_t gpu_hits = 0, gpu_misses = 0, ram_hits = 0, ram_misses = 0, disk_bytes = 0;
  uint64_t uncached = 0, skipped = 0, gpu_resident = 0, ram_resident = 0;
  friend bool operator==(const ClientStats&, const ClientStats&) = default;
};

// Adds a tile's stats to a client's total for the frame: times and counts
// add up; resident bytes are the latest.
void accumulate(ClientStats& total, const ClientStats& tile);

// The region's pixels as RGB8 rows, bottom row first, compressed with `codec`.
struct SubFrame {
  uint32_t frame = 0;
  Rect region;
  Codec codec = Codec::LZ4;
  uint64_t raw_size = 0;
  std::vector<uint8_t> data;
  ClientStats stats;
  std::vector<uint32_t> drawn;  // the objects the render stage drew (ascending)
  friend bool operator==(const SubFrame&, const SubFrame&) = default;
};

std::vector<uint8_t> encodeJob(const FrameJob& j);
// Decodes a Job for a scene of `object_count` objects. A job is a peer's
// input, and clients index the scene with it: throws Error (naming the
// message) unless its objects ascend strictly below `object_count`, its
// hints ascend strictly and are among its objects, its region lies inside
// its frame, and its camera is finite with a field of view in (0, 180)
// degrees, positive aspect and near, and a non-zero rotation.
FrameJob decodeJob(const std::vector<uint8_t>& bytes, size_t object_count);
std::vector<uint8_t> encodeSubFrame(const SubFrame& s);
SubFrame decodeSubFrame(const std::vector<uint8_t>& bytes);
// A SubFrame message: one or more sub-frames (a client's batch of tiles).
std::vector<uint8_t> encodeSubFrames(const std::vector<SubFrame>& s);
std::vector<SubFrame> decodeSubFrames(const std::vector<uint8_t>& bytes);
std::vector<uint8_t> encodeText(const std::string& s);
std::string decodeText(const std::vector<uint8_t>& bytes);

}  // namespace dmmr
