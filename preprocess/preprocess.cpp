#include "preprocess.h"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <osg/Billboard>
#include <osg/Geode>
#include <osg/Geometry>
#include <osg/LOD>
#include <osg/Material>
#include <osg/PagedLOD>
#include <osg/Switch>
#include <osg/Texture2D>
#include <osg/Transform>
#include <osg/TriangleIndexFunctor>
#include <osgDB/ReadFile>
#include <sstream>
#include <tuple>
#include <unordered_map>

#include <meshoptimizer.h>

#include "assimp_reader.h"
#include "atomic_file.h"
#include "cluster.h"
#include "error.h"
#include "obj_check.h"
#include "plugin_guard.h"
#include "ply_reader.h"

namespace fs = std::filesystem;

namespace dmmr {

namespace {

using Clock = std::chrono::steady_clock;

// State inherited along a path: the nearest Material's diffuse and the
// nearest 2D texture on unit 0.
struct InheritedState {
  const osg::Material* material = nullptr;
  const osg::Texture2D* texture = nullptr;
};

InheritedState applyStateSet(InheritedState s, const osg::StateSet* ss) {
  if (!ss) return s;
  if (auto* m = dynamic_cast<const osg::Material*>(ss->getAttribute(osg::StateAttribute::MATERIAL)))
    s.material = m;
  if (auto* t = dynamic_cast<const osg::Texture2D*>(
          ss->getTextureAttribute(0, osg::StateAttribute::TEXTURE)))
    s.texture = t;
  // Generated texture coordinates (sphere maps, planes) are fixed-function
  // effects dmmr does not reproduce: such a texture is left off.
  if (ss->getTextureAttribute(0, osg::StateAttribute::TEXGEN)) s.texture = nullptr;
  return s;
}

struct TriangleCollector {
  std::vector<uint32_t>* out;
  void operator()(unsigned a, unsigned b, unsigned c) {
    out->push_back(a);
    out->push_back(b);
    out->push_back(c);
  }
};

// Reads element i of a vertex-like array as double xyz.
bool readVec3(const osg::Array* a, size_t i, Vec3d* v) {
  if (auto* f = dynamic_cast<const osg::Vec3Array*>(a)) {
    const osg::Vec3& p = (*f)[i];
    *v = {p.x(), p.y(), p.z()};
    return true;
  }
  if (auto* d = dynamic_cast<const osg::Vec3dArray*>(a)) {
    const osg::Vec3d& p = (*d)[i];
    *v = {p.x(), p.y(), p.z()};
    return true;
  }
  return false;
}

bool readColor(const osg::Array* a, size_t i, uint8_t out[4]) {
  auto q = [](float x) { return uint8_t(std::lround(std::clamp(x, 0.f, 1.f) * 255.f)); };
  if (auto* c = dynamic_cast<const osg::Vec4Array*>(a)) {
    for (int k = 0; k < 4; ++k) out[k] = q((*c)[i][k]);
    return true;
  }
  if (auto* c = dynamic_cast<const osg::Vec4ubArray*>(a)) {
    for (int k = 0; k < 4; ++k) out[k] = (*c)[i][k];
    return true;
  }
  if (auto* c = dynamic_cast<const osg::Vec3Array*>(a)) {
    for (int k = 0; k < 3; ++k) out[k] = q((*c)[i][k]);
    out[3] = 255;
    return true;
  }
  return false;
}

bool perVertex(const osg::Array* a, size_t nv) {
  return a && a->getBinding() == osg::Array::BIND_PER_VERTEX && a->getNumElements() == nv;
}

// Colours bound one per primitive set: each set's vertices take its colour
// (a vertex two sets share is stored once for each).
bool colorsPerPrimitiveSet(const osg::Geometry& g) {
  const osg::Array* a = g.getColorArray();
  return a && a->getBinding() == osg::Array::BIND_PER_PRIMITIVE_SET &&
         a->getNumElements() == g.getNumPrimitiveSets();
}

// Converts an osg::Image to RGBA8, bottom row first. Returns false for pixel
// formats dmmr does not take (the texture is then left off, with a warning).
// A texture file holds repeat or clamp per axis; a mirrored repeat is stored
// as a repeat (docs/scene-format.md).
bool repeats(osg::Texture::WrapMode m) {
  return m == osg::Texture::REPEAT || m == osg::Texture::MIRROR;
}

bool convertImage(const osg::Image& img, const osg::Texture2D& tex, TextureData* out) {
  if (img.getDataType() != GL_UNSIGNED_BYTE || img.s() <= 0 || img.t() <= 0 || img.r() != 1)
    return false;
  int comps = 0;
  switch (img.getPixelFormat()) {
    case GL_LUMINANCE:
      comps = 1;
      break;
    case GL_LUMINANCE_ALPHA:
      comps = 2;
      break;
    case GL_RGB:
      comps = 3;
      break;
    case GL_RGBA:
      comps = 4;
      break;
    default:
      return false;
  }
  out->width = uint32_t(img.s());
  out->height = uint32_t(img.t());
  out->rgba.resize(size_t(out->width) * out->height * 4);
  for (uint32_t y = 0; y < out->height; ++y) {
    uint32_t srcRow = img.getOrigin() == osg::Image::TOP_LEFT ? out->height - 1 - y : y;
    const uint8_t* src = img.data(0, int(srcRow));
    uint8_t* dst = out->rgba.data() + size_t(y) * out->width * 4;
    for (uint32_t x = 0; x < out->width; ++x, src += comps, dst += 4) {
      uint8_t l = src[0];
      dst[0] = comps >= 3 ? src[0] : l;
      dst[1] = comps >= 3 ? src[1] : l;
      dst[2] = comps >= 3 ? src[2] : l;
      dst[3] = comps == 4 ? src[3] : (comps == 2 ? src[1] : 255);
    }
  }
  out->repeat_s = repeats(tex.getWrap(osg::Texture::WRAP_S));
  out->repeat_t = repeats(tex.getWrap(osg::Texture::WRAP_T));
  return true;
}

// Geometries of fewer triangles get no part boxes.
constexpr uint64_t kMinPartTriangles = 16;

struct GeometryInfo {
  Vec3d center;   // local offset folded into each instance's transform
  Box3d box;      // bounds of the recentred positions
  double radius;  // around the box centre
  uint64_t triangles;
};

// One merged geode geometry as objects see it: one geometry, or the
// clusters it was split into (all recentred on the mesh's centre).
struct MeshInfo {
  std::vector<uint32_t> geometries;  // empty: nothing drawable
  Box3d box;                         // the whole mesh's recentred box
};

class SceneWriter {
 public:
  SceneWriter(const PreprocessOptions& opts, std::string tmp) : opts_(opts), tmp_(std::move(tmp)) {
    fs::create_directories(tmp_ + "/geometry");
    fs::create_directories(tmp_ + "/textures");
  }

  void traverse(const osg::Node* node, const Mat4d& world, InheritedState state, uint32_t parent);
  void finish(PreprocessStats* stats);
  // Inputs are traversed one at a time under one root group, so every
  // object has a skeleton path; each input's graph is released after its
  // traversal, and a later one may reuse its addresses: endInput forgets
  // the pointer-keyed maps, which hold no per-triangle data.
  uint32_t beginRoot() { return addNode(NodeKind::Group, kNone, kNone, "dmmr-root"); }
  void endInput(const std::string& file) {
    manifest_.inputs.push_back(fs::absolute(file).string());
    geometry_index_.clear();
    texture_index_.clear();
  }
  void endRoot(uint32_t root) { skeleton_[root].end = uint32_t(skeleton_.size()); }

 private:
  uint32_t addNode(NodeKind kind, uint32_t parent, uint32_t object, const std::string& name);
  void addObject(const osg::Node* node, const std::vector<const osg::Geometry*>& drawables,
                 const Mat4d& world, const InheritedState& state, uint32_t parent);
  const MeshInfo& meshFor(const osg::Node* key, const std::vector<const osg::Geometry*>& drawables,
                          const InheritedState& state);
  uint32_t addGeometry(GeometryData g, const Vec3d& center);
  uint32_t addObject(uint32_t geometry, const Mat4d& world, uint32_t parent,
                     const std::string& name);
  void appendDrawable(const osg::Geometry& geom, InheritedState state, GeometryData* g,
                      std::vector<double>* positions, const std::vector<bool>& attrs);
  int32_t textureFor(const osg::Texture2D* tex);
  void addLevelOfDetail(GeometryData* g);
  void writeFile(const std::string& name, const std::vector<uint8_t>& bytes);
  void progress(bool force = false);

  const PreprocessOptions& opts_;
  std::string tmp_;
  Manifest manifest_;
  std::vector<SkeletonNode> skeleton_;
  std::vector<ObjectBounds> objects_;
  std::vector<GeometryInfo> geometries_;
  std::vector<GeometryParts> parts_;  // per geometry
  std::map<std::tuple<const osg::Node*, const osg::Material*, const osg::Texture2D*>, MeshInfo>
      geometry_index_;
  Box3d scene_box_;  // of whole meshes: clustering leaves the default near plane as it was
  // Per image and wrap modes: two textures sharing an image may wrap
  // differently, and each texture file holds its wrap modes.
  std::map<std::tuple<const osg::Image*, bool, bool>, int32_t> texture_index_;
  PreprocessStats stats_;
  Clock::time_point start_ = Clock::now(), last_progress_ = Clock::now();
};

uint32_t SceneWriter::addNode(NodeKind kind, uint32_t parent, uint32_t object,
                              const std::string& name) {
  SkeletonNode n;
  n.kind = kind;
  n.parent = parent;
  n.object = object;
  n.name = name.size() > 4096 ? name.substr(0, 4096) : name;
  skeleton_.push_back(std::move(n));
  return uint32_t(skeleton_.size() - 1);
}

void SceneWriter::traverse(const osg::Node* node, const Mat4d& world, InheritedState state,
                           uint32_t parent) {
  state = applyStateSet(state, node->getStateSet());
  if (auto* bb = dynamic_cast<const osg::Billboard*>(node)) {
    // Each drawable at its own position. OSG turns it to face the eye every
    // frame; dmmr draws it as modelled (that turn depends on the view, and
    // objects here have one transform), so billboards are counted and warned.
    ++stats_.billboards;
    uint32_t self = addNode(NodeKind::Group, parent, kNone, node->getName());
    for (unsigned i = 0; i < bb->getNumDrawables(); ++i) {
      const osg::Drawable* d = bb->getDrawable(i);
      const osg::Vec3& p = bb->getPosition(i);
      if (const osg::Geometry* g = d->asGeometry())
        addObject(d, {g}, world * Mat4d::translate({p.x(), p.y(), p.z()}), state, self);
      else
        ++stats_.skipped_drawables;
    }
    skeleton_[self].end = uint32_t(skeleton_.size());
    return;
  }
  if (auto* geode = node->asGeode()) {
    std::vector<const osg::Geometry*> drawables;
    for (unsigned i = 0; i < geode->getNumDrawables(); ++i) {
      const osg::Geometry* g = geode->getDrawable(i)->asGeometry();
      if (g)
        drawables.push_back(g);
      else
        ++stats_.skipped_drawables;
    }
    addObject(node, drawables, world, state, parent);
    return;
  }
  if (auto* drawable = node->asDrawable()) {  // OSG 3.6 lets drawables sit in groups
    if (auto* g = drawable->asGeometry())
      addObject(node, {g}, world, state, parent);
    else
      ++stats_.skipped_drawables;
    return;
  }
  const osg::Group* group = node->asGroup();
  if (!group) return;
  Mat4d childWorld = world;
  NodeKind kind = NodeKind::Group;
  if (auto* t = node->asTransform()) {
    // ABSOLUTE_RF puts its subtree in the camera's frame (a HUD): OSG draws
    // it fixed on the screen, which no walkthrough of the model reproduces.
    // ABSOLUTE_RF_INHERIT_VIEWPOINT is world placement without the parents'.
    if (t->getReferenceFrame() == osg::Transform::ABSOLUTE_RF) {
      ++stats_.camera_fixed_subtrees;
      return;
    }
    osg::Matrixd local;  // identity; the transform composes its own matrix in
    t->computeLocalToWorldMatrix(local, nullptr);
    Mat4d m = Mat4d::fromOsgPtr(local.ptr());
    childWorld = t->getReferenceFrame() == osg::Transform::RELATIVE_RF ? world * m : m;
    kind = NodeKind::Transform;
  }
  uint32_t self = addNode(kind, parent, kNone, node->getName());
  auto* sw = dynamic_cast<const osg::Switch*>(node);
  auto* lod = dynamic_cast<const osg::LOD*>(node);
  // A PagedLOD's levels in files are paged in by a viewer as the camera
  // nears; the preprocessor takes the loaded children only, and says so.
  if (auto* paged = dynamic_cast<const osg::PagedLOD*>(node))
    for (unsigned i = paged->getNumChildren(); i < paged->getNumFileNames(); ++i)
      if (!paged->getFileName(i).empty()) ++stats_.unloaded_lod_files;
  // A LOD contributes its most detailed child (the one whose range starts
  // nearest); a Switch its enabled children.
  int lodChild = -1;
  if (lod && lod->getNumChildren() > 0) {
    lodChild = 0;
    for (unsigned i = 1; i < lod->getNumChildren() && i < lod->getNumRanges(); ++i)
      if (lod->getMinRange(i) < lod->getMinRange(unsigned(lodChild))) lodChild = int(i);
  }
  for (unsigned i = 0; i < group->getNumChildren(); ++i) {
    if (sw && !sw->getValue(i)) continue;
    if (lod && int(i) != lodChild) continue;
    traverse(group->getChild(i), childWorld, state, self);
  }
  skeleton_[self].end = uint32_t(skeleton_.size());
}

void SceneWriter::addObject(const osg::Node* node,
                            const std::vector<const osg::Geometry*>& drawables, const Mat4d& world,
                            const InheritedState& state, uint32_t parent) {
  const MeshInfo& mesh = meshFor(node, drawables, state);
  if (mesh.geometries.empty()) return;  // nothing drawable (no triangles)
  const Vec3d& center = geometries_[mesh.geometries[0]].center;
  scene_box_.expand(transformBox(world * Mat4d::translate(center), mesh.box));
  if (mesh.geometries.size() == 1) {
    addObject(mesh.geometries[0], world, parent, node->getName());
    return;
  }
  // A split mesh: one group holding its clusters, in the clusters' order.
  uint32_t group = addNode(NodeKind::Group, parent, kNone, node->getName());
  for (size_t k = 0; k < mesh.geometries.size(); ++k)
    addObject(mesh.geometries[k], world, group, "cluster " + std::to_string(k));
  skeleton_[group].end = uint32_t(skeleton_.size());
}

uint32_t SceneWriter::addObject(uint32_t gi, const Mat4d& world, uint32_t parent,
                                const std::string& name) {
  const GeometryInfo& info = geometries_[gi];
  ObjectBounds o;
  o.geometry = gi;
  o.transform = world * Mat4d::translate(info.center);
  o.box = transformBox(o.transform, info.box);
  o.sphere.center = o.transform.transformPoint(info.box.center());
  o.sphere.radius = info.radius * o.transform.maxScale();
  o.use_box = o.box.volume() <= o.sphere.volume();
  o.weight = info.triangles;
  uint32_t index = uint32_t(objects_.size());
  objects_.push_back(o);
  uint32_t self = addNode(NodeKind::Object, parent, index, name);
  skeleton_[self].end = self + 1;
  stats_.triangles += info.triangles;
  progress();
  return index;
}

// The cluster of `g` made of triangles `tris` (ascending): their corners in
// order, the vertices they use (compacted, values copied bit for bit) and
// the submeshes they fall in.
GeometryData extractCluster(const GeometryData& g, const std::vector<uint32_t>& tris) {
  GeometryData c;
  std::unordered_map<uint32_t, uint32_t> remap;
  remap.reserve(tris.size() * 2);
  size_t sm = 0, last = SIZE_MAX;  // the submesh of `t`, and of c.submeshes.back()
  for (uint32_t t : tris) {
    uint32_t first = 3 * t;
    while (first >= g.submeshes[sm].first_index + g.submeshes[sm].index_count) ++sm;
    if (sm != last) {
      last = sm;
      SubMesh s = g.submeshes[sm];
      s.first_index = uint32_t(c.indices.size());
      s.index_count = 0;
      c.submeshes.push_back(s);
    }
    for (uint32_t k = 0; k < 3; ++k) {
      uint32_t v = g.indices[first + k];
      auto [it, added] = remap.emplace(v, uint32_t(remap.size()));
      if (added) {
        c.positions.insert(c.positions.end(), &g.positions[3 * size_t(v)],
                           &g.positions[3 * size_t(v)] + 3);
        if (!g.normals.empty())
          c.normals.insert(c.normals.end(), &g.normals[3 * size_t(v)],
                           &g.normals[3 * size_t(v)] + 3);
        if (!g.colors.empty())
          c.colors.insert(c.colors.end(), &g.colors[4 * size_t(v)], &g.colors[4 * size_t(v)] + 4);
        if (!g.texcoords.empty())
          c.texcoords.insert(c.texcoords.end(), &g.texcoords[2 * size_t(v)],
                             &g.texcoords[2 * size_t(v)] + 2);
      }
      c.indices.push_back(it->second);
    }
    c.submeshes.back().index_count += 3;
  }
  return c;
}

const MeshInfo& SceneWriter::meshFor(const osg::Node* key,
                                     const std::vector<const osg::Geometry*>& drawables,
                                     const InheritedState& state) {
  auto k = std::make_tuple(key, state.material, state.texture);
  if (auto it = geometry_index_.find(k); it != geometry_index_.end()) return it->second;
  MeshInfo& mesh = geometry_index_[k];
  // Which optional attributes any drawable has: the merged geometry carries
  // an attribute only if at least one drawable does.
  std::vector<bool> attrs(3, false);
  for (const osg::Geometry* d : drawables) {
    size_t nv = d->getVertexArray() ? d->getVertexArray()->getNumElements() : 0;
    InheritedState s = applyStateSet(state, d->getStateSet());
    attrs[0] = attrs[0] || perVertex(d->getNormalArray(), nv);
    attrs[1] = attrs[1] || perVertex(d->getColorArray(), nv) || colorsPerPrimitiveSet(*d);
    attrs[2] = attrs[2] || (s.texture && perVertex(d->getTexCoordArray(0), nv));
  }
  GeometryData g;
  std::vector<double> pos;
  for (const osg::Geometry* d : drawables) appendDrawable(*d, state, &g, &pos, attrs);
  if (g.indices.empty()) return mesh;
  // Recentre on the box centre in double before converting to float, so a
  // model placed far from the origin keeps its precision. Clusters share
  // the mesh's centre, so their floats are the unsplit mesh's, bit for bit.
  Box3d box;
  for (size_t i = 0; i < pos.size(); i += 3) box.expand(Vec3d{pos[i], pos[i + 1], pos[i + 2]});
  Vec3d center = box.center();
  g.positions.resize(pos.size());
  for (size_t i = 0; i < pos.size(); ++i) g.positions[i] = float(pos[i] - center[int(i % 3)]);
  pos = {};
  for (size_t i = 0; i < g.positions.size(); i += 3)
    mesh.box.expand(Vec3d{g.positions[i], g.positions[i + 1], g.positions[i + 2]});
  if (opts_.cluster_triangles == 0 || g.triangleCount() <= opts_.cluster_triangles) {
    mesh.geometries.push_back(addGeometry(std::move(g), center));
    return mesh;
  }
  ++stats_.split_meshes;
  for (const auto& tris : clusterTriangles(g.positions.data(), g.vertexCount(), g.indices.data(),
                                           g.indices.size(), opts_.cluster_triangles))
    mesh.geometries.push_back(addGeometry(extractCluster(g, tris), center));
  return mesh;
}

// Writes `g` (positions already relative to `center`) as a new geometry.
uint32_t SceneWriter::addGeometry(GeometryData g, const Vec3d& center) {
  GeometryInfo info;
  info.center = center;
  auto at = [&](size_t i) { return Vec3d{g.positions[i], g.positions[i + 1], g.positions[i + 2]}; };
  for (size_t i = 0; i < g.positions.size(); i += 3) info.box.expand(at(i));
  double r2 = 0;
  for (size_t i = 0; i < g.positions.size(); i += 3) {
    Vec3d d = at(i) - info.box.center();
    r2 = std::max(r2, dot(d, d));
  }
  info.radius = std::sqrt(r2) * (1 + 1e-12);
  info.triangles = g.triangleCount();
  // Part boxes where a mesh has triangles enough to have a shape its box
  // misses (an elbow, a rotated run); below that the box is the test.
  // Each part's triangles are put together within every submesh, so that a
  // client can draw the parts that reach its region and not the others
  // (docs/scene-format.md, "Part boxes"); the reference draws the new order
  // too, so every renderer draws the same list.
  PartOrder parts;
  if (info.triangles >= kMinPartTriangles) {
    std::vector<uint32_t> submesh_triangles;
    for (const SubMesh& s : g.submeshes) submesh_triangles.push_back(s.index_count / 3);
    parts = orderByParts(g.positions.data(), g.vertexCount(), g.indices.data(), g.indices.size(),
                         submesh_triangles, kMaxParts);
    if (opts_.part_order) {
      std::vector<uint32_t> reordered(g.indices.size());
      for (size_t t = 0; t < parts.order.size(); ++t)
        std::copy_n(g.indices.data() + 3 * size_t(parts.order[t]), 3, reordered.data() + 3 * t);
      g.indices = std::move(reordered);
    } else {
      parts.triangles.clear();
    }
  }
  parts_.push_back(quantizeParts(info.box, parts.boxes));
  parts_.back().triangles = std::move(parts.triangles);
  addLevelOfDetail(&g);
  uint32_t index = uint32_t(geometries_.size());
  geometries_.push_back(info);
  writeFile(geometryFileName(index), encodeGeometry(g, opts_.encoding));
  stats_.unique_triangles += info.triangles;
  return index;
}

// Appends one drawable's triangles to `g`. Positions go to `positions` in
// double; the caller recentres them before they become float.
void SceneWriter::appendDrawable(const osg::Geometry& geom, InheritedState state, GeometryData* g,
                                 std::vector<double>* positions, const std::vector<bool>& attrs) {
  state = applyStateSet(state, geom.getStateSet());
  const osg::Array* verts = geom.getVertexArray();
  if (!verts || verts->getNumElements() == 0) return;
  size_t nv = verts->getNumElements();
  Vec3d probe;
  if (!readVec3(verts, 0, &probe)) {
    ++stats_.skipped_drawables;  // 2D or 4D vertex arrays: not taken
    return;
  }
  std::vector<uint32_t> tris;
  osg::TriangleIndexFunctor<TriangleCollector> f;
  f.out = &tris;
  // With colours per primitive set, set by set: set_end[k] is where set k's
  // triangles end in `tris`.
  const bool per_set = colorsPerPrimitiveSet(geom);
  std::vector<size_t> set_end;
  if (per_set) {
    for (unsigned k = 0; k < geom.getNumPrimitiveSets(); ++k) {
      geom.getPrimitiveSet(k)->accept(f);
      set_end.push_back(tris.size());
    }
  } else {
    geom.accept(f);
  }
  if (tris.empty()) return;

  std::vector<uint8_t> finite(nv);
  for (size_t i = 0; i < nv; ++i) {
    Vec3d p;
    readVec3(verts, i, &p);
    finite[i] = isFinite(p) && std::isfinite(float(p.x)) && std::isfinite(float(p.y)) &&
                std::isfinite(float(p.z));
    if (!finite[i]) ++stats_.nonfinite_vertices;
  }
  // Compact to the referenced, finite vertices; renumber indices.
  std::vector<uint32_t> remap(nv, kNone);
  const osg::Array* normals =
      perVertex(geom.getNormalArray(), nv) ? geom.getNormalArray() : nullptr;
  const osg::Array* colors =
      perVertex(geom.getColorArray(), nv) || per_set ? geom.getColorArray() : nullptr;
  size_t set = 0;                // the primitive set of triangle t (per_set)
  std::vector<uint32_t> mapped;  // vertices remapped in this set, to forget at the next
  auto* uv = dynamic_cast<const osg::Vec2Array*>(geom.getTexCoordArray(0));
  if (!state.texture || !perVertex(uv, nv)) uv = nullptr;
  uint32_t firstIndex = uint32_t(g->indices.size());
  for (size_t t = 0; t + 2 < tris.size(); t += 3) {
    if (per_set && t >= set_end[set]) {
      while (t >= set_end[set]) ++set;
      for (uint32_t src : mapped) remap[src] = kNone;
      mapped.clear();
    }
    uint32_t v[3] = {tris[t], tris[t + 1], tris[t + 2]};
    if (v[0] >= nv || v[1] >= nv || v[2] >= nv) {
      ++stats_.bad_index_triangles;
      continue;
    }
    if (!finite[v[0]] || !finite[v[1]] || !finite[v[2]]) {
      ++stats_.dropped_triangles;
      continue;
    }
    // Corners that coincide (one vertex twice, or two at one position) make
    // a triangle that covers no pixel: dropping it changes no image.
    // Collinear corners are kept: in float, after the transform, they may
    // cover a sliver.
    Vec3d p[3];
    for (int k = 0; k < 3; ++k) readVec3(verts, v[k], &p[k]);
    if (p[0] == p[1] || p[1] == p[2] || p[0] == p[2]) {
      ++stats_.degenerate_triangles;
      continue;
    }
    for (uint32_t src : v) {
      if (remap[src] == kNone) {
        remap[src] = uint32_t(positions->size() / 3);
        if (per_set) mapped.push_back(src);
        Vec3d p;
        readVec3(verts, src, &p);
        positions->insert(positions->end(), {p.x, p.y, p.z});
        if (attrs[0]) {
          Vec3d n{0, 0, 0};
          if (normals) readVec3(normals, src, &n);
          g->normals.insert(g->normals.end(), {float(n.x), float(n.y), float(n.z)});
        }
        if (attrs[1]) {
          uint8_t c[4] = {255, 255, 255, 255};
          if (colors) readColor(colors, per_set ? set : src, c);
          g->colors.insert(g->colors.end(), c, c + 4);
        }
        if (attrs[2]) {
          osg::Vec2 tc = uv ? (*uv)[src] : osg::Vec2(0, 0);
          g->texcoords.insert(g->texcoords.end(), {tc.x(), tc.y()});
        }
      }
      g->indices.push_back(remap[src]);
    }
  }
  SubMesh sm;
  sm.first_index = firstIndex;
  sm.index_count = uint32_t(g->indices.size()) - firstIndex;
  if (sm.index_count == 0) return;
  osg::Vec4 diffuse(0.8f, 0.8f, 0.8f, 1.f);
  if (state.material)
    diffuse = state.material->getDiffuse(osg::Material::FRONT);
  else if (geom.getColorArray() && geom.getColorArray()->getBinding() == osg::Array::BIND_OVERALL) {
    uint8_t c[4];
    if (readColor(geom.getColorArray(), 0, c))
      diffuse = osg::Vec4(c[0] / 255.f, c[1] / 255.f, c[2] / 255.f, c[3] / 255.f);
  }
  for (int k = 0; k < 4; ++k) sm.diffuse[k] = diffuse[k];
  sm.texture = uv ? textureFor(state.texture) : -1;
  g->submeshes.push_back(sm);
}

void SceneWriter::addLevelOfDetail(GeometryData* g) {
  if (opts_.lod_ratio <= 0 || g->triangleCount() < opts_.lod_min_triangles) return;
  size_t target = std::max<size_t>(3, size_t(double(g->indices.size()) * opts_.lod_ratio) / 3 * 3);
  std::vector<uint32_t> lod(g->indices.size());
  size_t n = meshopt_simplify(lod.data(), g->indices.data(), g->indices.size(), g->positions.data(),
                              g->vertexCount(), 3 * sizeof(float), target, float(opts_.lod_error));
  if (n == 0 || n * 4 > g->indices.size() * 3) return;  // saves less than a quarter
  lod.resize(n);
  g->lod_indices = std::move(lod);
  ++stats_.lod_geometries;
  stats_.lod_triangles += n / 3;
}

int32_t SceneWriter::textureFor(const osg::Texture2D* tex) {
  const osg::Image* img = tex->getImage();
  if (!img) return -1;
  const auto key = std::make_tuple(img, repeats(tex->getWrap(osg::Texture::WRAP_S)),
                                   repeats(tex->getWrap(osg::Texture::WRAP_T)));
  if (auto it = texture_index_.find(key); it != texture_index_.end()) return it->second;
  TextureData t;
  int32_t index = -1;
  if (convertImage(*img, *tex, &t)) {
    index = int32_t(manifest_.textures++);
    writeFile(textureFileName(uint32_t(index)), encodeTexture(t));
  } else {
    std::fprintf(stderr,
                 "dmmr-preprocess: warning: texture %s has an unsupported pixel format; "
                 "left off\n",
                 img->getFileName().c_str());
  }
  texture_index_[key] = index;
  return index;
}

void SceneWriter::writeFile(const std::string& name, const std::vector<uint8_t>& bytes) {
  std::string path = tmp_ + "/" + name;
  std::ofstream f(path, std::ios::binary);
  if (!f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size())) ||
      !f.flush())
    throw Error(fileError(path, "write failed (disk full?)"));
  manifest_.files[name] = {bytes.size(), manifestCrc(bytes)};
  stats_.bytes_written += bytes.size();
}

void SceneWriter::progress(bool force) {
  if (!opts_.progress) return;
  auto now = Clock::now();
  if (!force && now - last_progress_ < std::chrono::seconds(1)) return;
  last_progress_ = now;
  double s = std::chrono::duration<double>(now - start_).count();
  std::fprintf(stderr, "\rdmmr-preprocess: %zu objects, %zu geometries, %.1fM triangles, %.1f s",
               objects_.size(), geometries_.size(), double(stats_.triangles) / 1e6, s);
}

void SceneWriter::finish(PreprocessStats* stats) {
  progress(true);
  if (opts_.progress) std::fprintf(stderr, "\n");
  if (objects_.empty())
    throw Error(fileError(opts_.inputs.front(), "model has no triangles to render"));
  // Subtree boxes, children before parents (reverse pre-order).
  for (size_t i = skeleton_.size(); i-- > 0;) {
    SkeletonNode& n = skeleton_[i];
    if (n.kind == NodeKind::Object) n.box = objects_[n.object].box;
    if (n.parent != kNone) skeleton_[n.parent].box.expand(n.box);
  }
  std::vector<uint32_t> occluders =
      selectOccluders(objects_, opts_.occluder_area_percentile, opts_.occluder_max_triangles);
  manifest_.geometry_bytes = stats_.bytes_written;
  writeFile("skeleton.bin", encodeSkeleton(skeleton_));
  writeFile("bounds.bin", encodeBounds(objects_));
  writeFile("occluders.bin", encodeOccluders(occluders));
  writeFile("parts.bin", encodeParts(parts_));
  manifest_.objects = objects_.size();
  manifest_.geometries = geometries_.size();
  manifest_.occluders = occluders.size();
  manifest_.triangles = stats_.triangles;
  manifest_.unique_triangles = stats_.unique_triangles;
  manifest_.bounds = scene_box_;
  manifest_.encoding = opts_.encoding;
  writeFileAtomic(tmp_ + "/manifest.json", encodeManifest(manifest_));
  stats_.objects = objects_.size();
  stats_.geometries = geometries_.size();
  stats_.textures = manifest_.textures;
  stats_.occluders = occluders.size();
  *stats = stats_;
}

// Inputs as files: a directory stands for every model file (modelReaderFor)
// in it and its subdirectories, sorted by path so the scene does not depend
// on the order the file system lists them; hidden entries are skipped.
// `roots` (one per file): the directory a file's references must stay in,
// the directory input it was found under ("" for a file given itself: its
// own directory), so that a model may name files elsewhere in the tree the
// user gave (an OBJ in obj/ naming ../textures/t.png).
std::vector<std::string> expandInputs(const std::vector<std::string>& inputs,
                                      std::vector<std::string>* roots) {
  std::vector<std::string> files;
  for (const auto& in : inputs) {
    std::error_code ec;
    if (!fs::exists(in, ec)) throw Error(fileError(in, "no such file"));
    if (!fs::is_directory(in, ec)) {
      files.push_back(in);
      roots->push_back("");
      continue;
    }
    std::vector<std::string> found;
    try {
      for (auto it = fs::recursive_directory_iterator(in); it != fs::recursive_directory_iterator();
           ++it) {
        std::string name = it->path().filename().string();
        if (name.empty() || name[0] == '.') {
          if (it->is_directory()) it.disable_recursion_pending();
          continue;
        }
        if (it->is_regular_file() && modelReaderFor(name) != ModelReader::None)
          found.push_back(it->path().string());
      }
    } catch (const fs::filesystem_error& e) {
      throw Error(fileError(e.path1().empty() ? in : e.path1().string(),
                            "cannot list directory: " + e.code().message()));
    }
    if (found.empty())
      throw Error(fileError(in,
                            "directory holds no model file (OBJ, PLY, OSGB, glTF, FBX, ...; "
                            "see docs/scene-format.md)"));
    std::sort(found.begin(), found.end());
    files.insert(files.end(), found.begin(), found.end());
    roots->insert(roots->end(), found.size(), in);
  }
  return files;
}

// A third-party reader (an OSG plugin, assimp) that crashes on a malformed
// file would end the run with a bare signal. While one reads, a fatal signal
// prints which file it was reading and exits 1 instead. The partial scene
// directory cannot be removed safely from a signal handler; the next run
// removes it (removeStalePartials). Only async-signal-safe calls in the
// handler: the message is composed before the read.
class ReaderCrashGuard {
 public:
  ReaderCrashGuard(const std::string& file, const fs::path& partial) {
    std::string m = "dmmr-preprocess: " + file +
                    ": the reader of this format crashed on it (a malformed file, or a bug in "
                    "the reader); nothing was written to the scene (" +
                    partial.string() + " is removed by the next run)\n";
    size_t n = std::min(m.size(), sizeof(message_) - 1);
    std::memcpy(message_, m.data(), n);
    message_size_ = n;
    struct sigaction sa {};
    sa.sa_handler = &ReaderCrashGuard::onSignal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND | SA_ONSTACK;
    for (size_t i = 0; i < kSignals.size(); ++i) sigaction(kSignals[i], &sa, &previous_[i]);
  }
  ~ReaderCrashGuard() {
    for (size_t i = 0; i < kSignals.size(); ++i) sigaction(kSignals[i], &previous_[i], nullptr);
  }
  ReaderCrashGuard(const ReaderCrashGuard&) = delete;
  ReaderCrashGuard& operator=(const ReaderCrashGuard&) = delete;

 private:
  static void onSignal(int) {
    ssize_t ignored = ::write(2, message_, message_size_);
    (void)ignored;
    ::_exit(1);
  }
  static constexpr std::array<int, 4> kSignals = {SIGSEGV, SIGBUS, SIGFPE, SIGILL};
  static inline char message_[8192];
  static inline size_t message_size_ = 0;
  std::array<struct sigaction, 4> previous_{};
};

// Test hook: DMMR_INJECT_FAULT=preprocess-read-crash makes the read of every
// input crash, as a reader's bug would (preprocess_test).
void injectReadCrash() {
  const char* spec = std::getenv("DMMR_INJECT_FAULT");
  if (spec && std::strcmp(spec, "preprocess-read-crash") == 0) ::raise(SIGSEGV);
}

// When process `pid` started, in clock ticks since boot (/proc/PID/stat's
// 22nd field), or 0 when unknown. With the PID it names a process for good:
// a PID is reused, a PID and its start time are not (until a reboot, which
// ends every run anyway).
uint64_t processStartTicks(long pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  size_t paren = stat.rfind(')');  // the command name may hold spaces and parentheses
  if (paren == std::string::npos) return 0;
  std::istringstream fields(stat.substr(paren + 1));
  std::string field;
  for (int k = 3; k <= 22 && fields >> field; ++k)
    if (k == 22) return std::strtoull(field.c_str(), nullptr, 10);
  return 0;
}

}  // namespace

std::string partialSuffix(long pid) {
  return ".partial-" + std::to_string(pid) + "-" + std::to_string(processStartTicks(pid));
}

// Partial scene directories of `out` (OUT.partial-PID-START, or
// OUT.partial-PID from older runs) whose process is gone, or whose PID now
// belongs to a process that started at another time: left by a run that was
// killed or whose reader crashed.
void removeStalePartials(const fs::path& out) {
  std::error_code ec;
  fs::path dir = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  const std::string prefix = out.filename().string() + ".partial-";
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    char* end = nullptr;
    long pid = std::strtol(name.c_str() + prefix.size(), &end, 10);
    if (pid <= 0) continue;
    uint64_t start = 0;  // 0: not in the name (an older run) or unknown to it
    if (*end == '-') {
      char* end2 = nullptr;
      start = std::strtoull(end + 1, &end2, 10);
      if (end2 == end + 1 || *end2 != '\0') continue;
    } else if (*end != '\0') {
      continue;
    }
    bool gone = ::kill(pid_t(pid), 0) == -1 && errno == ESRCH;
    uint64_t now = gone ? 0 : processStartTicks(pid);
    if (gone || (start != 0 && now != 0 && now != start)) fs::remove_all(e.path(), ec);
  }
}

namespace {

osg::ref_ptr<osg::Node> readModel(const std::string& path) {
  if (!fs::exists(path)) throw Error(fileError(path, "no such file"));
  if (fs::is_directory(path)) throw Error(fileError(path, "is a directory, not a model"));
  if (modelReaderFor(path) == ModelReader::Assimp) return readWithAssimp(path);
  if (modelReaderFor(path) == ModelReader::Ply) return readPly(path);
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (ext == ".obj") {
    std::ifstream in(path);
    checkObjIndices(in, path);
  }
  osg::ref_ptr<osg::Node> node = osgDB::readRefNodeFile(path);
  if (!node)
    throw Error(fileError(path,
                          "OpenSceneGraph cannot read this model (unknown format "
                          "or corrupt file)"));
  return node;
}

}  // namespace

std::vector<uint32_t> selectOccluders(const std::vector<ObjectBounds>& objects,
                                      double area_percentile, uint64_t max_triangles) {
  if (objects.empty()) return {};
  auto faceArea = [](const ObjectBounds& o) {
    Vec3d e = o.box.extent();
    return std::max({e.x * e.y, e.y * e.z, e.x * e.z});
  };
  std::vector<double> areas;
  areas.reserve(objects.size());
  for (const auto& o : objects) areas.push_back(faceArea(o));
  std::vector<double> sorted = areas;
  size_t k = std::min(sorted.size() - 1, size_t(std::clamp(area_percentile, 0.0, 100.0) / 100.0 *
                                                double(sorted.size())));
  std::nth_element(sorted.begin(), sorted.begin() + long(k), sorted.end());
  double threshold = sorted[k];
  std::vector<uint32_t> out;
  for (size_t i = 0; i < objects.size(); ++i)
    if (areas[i] >= threshold && areas[i] > 0 && objects[i].weight <= max_triangles)
      out.push_back(uint32_t(i));
  return out;
}

PreprocessStats preprocess(const PreprocessOptions& opts) {
  if (opts.inputs.empty()) throw Error("no input models given");
  if (opts.out.empty()) throw Error("no output directory given");
  fs::path out = fs::path(opts.out).lexically_normal();
  if (out.filename().empty()) out = out.parent_path();
  // symlink_status: a dangling link is there too (renaming onto it at the
  // end failed after all the work).
  if (fs::symlink_status(out).type() != fs::file_type::not_found)
    throw Error(fileError(out.string(), "output already exists; remove it or choose another"));
  auto t0 = Clock::now();  // reading the models counts toward throughput
  std::vector<std::string> roots;
  std::vector<std::string> files = expandInputs(opts.inputs, &roots);

  fs::path tmp = out;
  tmp += partialSuffix(::getpid());
  fs::remove_all(tmp);
  removeStalePartials(out);
  PreprocessStats stats;
  uint64_t skipped = 0;
  try {
    SceneWriter w(opts, tmp.string());
    PluginGuard guard;  // models from strangers load only allowed formats
    // One input in memory at a time: read, traverse, release. Peak memory
    // is the largest input plus the writer's per-object metadata.
    uint32_t root = w.beginRoot();
    for (size_t k = 0; k < files.size(); ++k) {
      const std::string& file = files[k];
      osg::ref_ptr<osg::Node> model;
      try {
        ReaderCrashGuard crash_guard(file, tmp);
        injectReadCrash();
        guard.confineTo(file, roots[k]);
        model = readModel(file);
      } catch (const Error& e) {
        if (!opts.skip_unreadable) throw;
        std::fprintf(stderr, "dmmr-preprocess: warning: skipped %s\n", e.what());
        ++skipped;
        continue;
      }
      w.traverse(model.get(), Mat4d::identity(), {}, root);
      model = nullptr;
      w.endInput(file);
    }
    w.endRoot(root);
    if (skipped == files.size())
      throw Error("every input was skipped as unreadable (" + std::to_string(skipped) +
                  "): nothing to preprocess");
    w.finish(&stats);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  std::error_code ec;
  fs::rename(tmp, out, ec);
  if (ec) {
    fs::remove_all(tmp, ec);
    throw Error(fileError(out.string(), "cannot move the finished scene into place"));
  }
  stats.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  stats.inputs = files.size() - skipped;
  stats.skipped_inputs = skipped;
  return stats;
}

}  // namespace dmmr
