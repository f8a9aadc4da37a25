#include "walkthrough.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "atomic_file.h"
#include "error.h"

namespace dmmr {

namespace {

bool parseDouble(std::string_view s, double* out) {
  const char* end = s.data() + s.size();
  auto r = std::from_chars(s.data(), end, *out);
  return r.ec == std::errc() && r.ptr == end && std::isfinite(*out);
}

}  // namespace

bool unitRotation(const Quatd& q, Quatd* out, double* norm) {
  double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  if (norm) *norm = n;
  if (!(std::fabs(n - 1.0) <= 1e-3)) return false;
  *out = {q.x / n, q.y / n, q.z / n, q.w / n};
  return true;
}

Walkthrough parseWalkthrough(const std::string& text, const std::string& path) {
  Walkthrough w;
  std::istringstream in(text);
  std::string line;
  long lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    std::string f;
    double v[8];
    int n = 0;
    while (fields >> f) {
      if (n == 8)
        throw Error(
            fileError(path, lineno, "expected 8 fields (time x y z qx qy qz qw), got more"));
      if (!parseDouble(f, &v[n]))
        throw Error(
            fileError(path, lineno,
                      "field " + std::to_string(n + 1) + " ('" + f + "') is not a finite number"));
      ++n;
    }
    if (n != 8)
      throw Error(fileError(
          path, lineno, "expected 8 fields (time x y z qx qy qz qw), got " + std::to_string(n)));
    ControlPoint cp{v[0], {v[1], v[2], v[3]}, {v[4], v[5], v[6], v[7]}};
    if (double norm; !unitRotation(cp.rotation, &cp.rotation, &norm))
      throw Error(
          fileError(path, lineno,
                    "rotation quaternion is not unit length (|q| = " + std::to_string(norm) + ")"));
    if (!w.points.empty() && cp.time < w.points.back().time)
      throw Error(fileError(path, lineno, "time goes backwards"));
    w.points.push_back(cp);
  }
  if (w.points.empty()) throw Error(fileError(path, "walkthrough has no control points"));
  return w;
}

Walkthrough readWalkthrough(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(fileError(path, "cannot open walkthrough"));
  std::ostringstream ss;
  ss << f.rdbuf();
  return parseWalkthrough(ss.str(), path);
}

std::string formatWalkthrough(const Walkthrough& w) {
  std::ostringstream os;
  os << std::setprecision(17);
  for (const auto& p : w.points)
    os << p.time << " " << p.position.x << " " << p.position.y << " " << p.position.z << " "
       << p.rotation.x << " " << p.rotation.y << " " << p.rotation.z << " " << p.rotation.w << "\n";
  return os.str();
}

void writeWalkthrough(const std::string& path, const Walkthrough& w) {
  writeFileAtomic(path, formatWalkthrough(w));
}

std::string frameFileName(size_t index) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%06zu.png", index);
  return buf;
}

Quatd lookAtRotation(Vec3d eye, Vec3d target, Vec3d up) {
  // Columns of the camera-to-world rotation: right, up, back (-forward).
  Vec3d f = normalize(target - eye);
  Vec3d r = cross(f, up);
  if (length(r) < 1e-12) r = cross(f, std::fabs(f.z) < 0.9 ? Vec3d{0, 0, 1} : Vec3d{1, 0, 0});
  r = normalize(r);
  Vec3d u = cross(r, f);
  Vec3d b = -f;
  // Rotation matrix to quaternion (Shepperd).
  double m00 = r.x, m01 = u.x, m02 = b.x;
  double m10 = r.y, m11 = u.y, m12 = b.y;
  double m20 = r.z, m21 = u.z, m22 = b.z;
  double tr = m00 + m11 + m22;
  Quatd q;
  if (tr > 0) {
    double s = std::sqrt(tr + 1.0) * 2;
    q = {(m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s};
  } else if (m00 > m11 && m00 > m22) {
    double s = std::sqrt(1.0 + m00 - m11 - m22) * 2;
    q = {0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s};
  } else if (m11 > m22) {
    double s = std::sqrt(1.0 + m11 - m00 - m22) * 2;
    q = {(m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s};
  } else {
    double s = std::sqrt(1.0 + m22 - m00 - m11) * 2;
    q = {(m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s};
  }
  double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  return {q.x / n, q.y / n, q.z / n, q.w / n};
}

}  // namespace dmmr
