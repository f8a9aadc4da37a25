// A strict reader for PLY models (ASCII, binary little- and big-endian), in
// place of OpenSceneGraph's PLY plugin, which crashes on a header cut short
// or a face index past the vertices and returns part of a model whose faces
// are cut short. For every well-formed file it builds the same osg::Geometry
// as that plugin did, so the frames of PLY scenes stay as they were.
#pragma once

#include <cstdint>
#include <istream>
#include <string>
#include <vector>

#include <osg/Node>
#include <osg/ref_ptr>

namespace dmmr {

// A PLY model as its file has it.
struct PlyMesh {
  std::vector<float> positions;  // x, y, z per vertex
  std::vector<float> normals;    // nx, ny, nz per vertex; empty when the file has none
  // RGBA in [0, 1] per vertex; empty when the file has none. From the
  // vertex's red/green/blue(/alpha) or else diffuse_red/... or
  // specular_red/...; integers are scaled by their type's maximum (uchar:
  // 255, as OSG's plugin did), floats clamped to [0, 1].
  std::vector<float> colors;
  std::vector<uint32_t> triangles;  // 3 vertex indices per face of 3 corners
  std::vector<uint32_t> quads;      // 4 per face of 4 corners
  uint64_t other_faces = 0;         // faces of other corner counts: not drawn, as in OSG
  std::vector<float> uv;            // texture_u, texture_v per vertex; empty without both
  std::string texture_file;         // the header's "comment TextureFile NAME" (empty: none)
  // The header's "comment modified by flipply": faces were reversed (the
  // corner order above is already the drawn one).
  bool flipped = false;
};

// Parses a whole PLY file from `in`. `name` (the path) starts every error
// message. Throws Error on a malformed or unsupported header (no "ply", no
// or unknown format, a property of unknown type, no end_header, a vertex
// element without x, y and z, a face list of non-integer indices), on a body
// cut short (naming the element and how many of its items were read), on a
// number that does not parse (ASCII, with its line), on a negative or
// out-of-range vertex index (naming the face), and on bytes after the last
// element other than whitespace. `size_hint`: the file's size in bytes if
// known (0: unknown); it bounds what the header's counts may reserve.
PlyMesh parsePly(std::istream& in, const std::string& name, uint64_t size_hint = 0);

// Reads `path` with parsePly and builds what OSG's PLY plugin built: a Geode
// with one Geometry holding the vertices, per-vertex colours and normals, a
// TRIANGLES and a QUADS DrawElementsUInt (those not empty), and, for a file
// without normals, the normals osgUtil::SmoothingVisitor makes with a crease
// angle of 90 degrees. A file with no faces gives its vertices as points
// (which dmmr does not draw). Throws Error as parsePly, and when the file
// cannot be opened.
osg::ref_ptr<osg::Node> readPly(const std::string& path);

}  // namespace dmmr
