#include "assimp_reader.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include <assimp/DefaultIOSystem.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/Importer.hpp>
#include <nlohmann/json.hpp>
#include <osg/Geode>
#include <osg/Geometry>
#include <osg/Material>
#include <osg/MatrixTransform>
#include <osg/Texture2D>
#include <osgDB/ReadFile>
#include <osgDB/Registry>

#include "error.h"
#include "plugin_guard.h"

namespace fs = std::filesystem;

namespace dmmr {

namespace {

bool hasScheme(const std::string& ref) {
  size_t colon = ref.find(':');
  if (colon == std::string::npos || colon < 2) return false;  // "C:" is a drive, checked below
  return std::all_of(ref.begin(), ref.begin() + long(colon), [](unsigned char c) {
    return std::isalnum(c) || c == '+' || c == '-' || c == '.';
  });
}

// True when `p` (absolute, normalised) lies in `root` or below.
bool inside(const fs::path& root, const fs::path& p) {
  auto r = root.begin(), q = p.begin();
  for (; r != root.end(); ++r, ++q) {
    if (r->empty()) continue;  // a trailing separator
    if (q == p.end() || *r != *q) return false;
  }
  return true;
}

fs::path canonicalOf(const fs::path& p) {
  std::error_code ec;
  fs::path c = fs::weakly_canonical(fs::absolute(p), ec);
  return ec ? fs::absolute(p).lexically_normal() : c;
}

// assimp's file access for one model: files in the model's directory or
// below, read only. A refusal or a missing file is remembered, so the error
// can name the file instead of assimp's generic message.
class ConfinedIOSystem : public Assimp::DefaultIOSystem {
 public:
  explicit ConfinedIOSystem(fs::path root) : root_(std::move(root)) {}
  bool Exists(const char* file) const override {
    return allowed(file) && Assimp::DefaultIOSystem::Exists(file);
  }
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    if (std::strpbrk(mode, "wa+")) {
      note(file, "the preprocessor writes no files through assimp");
      return nullptr;
    }
    if (!allowed(file)) {
      note(file, "outside the model's directory " + root_.string());
      return nullptr;
    }
    Assimp::IOStream* s = Assimp::DefaultIOSystem::Open(file, mode);
    if (!s) note(file, "no such file, or unreadable");
    return s;
  }
  const std::string& problem() const { return problem_; }

 private:
  bool allowed(const char* file) const { return inside(root_, canonicalOf(file)); }
  void note(const char* file, const std::string& why) {
    if (problem_.empty()) problem_ = "'" + std::string(file) + "': " + why;
  }
  fs::path root_;
  std::string problem_;
};

// The URIs of a glTF's buffers and images (`buffers[i].uri`,
// `images[i].uri`; not those in extras), read with a SAX parser so a large
// embedded data: URI is not held twice. A malformed file yields what was
// seen; assimp then reports the error.
std::vector<std::string> gltfUris(const std::string& path) {
  struct Sax : nlohmann::json_sax<nlohmann::json> {
    std::vector<std::string> uris;
    int depth = 0;  // 1 inside the top-level object, 3 inside an element of its arrays
    bool files = false, uriKey = false;
    bool value() {
      uriKey = false;
      return true;
    }
    bool null() override { return value(); }
    bool boolean(bool) override { return value(); }
    bool number_integer(number_integer_t) override { return value(); }
    bool number_unsigned(number_unsigned_t) override { return value(); }
    bool number_float(number_float_t, const string_t&) override { return value(); }
    bool string(string_t& s) override {
      if (uriKey) uris.push_back(s);
      return value();
    }
    bool binary(binary_t&) override { return value(); }
    bool start_object(std::size_t) override {
      ++depth;
      return value();
    }
    bool key(string_t& k) override {
      if (depth == 1) files = k == "buffers" || k == "images";
      uriKey = depth == 3 && files && k == "uri";
      return true;
    }
    bool end_object() override {
      --depth;
      return value();
    }
    bool start_array(std::size_t) override {
      ++depth;
      return value();
    }
    bool end_array() override {
      --depth;
      return value();
    }
    bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
      return false;
    }
  } sax;
  std::ifstream in(path, std::ios::binary);
  try {
    nlohmann::json::sax_parse(in, &sax);
  } catch (const std::exception&) {
  }
  return sax.uris;
}

osg::Matrixd toOsg(const aiMatrix4x4& m) {
  // assimp: row-major, column vectors; OSG: row vectors. Transpose.
  return osg::Matrixd(m.a1, m.b1, m.c1, m.d1, m.a2, m.b2, m.c2, m.d2, m.a3, m.b3, m.c3, m.d3, m.a4,
                      m.b4, m.c4, m.d4);
}

class Converter {
 public:
  Converter(const aiScene& scene, std::string model)
      : scene_(scene), model_(std::move(model)), dir_(canonicalOf(model_).parent_path()) {
    geometries_.resize(scene.mNumMeshes);
    built_.resize(scene.mNumMeshes, false);
    states_.resize(scene.mNumMaterials);
  }

  osg::ref_ptr<osg::Node> convert() {
    // assimp's convention is Y up; dmmr's (and OSG's OBJ reader's) Z up.
    osg::ref_ptr<osg::MatrixTransform> root =
        new osg::MatrixTransform(osg::Matrixd(1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1));
    root->setName(fs::path(model_).filename().string());
    if (osg::ref_ptr<osg::Node> n = node(scene_.mRootNode, 0)) root->addChild(n);
    return root;
  }

 private:
  osg::ref_ptr<osg::Node> node(const aiNode* n, int depth) {
    if (!n) return nullptr;
    // The SceneWriter recurses as deep as the graph; a hostile file must
    // not overflow the stack.
    if (depth > 1000) throw Error(fileError(model_, "node hierarchy deeper than 1000 levels"));
    osg::ref_ptr<osg::Group> g;
    if (n->mTransformation.IsIdentity())
      g = new osg::Group;
    else
      g = new osg::MatrixTransform(toOsg(n->mTransformation));
    g->setName(n->mName.C_Str());
    if (osg::ref_ptr<osg::Geode> geode = geodeFor(n)) g->addChild(geode);
    for (unsigned i = 0; i < n->mNumChildren; ++i)
      if (osg::ref_ptr<osg::Node> c = node(n->mChildren[i], depth + 1)) g->addChild(c);
    return g->getNumChildren() ? g : nullptr;
  }

  osg::ref_ptr<osg::Geode> geodeFor(const aiNode* n) {
    if (n->mNumMeshes == 0 || !n->mMeshes) return nullptr;
    std::vector<unsigned> meshes;
    for (unsigned i = 0; i < n->mNumMeshes; ++i) meshes.push_back(n->mMeshes[i]);
    if (auto it = geodes_.find(meshes); it != geodes_.end()) return it->second;
    osg::ref_ptr<osg::Geode> geode = new osg::Geode;
    geode->setName(n->mName.C_Str());
    for (unsigned m : meshes)
      if (osg::Geometry* g = geometry(m)) geode->addDrawable(g);
    if (!geode->getNumDrawables()) geode = nullptr;
    geodes_[meshes] = geode;
    return geode;
  }

  osg::Geometry* geometry(unsigned index) {
    if (index >= scene_.mNumMeshes) return nullptr;
    if (built_[index]) return geometries_[index].get();
    built_[index] = true;
    const aiMesh& m = *scene_.mMeshes[index];
    auto* idx = new osg::DrawElementsUInt(GL_TRIANGLES);
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
      const aiFace& face = m.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines are not drawn
      for (int k = 0; k < 3; ++k) idx->push_back(face.mIndices[k]);
    }
    if (idx->empty() || m.mNumVertices == 0) {
      idx->unref();
      return nullptr;
    }
    osg::ref_ptr<osg::Geometry> g = new osg::Geometry;
    g->setName(m.mName.C_Str());
    auto* v = new osg::Vec3Array(m.mNumVertices);
    for (unsigned i = 0; i < m.mNumVertices; ++i)
      (*v)[i].set(m.mVertices[i].x, m.mVertices[i].y, m.mVertices[i].z);
    g->setVertexArray(v);
    if (m.mNormals) {
      auto* a = new osg::Vec3Array(m.mNumVertices);
      for (unsigned i = 0; i < m.mNumVertices; ++i)
        (*a)[i].set(m.mNormals[i].x, m.mNormals[i].y, m.mNormals[i].z);
      g->setNormalArray(a, osg::Array::BIND_PER_VERTEX);
    }
    if (m.mColors[0]) {
      auto* a = new osg::Vec4Array(m.mNumVertices);
      for (unsigned i = 0; i < m.mNumVertices; ++i) {
        const aiColor4D& c = m.mColors[0][i];
        (*a)[i].set(c.r, c.g, c.b, c.a);
      }
      g->setColorArray(a, osg::Array::BIND_PER_VERTEX);
    }
    unsigned uvChannel = 0;
    if (m.mMaterialIndex < scene_.mNumMaterials) {
      g->setStateSet(stateFor(m.mMaterialIndex, &uvChannel));
      if (uvChannel < AI_MAX_NUMBER_OF_TEXTURECOORDS && m.mTextureCoords[uvChannel]) {
        auto* a = new osg::Vec2Array(m.mNumVertices);
        for (unsigned i = 0; i < m.mNumVertices; ++i)
          (*a)[i].set(m.mTextureCoords[uvChannel][i].x, m.mTextureCoords[uvChannel][i].y);
        g->setTexCoordArray(0, a, osg::Array::BIND_PER_VERTEX);
      }
    }
    g->addPrimitiveSet(idx);
    geometries_[index] = g;
    return g.get();
  }

  osg::StateSet* stateFor(unsigned index, unsigned* uvChannel) {
    if (states_[index]) {
      *uvChannel = uv_[index];
      return states_[index].get();
    }
    const aiMaterial* mat = scene_.mMaterials[index];
    osg::ref_ptr<osg::StateSet> ss = new osg::StateSet;
    aiColor4D c;
    if (aiGetMaterialColor(mat, AI_MATKEY_BASE_COLOR, &c) == AI_SUCCESS ||
        aiGetMaterialColor(mat, AI_MATKEY_COLOR_DIFFUSE, &c) == AI_SUCCESS) {
      auto* m = new osg::Material;
      m->setDiffuse(osg::Material::FRONT_AND_BACK, osg::Vec4(c.r, c.g, c.b, c.a));
      ss->setAttribute(m);
    }
    unsigned uv = 0;
    for (aiTextureType type : {aiTextureType_DIFFUSE, aiTextureType_BASE_COLOR}) {
      aiString path;
      aiTextureMapMode mode[2] = {aiTextureMapMode_Wrap, aiTextureMapMode_Wrap};
      if (mat->GetTexture(type, 0, &path, nullptr, &uv, nullptr, nullptr, mode) != AI_SUCCESS)
        continue;
      if (osg::ref_ptr<osg::Image> img = image(path.C_Str())) {
        auto* t = new osg::Texture2D(img.get());
        auto wrap = [](aiTextureMapMode m) {
          return m == aiTextureMapMode_Wrap     ? osg::Texture::REPEAT
                 : m == aiTextureMapMode_Mirror ? osg::Texture::MIRROR
                                                : osg::Texture::CLAMP_TO_EDGE;
        };
        t->setWrap(osg::Texture::WRAP_S, wrap(mode[0]));
        t->setWrap(osg::Texture::WRAP_T, wrap(mode[1]));
        ss->setTextureAttribute(0, t);
      }
      break;
    }
    states_[index] = ss;
    uv_[index] = uv;
    *uvChannel = uv;
    return ss.get();
  }

  // The image a material names: embedded ("*N", or a name the file embeds)
  // or a file beside the model. A missing or undecodable image is a warning
  // (the model loads untextured, as with OSG's readers); one outside the
  // model's directory is an error.
  osg::ref_ptr<osg::Image> image(const std::string& ref) {
    if (auto it = images_.find(ref); it != images_.end()) return it->second;
    osg::ref_ptr<osg::Image> img;
    if (const aiTexture* t = scene_.GetEmbeddedTexture(ref.c_str()))
      img = embedded(*t, ref);
    else
      img = external(ref);
    images_[ref] = img;
    return img;
  }

  osg::ref_ptr<osg::Image> embedded(const aiTexture& t, const std::string& ref) {
    if (t.mHeight == 0) {  // compressed: mWidth bytes in a file format
      const char* bytes = reinterpret_cast<const char*>(t.pcData);
      std::string ext = t.achFormatHint;
      if (ext.empty() && t.mWidth >= 4 && std::memcmp(bytes, "\x89PNG", 4) == 0) ext = "png";
      if (ext.empty() && t.mWidth >= 2 && std::memcmp(bytes, "\xff\xd8", 2) == 0) ext = "jpg";
      std::string why;
      osgDB::ReaderWriter* rw = allowedReference("embedded." + ext, ReadKind::Image, &why)
                                    ? osgDB::Registry::instance()->getReaderWriterForExtension(ext)
                                    : nullptr;
      if (rw) {
        std::istringstream in(std::string(bytes, t.mWidth));
        osgDB::ReaderWriter::ReadResult r = rw->readImage(in);
        if (r.validImage()) return r.getImage();
      }
      warn("embedded texture " + ref + " ('" + ext + "') cannot be decoded; left off");
      return nullptr;
    }
    // Uncompressed: BGRA texels, top row first.
    osg::ref_ptr<osg::Image> img = new osg::Image;
    img->allocateImage(int(t.mWidth), int(t.mHeight), 1, GL_RGBA, GL_UNSIGNED_BYTE);
    uint8_t* d = img->data();
    for (size_t i = 0; i < size_t(t.mWidth) * t.mHeight; ++i, d += 4) {
      const aiTexel& p = t.pcData[i];
      d[0] = p.r, d[1] = p.g, d[2] = p.b, d[3] = p.a;
    }
    img->setOrigin(osg::Image::TOP_LEFT);
    return img;
  }

  osg::ref_ptr<osg::Image> external(const std::string& ref) {
    std::string path, why;
    if (!resolveReference(dir_.string(), ref, &path, &why))
      throw Error(fileError(model_, "texture '" + ref + "': " + why));
    if (!fs::is_regular_file(path)) {
      warn("texture " + path + " is missing; left off");
      return nullptr;
    }
    osg::ref_ptr<osg::Image> img = osgDB::readRefImageFile(path);  // through the PluginGuard
    if (!img) warn("texture " + path + " cannot be read; left off");
    return img;
  }

  void warn(const std::string& what) {
    std::fprintf(stderr, "dmmr-preprocess: warning: %s: %s\n", model_.c_str(), what.c_str());
  }

  const aiScene& scene_;
  std::string model_;
  fs::path dir_;
  std::vector<osg::ref_ptr<osg::Geometry>> geometries_;
  std::vector<bool> built_;
  std::vector<osg::ref_ptr<osg::StateSet>> states_;
  std::map<unsigned, unsigned> uv_;
  std::map<std::vector<unsigned>, osg::ref_ptr<osg::Geode>> geodes_;
  std::map<std::string, osg::ref_ptr<osg::Image>> images_;
};

}  // namespace

bool resolveReference(const std::string& dir, const std::string& ref, std::string* resolved,
                      std::string* why) {
  std::string r = ref;
  std::replace(r.begin(), r.end(), '\\', '/');
  if (r.empty()) {
    *why = "empty file name";
    return false;
  }
  bool drive = r.size() >= 2 && std::isalpha(static_cast<unsigned char>(r[0])) && r[1] == ':';
  if (hasScheme(r)) {
    *why = "references with a scheme (URLs) are not followed";
    return false;
  }
  if (r[0] == '/' || drive) {
    *why = "absolute paths are not followed; the file must lie in the model's directory or below";
    return false;
  }
  fs::path root = canonicalOf(dir);
  fs::path p = canonicalOf(root / r);
  if (!inside(root, p)) {
    *why = "outside the model's directory " + root.string() + " (files must lie in it or below)";
    return false;
  }
  *resolved = p.string();
  return true;
}

osg::ref_ptr<osg::Node> readWithAssimp(const std::string& path) {
  fs::path dir = canonicalOf(path).parent_path();
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  // glTF names its buffers and images by URI: check them all up front, so a
  // bad one is named as the file has it (assimp would prefix the directory).
  if (ext == ".gltf") {
    for (const std::string& uri : gltfUris(path)) {
      if (uri.compare(0, 5, "data:") == 0) continue;  // embedded; assimp decodes it
      std::string resolved, why;
      if (!resolveReference(dir.string(), uri, &resolved, &why))
        throw Error(fileError(path, "'" + uri + "': " + why));
    }
  }
  Assimp::Importer importer;
  auto* io = new ConfinedIOSystem(dir);  // the importer owns it
  importer.SetIOHandler(io);
  // Points and lines are not drawn: drop them while sorting by type.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE,
                              aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  // Triangulate polygons; no welding, no generated normals, no
  // pre-transformed vertices: positions stay as the file has them and
  // shared meshes stay shared.
  const aiScene* scene = importer.ReadFile(
      path, aiProcess_Triangulate | aiProcess_SortByPType | aiProcess_ValidateDataStructure);
  if (!scene || !scene->mRootNode) {
    std::string why = importer.GetErrorString();
    if (!io->problem().empty()) why = "cannot read " + io->problem();
    throw Error(fileError(path, "assimp cannot read this model: " + why));
  }
  return Converter(*scene, path).convert();
}

}  // namespace dmmr
