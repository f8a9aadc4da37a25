#include "protocol.h"

#include "bytes.h"

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
  return std::move(w.bytes());
}

FrameJob decodeJob(const std::vector<uint8_t>& bytes) {
  ByteReader r(bytes.data(), bytes.size(), "Job message");
  FrameJob j;
  j.frame = r.u32("frame");
  Camera& c = j.camera;
  for (double* v : {&c.eye.x, &c.eye.y, &c.eye.z, &c.rotation.x, &c.rotation.y, &c.rotation.z,
                    &c.rotation.w, &c.fovy_deg, &c.aspect, &c.near})
    *v = r.f64("camera");
  j.width = r.i32("width");
  j.height = r.i32("height");
  if (j.width <= 0 || j.height <= 0) r.fail("bad frame size");
  j.region = getRect(r);
  r.array(&j.objects, r.u32("object count"), "objects");
  r.finish();
  return j;
}

std::vector<uint8_t> encodeSubFrame(const SubFrame& s) {
  ByteWriter w;
  w.u32(s.frame);
  putRect(w, s.region);
  w.u8(uint8_t(s.codec));
  w.u64(s.raw_size);
  const ClientStats& t = s.stats;
  for (double v : {t.prepare_ms, t.retrieve_ms, t.pass_ms, t.load_ms, t.render_ms, t.readback_ms,
                   t.compress_ms, t.send_ms})
    w.f64(v);
  for (uint64_t v : {t.objects, t.occluders, t.queried, t.visible, t.triangles, t.bytes_raw,
                     t.bytes_sent, t.gpu_hits, t.gpu_misses, t.ram_hits, t.ram_misses, t.disk_bytes,
                     t.uncached, t.skipped, t.gpu_resident, t.ram_resident})
    w.u64(v);
  w.u64(s.data.size());
  w.array(s.data.data(), s.data.size());
  w.u32(uint32_t(s.drawn.size()));
  w.array(s.drawn.data(), s.drawn.size());
  return std::move(w.bytes());
}

SubFrame decodeSubFrame(const std::vector<uint8_t>& bytes) {
  ByteReader r(bytes.data(), bytes.size(), "SubFrame message");
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
                    &t.readback_ms, &t.compress_ms, &t.send_ms})
    *v = r.f64("stats");
  for (uint64_t* v : {&t.objects, &t.occluders, &t.queried, &t.visible, &t.triangles, &t.bytes_raw,
                      &t.bytes_sent, &t.gpu_hits, &t.gpu_misses, &t.ram_hits, &t.ram_misses,
                      &t.disk_bytes, &t.uncached, &t.skipped, &t.gpu_resident, &t.ram_resident})
    *v = r.u64("stats");
  r.array(&s.data, r.u64("data size"), "data");
  r.array(&s.drawn, r.u32("drawn count"), "drawn objects");
  r.finish();
  return s;
}

std::vector<uint8_t> encodeText(const std::string& s) {
  return {s.begin(), s.end()};
}
std::string decodeText(const std::vector<uint8_t>& bytes) {
  return {bytes.begin(), bytes.end()};
}

}  // namespace dmmr
