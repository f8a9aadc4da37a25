#include "effects.h"

#include <fnmatch.h>

namespace dmmr {

std::vector<SurfaceEffect> effectsByName(const std::vector<SkeletonNode>& skeleton, size_t objects,
                                         const std::vector<std::string>& mirror,
                                         const std::vector<std::string>& glass) {
  std::vector<SurfaceEffect> out(objects, SurfaceEffect::None);
  if (mirror.empty() && glass.empty()) return out;
  auto matches = [](const std::vector<std::string>& patterns, const std::string& name) {
    for (const std::string& p : patterns)
      if (fnmatch(p.c_str(), name.c_str(), 0) == 0) return true;
    return false;
  };
  // Each node's effect: its own name's, else its parent's (parents come
  // first in pre-order).
  std::vector<SurfaceEffect> node(skeleton.size(), SurfaceEffect::None);
  for (size_t i = 0; i < skeleton.size(); ++i) {
    const SkeletonNode& n = skeleton[i];
    SurfaceEffect e = n.parent < i ? node[n.parent] : SurfaceEffect::None;
    if (matches(glass, n.name))
      e = SurfaceEffect::Glass;
    else if (e == SurfaceEffect::None && matches(mirror, n.name))
      e = SurfaceEffect::Mirror;
    node[i] = e;
    if (n.kind == NodeKind::Object && n.object < objects && node[i] != SurfaceEffect::None)
      out[n.object] = node[i];
  }
  return out;
}

}  // namespace dmmr
