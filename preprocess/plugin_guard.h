// Which OpenSceneGraph plugins a model from a stranger may make the
// preprocessor load. A model file can name other files (textures, external
// nodes, shaders, scripts, archives) and OSG picks a plugin by each name's
// extension, or by a URL's scheme: left alone, an .osgt could make
// dmmr-preprocess fetch from the network (osgdb_curl), run a script
// (osgdb_lua), or load any installed plugin through a pseudo-loader name
// such as "model.osg.0,0,1.trans". While a PluginGuard lives, every read
// through osgDB's registry is checked against an allow-list of model and
// image formats; anything else is refused with a warning on stderr and the
// model loads without it.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include <osg/ref_ptr>
#include <osgDB/Callbacks>

namespace dmmr {

enum class ReadKind { Node, Image, Object, Other };

// True when `filename` may be read as `kind`; otherwise *why says why.
// Pure: looks at the name only.
bool allowedReference(const std::string& filename, ReadKind kind, std::string* why);

// Which library reads an input model, by its extension: assimp for the
// formats OSG 3.6 has no plugin for (glTF 2.0, FBX, 3MF, OFF), dmmr's own
// strict reader for PLY (ply_reader.h: OSG's plugin crashes on malformed
// files), OSG for the rest of the allow-list; None for anything else
// (images, buffers, text).
enum class ModelReader { None, Osg, Assimp, Ply };
ModelReader modelReaderFor(const std::string& filename);

// True when `path` (found by OSG: absolute, or relative to the working
// directory) is a regular file in `root` (a canonical directory) or below,
// symbolic links resolved; otherwise false with *why. Looks at the disk.
bool insideRoot(const std::string& root, const std::string& path, std::string* why);

class PluginGuard {
 public:
  PluginGuard();   // installs the registry's read and find-file callbacks
  ~PluginGuard();  // restores the ones before
  PluginGuard(const PluginGuard&) = delete;
  PluginGuard& operator=(const PluginGuard&) = delete;
  uint64_t refused() const;  // reads refused so far
  // From now on, every file OSG looks for (findDataFile: the model, an OBJ's
  // mtllib, textures, a ProxyNode's model) must be a regular file in `root`
  // (a directory input the model was found under) or, when `root` is empty,
  // the directory of `model`, or below; anything else is refused with a warning
  // naming it, as if it were missing (so OSG's search of the working
  // directory and OSG_FILE_PATH finds nothing outside either). A FIFO or a
  // device (an OBJ naming /dev/zero as its mtllib hung the read) is refused
  // too.
  void confineTo(const std::string& model, const std::string& root = "");

 private:
  class Callback;
  class FindCallback;
  osg::ref_ptr<Callback> callback_;
  osg::ref_ptr<FindCallback> find_;
  osg::ref_ptr<osgDB::ReadFileCallback> previous_;
  osg::ref_ptr<osgDB::FindFileCallback> previous_find_;
};

}  // namespace dmmr
