// Camera paths in OSG's AnimationPath text format: one control point a line,
// "time x y z qx qy qz qw", the camera's position and orientation in world
// space (the camera looks down its local -Z, +Y up). The same files play in
// osgviewer. dmmr renders one frame per control point.
#pragma once

#include <string>
#include <vector>

#include "math.h"

namespace dmmr {

struct ControlPoint {
  double time = 0;
  Vec3d position;
  Quatd rotation;
  friend bool operator==(const ControlPoint&, const ControlPoint&) = default;
};

struct Walkthrough {
  std::vector<ControlPoint> points;
};

// Parses AnimationPath text. Blank lines and lines starting with '#' are
// skipped. Throws Error naming `path` and the line for: a wrong number of
// fields, a field that is not a finite number, a zero or non-unit quaternion
// (|q| off 1 by more than 1e-3; near-unit ones are renormalised), or time
// going backwards. An empty path is an error too.
// A camera rotation as every pose source takes it: |q| within 1e-3 of 1,
// then divided by |q| (so a pose written to a file and read back renders the
// same camera). False, with *norm set, when q is off unit length or not
// finite; *out is then untouched.
bool unitRotation(const Quatd& q, Quatd* out, double* norm = nullptr);

Walkthrough parseWalkthrough(const std::string& text, const std::string& path);
Walkthrough readWalkthrough(const std::string& path);
std::string formatWalkthrough(const Walkthrough& w);
// Writes atomically (temporary file, then rename).
void writeWalkthrough(const std::string& path, const Walkthrough& w);

// The file name of frame `index` (one per control point): "frame_000042.png".
std::string frameFileName(size_t index);

// Orientation of a camera at `eye` looking at `target` with `up` roughly up.
Quatd lookAtRotation(Vec3d eye, Vec3d target, Vec3d up);

}  // namespace dmmr
