#include "protocol.h"

#include <algorithm>
#include <cmath>

#include "bytes.h"
#include "error.h"

namespace dmmr {

namespace {

void putRect(ByteWriter& w, const Rect& r) {
  w.i32(r.x);
  w.i32(r.y);
  w.i32(r.w);
  w.i32(r.h);
}
Rect getRect(ByteReader& r) {
  Rect x{r.i32("x"), r.i32("y"), r.i32("w"), r.i32("h")};
  if (x.w < 0 || x.h < 0) r.fail("negative region size");
  return x;
}

}  // namespace

std::vector<uint8_t> encodeJob(const FrameJob& j) {
  ByteWriter w;
  w.u32(j.frame);
  const Camera& c = j.camera;
  for (double v : {c.eye.x, c.eye.y, c.eye.z, c.rotation.x, c.rotation.y, c.rotation.z,
                   c.rotation.w, c.fovy_deg, c.aspect, c.near})
    w.f64(v);
  w.i32(j.width);
  w.i32(j.height);
  putRect(w, j.region);
  w.u32(uint32_t(j.objects.size()));
  w.array(j.objects.data(), j.objects.size());
  w.u8(j.flush ? 1 : 0);
  w.u32(uint32_t(j.hints.size()));
  w.array(j.hints.data(), j.hints.size());
  w.u8(j.ray_stride);
  return std::move(w.bytes());
}

FrameJob decodeJob(const std::vector<uint8_t>& bytes, size_t object_count) {
  ByteReader r(bytes.data(), bytes.size(), "Job message");
  FrameJob j;
  j.frame = r.u32("frame");
  Camera& c = j.camera;
  for (double* v : {&c.eye.x, &c.eye.y, &c.eye.z, &c.rotation.x, &c.rotation.y, &c.rotation.z,
                    &c.rotation.w, &c.fovy_deg, &c.aspect, &c.near})
    if (!std::isfinite(*v = r.f64("camera"))) r.fail("camera value is not finite");
  if (!(c.fovy_deg > 0 && c.fovy_deg < 180)) r.fail("field of view outside (0, 180) degrees");
  if (!(c.aspect > 0) || !(c.near > 0)) r.fail("aspect or near plane not positive");
  if (c.rotation.x == 0 && c.rotation.y == 0 && c.rotation.z == 0 && c.rotation.w == 0)
    r.fail("zero rotation");
  j.width = r.i32("width");
  j.height = r.i32("height");
  if (j.width <= 0 || j.height <= 0) r.fail("bad frame size");
  j.region = getRect(r);
  if (!insideFrame(j.region, j.width, j.height)) r.fail("region outside the frame");
  r.array(&j.objects, r.u32("object count"), "objects");
  for (size_t i = 0; i < j.objects.size(); ++i) {
    if (j.objects[i] >= object_count) r.fail("object index beyond the scene's objects");
    if (i > 0 && j.objects[i] <= j.objects[i - 1]) r.fail("object indices not ascending");
  }
  uint8_t flush = r.u8("flush");
  if (flush > 1) r.fail("flush is neither 0 nor 1");
  j.flush = flush == 1;
  r.array(&j.hints, r.u32("hint count"), "hints");
  auto in = j.objects.begin();
  for (size_t i = 0; i < j.hints.size(); ++i) {
    if (i > 0 && j.hints[i] <= j.hints[i - 1]) r.fail("hints not ascending");
    in = std::lower_bound(in, j.objects.end(), j.hints[i]);
    if (in == j.objects.end() || *in != j.hints[i]) r.fail("a hint that is not among the objects");
  }
  j.ray_stride = r.u8("ray stride");
  if (j.ray_stride < 1 || j.ray_stride > kMaxJobRayStride) r.fail("ray stride outside 1 to 8");
  r.finish();
  return j;
}

namespace {

void putSubFrame(ByteWriter& w, const SubFrame& s) {
  w.u32(s.frame);
  putRect(w, s.region);
  w.u8(uint8_t(s.codec));
  w.u64(s.raw_size);
  const ClientStats& t = s.stats;
  for (double v :
       {t.prepare_ms, t.retrieve_ms, t.pass_ms, t.load_ms, t.render_ms, t.readback_ms,
        t.compress_ms, t.send_ms, t.vis_cpu_ms, t.render_cpu_ms, t.vis_sys_ms, t.render_sys_ms})
    w.f64(v);
  for (uint64_t v :
       {t.objects, t.occluders, t.queried, t.visible, t.triangles, t.submitted, t.bytes_raw,
        t.bytes_sent, t.gpu_hits, t.gpu_misses, t.ram_hits, t.ram_misses, t.disk_bytes, t.uncached,
        t.skipped, t.gpu_resident, t.ram_resident, t.vis_faults, t.render_faults})
    w.u64(v);
  w.u64(s.data.size());
  w.array(s.data.data(), s.data.size());
  w.u32(uint32_t(s.drawn.size()));
  w.array(s.drawn.data(), s.drawn.size());
}

SubFrame getSubFrame(ByteReader& r) {
  SubFrame s;
  s.frame = r.u32("frame");
  s.region = getRect(r);
  uint8_t codec = r.u8("codec");
  if (codec > uint8_t(Codec::Zlib)) r.fail("unknown codec");
  s.codec = Codec(codec);
  s.raw_size = r.u64("raw size");
  if (s.raw_size != uint64_t(s.region.area()) * 3) r.fail("raw size does not match the region");
  ClientStats& t = s.stats;
  for (double* v : {&t.prepare_ms, &t.retrieve_ms, &t.pass_ms, &t.load_ms, &t.render_ms,
                    &t.readback_ms, &t.compress_ms, &t.send_ms, &t.vis_cpu_ms, &t.render_cpu_ms,
                    &t.vis_sys_ms, &t.render_sys_ms})
    *v = r.f64("stats");
  for (uint64_t* v :
       {&t.objects, &t.occluders, &t.queried, &t.visible, &t.triangles, &t.submitted, &t.bytes_raw,
        &t.bytes_sent, &t.gpu_hits, &t.gpu_misses, &t.ram_hits, &t.ram_misses, &t.disk_bytes,
        &t.uncached, &t.skipped, &t.gpu_resident, &t.ram_resident, &t.vis_faults, &t.render_faults})
    *v = r.u64("stats");
  r.array(&s.data, r.u64("data size"), "data");
  r.array(&s.drawn, r.u32("drawn count"), "drawn objects");
  return s;
}

}  // namespace

std::vector<uint8_t> encodeSubFrames(const std::vector<SubFrame>& subs) {
  ByteWriter w;
  w.u32(uint32_t(subs.size()));
  for (const SubFrame& s : subs) putSubFrame(w, s);
  return std::move(w.bytes());
}

std::vector<SubFrame> decodeSubFrames(const std::vector<uint8_t>& bytes) {
  ByteReader r(bytes.data(), bytes.size(), "SubFrame message");
  uint32_t n = r.u32("sub-frame count");
  if (n == 0) r.fail("no sub-frames");
  // Each sub-frame takes at least its fixed fields: a count beyond what the
  // bytes can hold is malformed, not an allocation to attempt.
  if (n > bytes.size() / 64) r.fail("more sub-frames than the message can hold");
  std::vector<SubFrame> subs;
  subs.reserve(n);
  for (uint32_t i = 0; i < n; ++i) subs.push_back(getSubFrame(r));
  r.finish();
  return subs;
}

std::vector<uint8_t> encodeSubFrame(const SubFrame& s) {
  return encodeSubFrames({s});
}

SubFrame decodeSubFrame(const std::vector<uint8_t>& bytes) {
  std::vector<SubFrame> subs = decodeSubFrames(bytes);
  if (subs.size() != 1)
    throw Error("SubFrame message: " + std::to_string(subs.size()) + " sub-frames, expected 1");
  return subs[0];
}

void accumulate(ClientStats& a, const ClientStats& b) {
  for (auto [x, y] : {std::pair{&a.prepare_ms, b.prepare_ms},
                      {&a.retrieve_ms, b.retrieve_ms},
                      {&a.pass_ms, b.pass_ms},
                      {&a.load_ms, b.load_ms},
                      {&a.render_ms, b.render_ms},
                      {&a.readback_ms, b.readback_ms},
                      {&a.compress_ms, b.compress_ms},
                      {&a.send_ms, b.send_ms},
                      {&a.vis_cpu_ms, b.vis_cpu_ms},
                      {&a.render_cpu_ms, b.render_cpu_ms},
                      {&a.vis_sys_ms, b.vis_sys_ms},
                      {&a.render_sys_ms, b.render_sys_ms}})
    *x += y;
  for (auto [x, y] : {std::pair{&a.objects, b.objects},
                      {&a.occluders, b.occluders},
                      {&a.queried, b.queried},
                      {&a.visible, b.visible},
                      {&a.triangles, b.triangles},
                      {&a.submitted, b.submitted},
                      {&a.bytes_raw, b.bytes_raw},
                      {&a.bytes_sent, b.bytes_sent},
                      {&a.gpu_hits, b.gpu_hits},
                      {&a.gpu_misses, b.gpu_misses},
                      {&a.ram_hits, b.ram_hits},
                      {&a.ram_misses, b.ram_misses},
                      {&a.disk_bytes, b.disk_bytes},
                      {&a.uncached, b.uncached},
                      {&a.skipped, b.skipped},
                      {&a.vis_faults, b.vis_faults},
                      {&a.render_faults, b.render_faults}})
    *x += y;
  a.gpu_resident = b.gpu_resident;
  a.ram_resident = b.ram_resident;
}

std::vector<uint8_t> encodeText(const std::string& s) {
  return {s.begin(), s.end()};
}
std::string decodeText(const std::vector<uint8_t>& bytes) {
  return {bytes.begin(), bytes.end()};
}

}  // namespace dmmr
