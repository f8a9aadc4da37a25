// Writes the small seed corpus of every fuzz target:
//   make_fuzz_corpus <dir>   ->  <dir>/<target>/<seed>
// The checked-in tests/fuzz/corpus was made with it; rerun after a format change.
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "bytes.h"
#include "formats.h"
#include "image.h"
#include "jpeg.h"
#include "protocol.h"
#include "viewer_protocol.h"
#include "walkthrough.h"

namespace fs = std::filesystem;
using namespace dmmr;

namespace {

std::string g_root;

void put(const std::string& target, const std::string& name, const std::vector<uint8_t>& bytes) {
  fs::create_directories(g_root + "/" + target);
  writeFileAtomic(g_root + "/" + target + "/" + name, bytes);
}
void put(const std::string& target, const std::string& name, const std::string& text) {
  put(target, name, std::vector<uint8_t>(text.begin(), text.end()));
}

SkeletonNode node(NodeKind kind, uint32_t parent, uint32_t end, uint32_t object,
                  const std::string& name) {
  SkeletonNode n;
  n.kind = kind;
  n.parent = parent;
  n.end = end;
  n.object = object;
  n.name = name;
  return n;
}

ObjectBounds object(uint32_t geometry, double x) {
  ObjectBounds o;
  o.geometry = geometry;
  o.transform = Mat4d::translate({x, 2, 3}) * Mat4d::scale({1, 2, 0.5});
  o.sphere = {{x, 2, 3}, 1.5};
  o.box = {{x - 1, 1, 2}, {x + 1, 3, 4}};
  o.use_box = geometry % 2 == 0;
  o.weight = 12 + geometry;
  return o;
}

GeometryData triangles(bool normals, bool colors, bool texcoords, int submeshes) {
  GeometryData g;
  g.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  if (normals) g.normals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  if (colors) g.colors = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 128, 9, 9, 9, 0};
  if (texcoords) g.texcoords = {0, 0, 1, 0, 0, 1, 1, 1};
  g.indices = {0, 1, 2, 2, 1, 3};
  for (int i = 0; i < submeshes; ++i) {
    SubMesh s;
    s.first_index = submeshes == 1 ? 0 : uint32_t(3 * i);
    s.index_count = submeshes == 1 ? 6 : 3;
    s.texture = i == 0 ? -1 : i - 1;
    s.diffuse[1] = 0.25f * float(i);
    g.submeshes.push_back(s);
  }
  return g;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_fuzz_corpus <dir>\n");
    return 2;
  }
  g_root = argv[1];

  put("bounds", "empty", encodeBounds({}));
  put("bounds", "one", encodeBounds({object(0, 1)}));
  put("bounds", "three", encodeBounds({object(0, 1), object(1, -5), object(0, 7)}));

  std::vector<SkeletonNode> tree = {
      node(NodeKind::Group, kNone, 6, kNone, "root"), node(NodeKind::Transform, 0, 4, kNone, "xf"),
      node(NodeKind::Object, 1, 3, 0, "a"),           node(NodeKind::Object, 1, 4, 1, ""),
      node(NodeKind::Group, 0, 6, kNone, "g"),        node(NodeKind::Object, 4, 6, 2, "c")};
  tree[0].box = {{-1, -2, -3}, {4, 5, 6}};
  tree[2].box = {{0, 0, 0}, {1, 1, 1}};
  put("skeleton", "single", encodeSkeleton({node(NodeKind::Object, kNone, 1, 0, "only")}));
  put("skeleton", "tree", encodeSkeleton(tree));

  put("occluders", "empty", encodeOccluders({}));
  put("occluders", "three", encodeOccluders({1, 5, 9}));

  {
    GeometryParts a, b;
    a.box = {{-1, -2, -3}, {1, 2, 3}};
    a.parts = {{0, 0, 0, 255, 255, 255}, {10, 20, 30, 40, 50, 60}};
    b.box = {{0.5, 0.5, 0.5}, {0.5, 0.75, 1}};
    put("parts", "empty", encodeParts({}));
    put("parts", "two", encodeParts({a, b}));
    // corpus/parts/two-v1 is "two" as version 1 wrote it, kept as a seed
    // for the older version's path.
    a.triangles = {3, 4, 0, 5};  // ordered by part, two submeshes
    put("parts", "ordered", encodeParts({a, b}));
  }

  put("geometry", "plain", encodeGeometry(triangles(false, false, false, 1)));
  put("geometry", "all_attributes", encodeGeometry(triangles(true, true, true, 2)));
  put("geometry", "normals_texcoords", encodeGeometry(triangles(true, false, true, 3)));
  {
    // The same triangles with 32-bit indices, which readers accept for any
    // vertex count (writers use them only above 65536 vertices).
    GeometryData g = triangles(false, true, false, 1);
    ByteWriter w;
    w.u8(0);
    w.u8(2);  // colors, 32-bit indices
    w.u32(4);
    w.u32(6);
    w.u32(1);
    w.u32(0);
    w.u32(6);
    w.array(g.submeshes[0].diffuse, 4);
    w.i32(-1);
    w.array(g.positions.data(), g.positions.size());
    w.array(g.colors.data(), g.colors.size());
    w.array(g.indices.data(), g.indices.size());
    put("geometry", "index32", wrapContainer(FileKind{"DMMRGEOM", 1, "geometry"}, w.bytes()));
  }
  put("geometry", "empty", encodeGeometry({}));
  // The compact encodings (formats.h), with every attribute, a level of
  // detail, and texture coordinates both in the 16-bit range and beyond it.
  {
    GeometryData g = triangles(true, true, true, 2);
    g.lod_indices = {0, 1, 2};
    GeometryData wide = triangles(true, false, true, 1);
    wide.texcoords[2] = 5.5f;  // spans more than 2: float texture coordinates
    GeometryData bare = triangles(false, false, false, 1);
    for (Encoding e : {Encoding::Quantized, Encoding::Meshopt, Encoding::QuantizedMeshopt}) {
      std::string name = encodingName(e);
      put("geometry", name + "_all_attributes", encodeGeometry(g, e));
      put("geometry", name + "_wide_texcoords", encodeGeometry(wide, e));
      put("geometry", name + "_plain", encodeGeometry(bare, e));
    }
  }

  TextureData t;
  t.width = 2;
  t.height = 3;
  t.repeat_s = false;
  for (int i = 0; i < 24; ++i) t.rgba.push_back(uint8_t(i * 10));
  put("texture", "2x3", encodeTexture(t));
  put("texture", "1x1", encodeTexture({1, 1, true, true, {1, 2, 3, 4}}));

  Manifest m;
  m.objects = 3;
  m.geometries = 2;
  m.textures = 1;
  m.occluders = 1;
  m.triangles = 6;
  m.unique_triangles = 4;
  m.geometry_bytes = 300;
  m.bounds = {{-1.5, 0, -2}, {10, 2.25, 1e6}};
  m.inputs = {"models/plant.osgb"};
  m.files = {{"skeleton.bin", {100, 1}},        {"bounds.bin", {600, 2}},
             {"occluders.bin", {28, 3}},        {"geometry/000000.bin", {120, 4}},
             {"geometry/000001.bin", {140, 5}}, {"textures/000000.bin", {40, 6}}};
  put("manifest", "full.json", encodeManifest(m));
  Manifest small;
  small.bounds = {{0, 0, 0}, {0, 0, 0}};
  put("manifest", "empty.json", encodeManifest(small));

  put("walkthrough", "simple.path",
      "# camera path\n0 0 0 10 0 0 0 1\n\n0.5 1 2 3 0.5 0.5 0.5 0.5\n1 1.5 2 3 0 0.70710678 0 "
      "0.70710678\n");
  put("walkthrough", "crlf.path", "0 1 2 3 0 0 0 1\r\n# c\r\n1 4 5 6 0 1 0 0\r\n");
  Walkthrough w;
  w.points = {
      {0, {-71.18, -12.3, 13.3}, lookAtRotation({-71.18, -12.3, 13.3}, {0, 0, 0}, {0, 0, 1})},
      {0.04, {-69.2, -11.5, 13.3}, lookAtRotation({-69.2, -11.5, 13.3}, {0, 0, 1}, {0, 0, 1})}};
  put("walkthrough", "formatted.path", formatWalkthrough(w));

  // Protocol messages, behind the target's selector byte (even: Job, with
  // the scene's object count in the upper 7 bits: 20, and 127 for 2^32).
  auto message = [](uint8_t selector, std::vector<uint8_t> bytes) {
    bytes.insert(bytes.begin(), selector);
    return bytes;
  };
  FrameJob job{3,        Camera{{1, 2, 3}, {0, 0, 0, 1}, 45, 1.5, 0.01}, 64, 48, {0, 16, 32, 16},
               {0, 4, 9}};
  put("protocol", "job.bin", message(20 << 1, encodeJob(job)));
  job.flush = false;
  job.hints = {4, 9};
  put("protocol", "job-noflush.bin", message(127 << 1, encodeJob(job)));
  job.ray_stride = 3;
  put("protocol", "job-stride.bin", message(31 << 1, encodeJob(job)));
  SubFrame sub;
  sub.frame = 3;
  sub.region = {0, 0, 2, 1};
  sub.codec = Codec::None;
  sub.raw_size = 6;
  sub.data = {1, 2, 3, 4, 5, 6};
  sub.drawn = {4};
  put("protocol", "subframe.bin", message(1, encodeSubFrames({sub})));
  SubFrame other = sub;
  other.region = {2, 0, 2, 1};
  put("protocol", "batch.bin", message(3, encodeSubFrames({sub, other})));

  // Viewer messages (interactive mode), behind the selector byte: 0 a
  // viewer's message, 1 a frame message, 2 a JPEG.
  Pose pose;
  pose.seq = 5;
  pose.time_ms = 1234.5;
  pose.position = {1, 2, 3};
  pose.rotation = {0, 0.70710678, 0, 0.70710678};
  pose.width = 640;
  pose.height = 480;
  put("viewer", "pose.bin", message(0, encodePose(pose)));
  put("viewer", "ack.bin", message(0, encodeAck(7)));
  put("viewer", "frame.bin",
      message(1, encodeFrameMessage({FrameEncoding::Png, R"({"frame":1})", {1, 2, 3}})));
  Image tiny = Image::blank(8, 8);
  for (size_t i = 0; i < tiny.rgba.size(); ++i) tiny.rgba[i] = uint8_t(i * 13);
  put("viewer", "small.jpg", message(2, encodeJpeg(tiny, 50)));

  Image rgba = Image::blank(3, 2);
  for (size_t i = 0; i < rgba.rgba.size(); ++i) rgba.rgba[i] = uint8_t(i * 37);
  put("png", "rgba3x2.png", encodePng(rgba, 0));
  put("png", "rgba1x1.png", encodePng(Image{1, 1, {10, 20, 30, 40}}, 9));
  return 0;
}
