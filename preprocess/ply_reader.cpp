#include <cstdio>
#include <filesystem>
#include <fstream>

#include <osg/Geode>
#include <osg/Geometry>
#include <osg/Texture2D>
#include <osgDB/ReadFile>
#include <osgUtil/SmoothingVisitor>

#include "assimp_reader.h"  // resolveReference
#include "error.h"
#include "ply_reader.h"

namespace dmmr {

namespace fs = std::filesystem;

osg::ref_ptr<osg::Node> readPly(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(fileError(path, "cannot open for reading"));
  std::error_code ec;
  uint64_t size = fs::file_size(path, ec);
  PlyMesh m = parsePly(f, path, ec ? 0 : size);
  if (f.bad()) throw Error(fileError(path, "read error"));

  const size_t nv = m.positions.size() / 3;
  osg::ref_ptr<osg::Geometry> geom = new osg::Geometry;
  auto* verts = new osg::Vec3Array(unsigned(nv));
  for (size_t i = 0; i < nv; ++i)
    (*verts)[unsigned(i)].set(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
  geom->setVertexArray(verts);
  bool faces = false;
  for (auto [list, mode] : {std::pair{&m.triangles, osg::PrimitiveSet::TRIANGLES},
                            {&m.quads, osg::PrimitiveSet::QUADS}}) {
    if (list->empty()) continue;
    auto* de = new osg::DrawElementsUInt(mode, list->begin(), list->end());
    geom->addPrimitiveSet(de);
    faces = true;
  }
  if (!faces) geom->addPrimitiveSet(new osg::DrawArrays(GL_POINTS, 0, int(nv)));
  if (!m.colors.empty()) {
    auto* c = new osg::Vec4Array(unsigned(nv));
    for (size_t i = 0; i < nv; ++i)
      (*c)[unsigned(i)].set(m.colors[4 * i], m.colors[4 * i + 1], m.colors[4 * i + 2],
                            m.colors[4 * i + 3]);
    geom->setColorArray(c, osg::Array::BIND_PER_VERTEX);
  }
  if (!m.normals.empty()) {
    auto* n = new osg::Vec3Array(unsigned(nv));
    for (size_t i = 0; i < nv; ++i)
      (*n)[unsigned(i)].set(m.normals[3 * i], m.normals[3 * i + 1], m.normals[3 * i + 2]);
    geom->setNormalArray(n, osg::Array::BIND_PER_VERTEX);
  }
  if (!m.uv.empty()) {
    auto* t = new osg::Vec2Array(unsigned(nv));
    for (size_t i = 0; i < nv; ++i) (*t)[unsigned(i)].set(m.uv[2 * i], m.uv[2 * i + 1]);
    geom->setTexCoordArray(0, t, osg::Array::BIND_PER_VERTEX);
    if (!m.texture_file.empty()) {
      // Only from the model's directory or below, as for glTF's textures.
      fs::path parent = fs::path(path).parent_path();
      const std::string dir = parent.empty() ? std::string(".") : parent.string();
      std::string resolved, why;
      osg::ref_ptr<osg::Image> image;
      if (resolveReference(dir, m.texture_file, &resolved, &why))
        image = osgDB::readRefImageFile(resolved);
      else
        std::fprintf(stderr, "dmmr-preprocess: warning: %s: texture '%s': %s\n", path.c_str(),
                     m.texture_file.c_str(), why.c_str());
      if (image) {
        auto* tex = new osg::Texture2D(image.get());
        geom->getOrCreateStateSet()->setTextureAttributeAndModes(0, tex);
      } else if (why.empty()) {
        std::fprintf(stderr, "dmmr-preprocess: warning: %s: texture '%s' cannot be read\n",
                     path.c_str(), m.texture_file.c_str());
      }
    }
  }
  // No normals: the ones OSG's plugin made (quads become triangles there).
  if (m.normals.empty() && faces) osgUtil::SmoothingVisitor::smooth(*geom, osg::PI / 2);
  osg::ref_ptr<osg::Geode> geode = new osg::Geode;
  geode->addDrawable(geom.get());
  return geode;
}

}  // namespace dmmr
