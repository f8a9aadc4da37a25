// A check of an OBJ file's face, line and point indices before OpenSceneGraph
// reads it: OSG's OBJ plugin expands indices without checking them, so an
// index past the vertices read past its arrays and gave garbage vertices (a
// scene whose bounds reached 1e37, drawn empty) or silently wrong triangles.
#pragma once

#include <istream>
#include <string>

namespace dmmr {

// Reads `in` (an OBJ's text; `name` starts every error) and throws Error
// naming the line when an f, l or p element refers to a vertex, texture
// coordinate or normal index that is 0, that lies past the file's count of
// that kind (positive indices: the whole file's `v`, `vt`, `vn` lines;
// negative ones: those before the element, as the format counts them back),
// or that is not a number; and when a face has fewer than 3 vertices or a
// v or vn line fewer than 3 coordinates (a line cut short, which OSG's
// plugin would take quietly: a two-vertex face as a line, which gives no
// triangle).
void checkObjIndices(std::istream& in, const std::string& name);

}  // namespace dmmr
