#include "plugin_guard.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
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
  const std::string* root = nullptr;  // the FindCallback's (empty: no confinement)

 private:
  RR refuse(const std::string& f) {
    allow(f, ReadKind::Other);
    return RR::FILE_NOT_HANDLED;
  }
  bool allow(const std::string& f, ReadKind kind) {
    std::string why;
    // A relative name is looked for through findDataFile (FindCallback
    // confines what it finds); an absolute one is opened as it is.
    bool inside = root == nullptr || root->empty() || !std::filesystem::path(f).is_absolute() ||
                  insideRoot(*root, f, &why);
    if (inside && allowedReference(f, kind, &why)) return true;
    ++refused;
    std::fprintf(stderr, "dmmr-preprocess: warning: refused to read '%s': %s\n", f.c_str(),
                 why.c_str());
    return false;
  }
};

bool insideRoot(const std::string& root, const std::string& path, std::string* why) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::path p = fs::canonical(path, ec);
  if (ec) {
    *why = "cannot be resolved";
    return false;
  }
  auto rel = p.lexically_relative(root);
  if (rel.empty() || *rel.begin() == "..") {
    *why = "outside the model's directory " + root;
    return false;
  }
  if (!fs::is_regular_file(p, ec)) {
    *why = "not a regular file";
    return false;
  }
  return true;
}

class PluginGuard::FindCallback : public osgDB::FindFileCallback {
 public:
  std::string findDataFile(const std::string& f, const osgDB::Options* o,
                           osgDB::CaseSensitivity cs) override {
    std::string found = osgDB::Registry::instance()->findDataFileImplementation(f, o, cs);
    if (found.empty() || root.empty()) return found;
    std::string why;
    if (insideRoot(root, found, &why)) return found;
    ++refused;
    std::fprintf(stderr, "dmmr-preprocess: warning: refused to read '%s' (found as %s): %s\n",
                 f.c_str(), found.c_str(), why.c_str());
    return "";
  }
  std::string root;  // canonical; empty: no confinement
  std::atomic<uint64_t> refused{0};
};

PluginGuard::PluginGuard() : callback_(new Callback), find_(new FindCallback) {
  callback_->root = &find_->root;
  osgDB::Registry* r = osgDB::Registry::instance();
  previous_ = r->getReadFileCallback();
  r->setReadFileCallback(callback_.get());
  previous_find_ = r->getFindFileCallback();
  r->setFindFileCallback(find_.get());
}

PluginGuard::~PluginGuard() {
  osgDB::Registry::instance()->setReadFileCallback(previous_.get());
  osgDB::Registry::instance()->setFindFileCallback(previous_find_.get());
}

void PluginGuard::confineTo(const std::string& model, const std::string& root) {
  std::error_code ec;
  std::filesystem::path dir = root.empty() ? std::filesystem::canonical(model, ec).parent_path()
                                           : std::filesystem::canonical(root, ec);
  find_->root = ec ? std::string() : dir.string();
}

uint64_t PluginGuard::refused() const {
  return callback_->refused + find_->refused;
}

}  // namespace dmmr
