#include "plugin_guard.h"

#include <algorithm>
#include <cstdio>
#include <osgDB/Registry>
#include <set>

namespace dmmr {

namespace {

std::string lowerExtension(const std::string& name) {
  size_t slash = name.find_last_of("/\\");
  size_t dot = name.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = name.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext;
}

// Formats whose plugins parse geometry or pixels and nothing else.
const std::set<std::string> kModels = {"osg", "osgt", "osgb", "osgx", "ive", "obj",
                                       "ply", "stl",  "3ds",  "flt",  "lwo", "ac",
                                       "dxf", "x",    "dae",  "fbx",  "off", "3mf"};
// Of those, the ones read through assimp (Debian's OSG has no plugin for
// them), plus glTF, which only assimp reads. Collada stays with OSG's dae
// plugin, OBJ, PLY and the OSG formats with OSG's own readers.
const std::set<std::string> kAssimpModels = {"gltf", "glb", "fbx", "3mf", "off"};
const std::set<std::string> kImages = {"png", "jpg", "jpeg", "bmp",  "tga", "tif", "tiff",
                                       "gif", "dds", "rgb",  "rgba", "sgi", "int", "inta",
                                       "bw",  "pnm", "ppm",  "pgm",  "pbm", "hdr", "ktx"};

}  // namespace

bool allowedReference(const std::string& filename, ReadKind kind, std::string* why) {
  if (filename.find("://") != std::string::npos) {
    *why = "network references are not followed";
    return false;
  }
  std::string ext = lowerExtension(filename);
  bool ok = (kind == ReadKind::Node || kind == ReadKind::Object) && kModels.count(ext);
  ok = ok || ((kind == ReadKind::Image || kind == ReadKind::Object) && kImages.count(ext));
  if (!ok) {
    *why = kind == ReadKind::Other ? "shaders, scripts and archives are not loaded"
           : ext.empty()           ? "no extension to choose a model or image format by"
                                   : "'." + ext + "' is not an allowed model or image format";
  }
  return ok;
}

ModelReader modelReaderFor(const std::string& filename) {
  std::string ext = lowerExtension(filename);
  if (kAssimpModels.count(ext)) return ModelReader::Assimp;
  if (ext == "ply") return ModelReader::Ply;
  return kModels.count(ext) ? ModelReader::Osg : ModelReader::None;
}

class PluginGuard::Callback : public osgDB::ReadFileCallback {
 public:
  using RR = osgDB::ReaderWriter::ReadResult;
  RR readNode(const std::string& f, const osgDB::Options* o) override {
    if (!allow(f, ReadKind::Node)) return RR::FILE_NOT_HANDLED;
    return osgDB::Registry::instance()->readNodeImplementation(f, o);
  }
  RR readImage(const std::string& f, const osgDB::Options* o) override {
    if (!allow(f, ReadKind::Image)) return RR::FILE_NOT_HANDLED;
    return osgDB::Registry::instance()->readImageImplementation(f, o);
  }
  RR readObject(const std::string& f, const osgDB::Options* o) override {
    if (!allow(f, ReadKind::Object)) return RR::FILE_NOT_HANDLED;
    return osgDB::Registry::instance()->readObjectImplementation(f, o);
  }
  RR readHeightField(const std::string& f, const osgDB::Options*) override { return refuse(f); }
  RR readShader(const std::string& f, const osgDB::Options*) override { return refuse(f); }
  RR readScript(const std::string& f, const osgDB::Options*) override { return refuse(f); }
  RR openArchive(const std::string& f, osgDB::ReaderWriter::ArchiveStatus, unsigned int,
                 const osgDB::Options*) override {
    return refuse(f);
  }
  std::atomic<uint64_t> refused{0};

 private:
  RR refuse(const std::string& f) {
    allow(f, ReadKind::Other);
    return RR::FILE_NOT_HANDLED;
  }
  bool allow(const std::string& f, ReadKind kind) {
    std::string why;
    if (allowedReference(f, kind, &why)) return true;
    ++refused;
    std::fprintf(stderr, "dmmr-preprocess: warning: refused to read '%s': %s\n", f.c_str(),
                 why.c_str());
    return false;
  }
};

PluginGuard::PluginGuard() : callback_(new Callback) {
  osgDB::Registry* r = osgDB::Registry::instance();
  previous_ = r->getReadFileCallback();
  r->setReadFileCallback(callback_.get());
}

PluginGuard::~PluginGuard() {
  osgDB::Registry::instance()->setReadFileCallback(previous_.get());
}

uint64_t PluginGuard::refused() const {
  return callback_->refused;
}

}  // namespace dmmr
