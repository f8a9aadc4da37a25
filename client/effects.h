// Which objects reflect or refract under the ray tracer (--reflections):
// chosen by name, so that marking a model's glass or mirrors needs no new
// preprocessing. A pattern (fnmatch(3) glob, e.g. "*window*") matches an
// object when it matches the name of the object's skeleton node or of any
// node above it (a model file's group, a geode, a cluster's mesh group).
#pragma once

#include <string>
#include <vector>

#include "formats.h"
#include "raytrace.h"

namespace dmmr {

// Effects by object index (size `objects`). `skeleton` in pre-order with
// parents before children (formats.h). Glass wins over mirror where both
// match. Patterns are matched case-sensitively.
std::vector<SurfaceEffect> effectsByName(const std::vector<SkeletonNode>& skeleton, size_t objects,
                                         const std::vector<std::string>& mirror,
                                         const std::vector<std::string>& glass);

}  // namespace dmmr
