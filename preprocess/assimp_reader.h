// Reads the formats OSG 3.6 has no plugin for (glTF 2.0, FBX, 3MF, OFF;
// plugin_guard.h's modelReaderFor) through assimp, converted into an
// osg::Node graph, so the SceneWriter traverses them like any OSG model.
#pragma once

#include <string>

#include <osg/Node>
#include <osg/ref_ptr>

namespace dmmr {

// The converted graph: one MatrixTransform turning assimp's Y-up into
// dmmr's Z-up ((x, y, z) -> (x, -z, y), as OSG's OBJ reader does), then
// Groups and MatrixTransforms for assimp's nodes, a Geode per node with
// meshes (shared between nodes with the same meshes, so instances stay
// instances), an osg::Geometry per triangle mesh with its normals, first
// colour set and the diffuse texture's coordinates, and a StateSet per
// material (diffuse or base colour, diffuse or base-colour texture).
// Files the model names (glTF buffers, textures) are read only from the
// model's directory or below. Throws Error naming the file and what is
// wrong: unreadable or malformed, a missing buffer, a reference that is
// absolute, has a scheme, or escapes the directory.
osg::ref_ptr<osg::Node> readWithAssimp(const std::string& path);

// Resolves `ref`, a file named by a model in directory `dir`, to a path in
// `dir` or below (symbolic links resolved); otherwise false with *why.
bool resolveReference(const std::string& dir, const std::string& ref, std::string* resolved,
                      std::string* why);

}  // namespace dmmr
