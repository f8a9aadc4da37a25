// Small glTF files the tests write themselves: a unit cube (8 vertices, 12
// triangles, texture coordinates) in two instances under a node hierarchy,
// as .gltf with any buffer and image URI, or as .glb.
#pragma once

#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <osg/Image>
#include <osgDB/WriteFile>

namespace dmmr::test::gltf {

// A unit cube centred on the origin: 8 vertices, texture coordinates, 12
// triangles as 16-bit indices. Layout: positions 0..95, uvs 96..159,
// indices 160..231.
inline const float kUv[8][2] = {{0, 0},      {1, 0},      {0, 1},      {1, 1},
                                {0.25, 0.5}, {0.75, 0.5}, {0.5, 0.25}, {0.5, 0.75}};

inline std::vector<uint8_t> cubeBuffer() {
  std::vector<uint8_t> b;
  auto put = [&](const void* p, size_t n) {
    b.insert(b.end(), static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n);
  };
  for (int i = 0; i < 8; ++i) {
    float v[3] = {(i & 1) ? 0.5f : -0.5f, (i & 2) ? 0.5f : -0.5f, (i & 4) ? 0.5f : -0.5f};
    put(v, sizeof v);
  }
  put(kUv, sizeof kUv);
  const uint16_t idx[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                            2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  put(idx, sizeof idx);
  return b;
}

inline std::string base64(const std::vector<uint8_t>& in) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < in.size(); i += 3) {
    uint32_t n = uint32_t(in[i]) << 16;
    if (i + 1 < in.size()) n |= uint32_t(in[i + 1]) << 8;
    if (i + 2 < in.size()) n |= in[i + 2];
    out += k[(n >> 18) & 63];
    out += k[(n >> 12) & 63];
    out += i + 1 < in.size() ? k[(n >> 6) & 63] : '=';
    out += i + 2 < in.size() ? k[n & 63] : '=';
  }
  return out;
}

struct Gltf {
  std::string buffer_uri;  // empty: the .glb's own BIN chunk
  std::string image_uri;   // empty: untextured
};

// Nodes: "root" (translation (10, 0, 0), scale 2) over "a" (the cube) and
// "b" (translation (0, 3, 0), the same cube): two instances of one mesh.
inline std::string gltfJson(const Gltf& g, size_t bufferBytes) {
  std::string buffer = "{\"byteLength\": " + std::to_string(bufferBytes);
  if (!g.buffer_uri.empty()) buffer += ", \"uri\": \"" + g.buffer_uri + "\"";
  buffer += "}";
  std::string material = "{\"pbrMetallicRoughness\": {\"baseColorFactor\": [0.25, 0.5, 0.75, 1]";
  if (!g.image_uri.empty()) material += ", \"baseColorTexture\": {\"index\": 0}";
  material += "}}";
  std::string attributes = "{\"POSITION\": 0";
  if (!g.image_uri.empty()) attributes += ", \"TEXCOORD_0\": 1";
  attributes += "}";
  std::string j = R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"name": "root", "translation": [10, 0, 0], "scale": [2, 2, 2], "children": [1, 2]},
            {"name": "a", "mesh": 0}, {"name": "b", "translation": [0, 3, 0], "mesh": 0}],
  "meshes": [{"primitives": [{"attributes": )" +
                  attributes + R"(, "indices": 2, "material": 0}]}],
  "materials": [)" +
                  material +
                  R"(],
  "buffers": [)" + buffer +
                  R"(],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 96},
                  {"buffer": 0, "byteOffset": 96, "byteLength": 64},
                  {"buffer": 0, "byteOffset": 160, "byteLength": 72}],
  "accessors": [
    {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
     "min": [-0.5, -0.5, -0.5], "max": [0.5, 0.5, 0.5]},
    {"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC2"},
    {"bufferView": 2, "componentType": 5123, "count": 36, "type": "SCALAR"}])";
  if (!g.image_uri.empty())
    j += R"(,
  "images": [{"uri": ")" +
         g.image_uri + R"("}], "textures": [{"source": 0}])";
  return j + "}\n";
}

inline void writeText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

inline void writeBytes(const std::string& path, const std::vector<uint8_t>& b) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

inline std::vector<uint8_t> glbBytes() {
  std::string json = gltfJson({}, cubeBuffer().size());
  while (json.size() % 4) json += ' ';
  std::vector<uint8_t> bin = cubeBuffer();
  while (bin.size() % 4) bin.push_back(0);
  std::vector<uint8_t> out;
  auto u32 = [&](uint32_t v) {
    for (int k = 0; k < 4; ++k) out.push_back(uint8_t(v >> (8 * k)));
  };
  out.insert(out.end(), {'g', 'l', 'T', 'F'});
  u32(2);
  u32(uint32_t(12 + 8 + json.size() + 8 + bin.size()));
  u32(uint32_t(json.size()));
  u32(0x4E4F534A);  // JSON
  out.insert(out.end(), json.begin(), json.end());
  u32(uint32_t(bin.size()));
  u32(0x004E4942);  // BIN
  out.insert(out.end(), bin.begin(), bin.end());
  return out;
}

// A 2x2 RGBA image written as PNG; returns its pixels, bottom row first.
inline std::vector<uint8_t> writePng(const std::string& path) {
  osg::ref_ptr<osg::Image> img = new osg::Image;
  img->allocateImage(2, 2, 1, GL_RGBA, GL_UNSIGNED_BYTE);
  const uint8_t px[16] = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 255};
  std::memcpy(img->data(), px, sizeof px);
  EXPECT_TRUE(osgDB::writeImageFile(*img, path)) << path;
  return std::vector<uint8_t>(px, px + 16);
}

}  // namespace dmmr::test::gltf
