#include "scenegen.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include <osg/ComputeBoundsVisitor>
#include <osg/Geode>
#include <osg/Material>
#include <osg/MatrixTransform>
#include <osg/NodeVisitor>
#include <osg/TriangleIndexFunctor>

#include "error.h"

namespace dmmr::scenegen {
namespace {

using V3 = osg::Vec3d;
const V3 kZ(0, 0, 1);
constexpr double kPi = 3.14159265358979323846;

// ------------------------------------------------------------------ randomness

// splitmix64 with our own [0,1) mapping, so scenes are identical across
// standard libraries (std distributions are implementation-defined).
class Rng {
 public:
  explicit Rng(uint64_t seed) : s_(seed) {}
  uint64_t next() {
    uint64_t z = (s_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return double(next() >> 11) * 0x1.0p-53; }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  int range(int lo, int hi) { return lo + int(next() % uint64_t(hi - lo + 1)); }  // inclusive
  bool chance(double p) { return uniform() < p; }
  template <typename T>
  T pick(std::initializer_list<T> items) {
    return items.begin()[range(0, int(items.size()) - 1)];
  }

 private:
  uint64_t s_;
};

// An independent stream per (seed, part), so one part's draws never shift another's.
Rng substream(uint64_t seed, uint64_t part) {
  Rng r(seed ^ (part * 0xD1B54A32D192ED03ull + 0x8CB92BA72F3D8DD7ull));
  r.next();
  return r;
}

// ------------------------------------------------------------------ primitives
// All primitives are in the geode's local frame. Detail factor d scales
// tessellation; the count and build code share the same step functions.

struct BoxPrim {
  V3 c;
  std::array<V3, 3> a;  // half-axes, right-handed
  double cell = 0;      // grid cell edge at detail 1; 0: never subdivided
};

struct TubePiece {
  bool arc = false;
  V3 a, b;           // straight: from a to b; arc: start point a
  V3 centre, axis;   // arc: rotate (a - centre) about axis by angle
  double angle = 0;  // arc only
  double length = 0;
};

// A pipe along a polyline with rounded corners (elbows).
struct TubePrim {
  std::vector<V3> path;
  double r = 0.1;
  double weight = 1;
  double aspect = 32;             // ring spacing along straights, in ring-segment widths
  std::vector<TubePiece> pieces;  // derived from path by finishTube
};

enum class Cap : uint8_t { None, Flat, Dome };

struct CylPrim {
  V3 base, axis;  // axis: base to top, length = height
  double r = 1;
  Cap cap0 = Cap::None, cap1 = Cap::None;
  double domeRatio = 0.5;  // dome cap height / radius
  double weight = 1;
  double aspect = 32;
  double taper = 0;  // radius shrinks by this fraction from base to top
  double flute = 0;  // radial depth of flutes, fraction of r
  int flutes = 0;
};

struct DomePrim {
  V3 c, up;
  double r = 1, ratio = 1, weight = 1;
};

struct TorusPrim {
  V3 c, axis, start;  // start: direction from c to the first ring centre
  double R = 1, r = 0.1, sweep = 2 * kPi, weight = 1;
};

struct Shape {
  int colour = 0;
  bool vertexColours = false;
  std::vector<BoxPrim> boxes;
  std::vector<TubePrim> tubes;
  std::vector<CylPrim> cyls;
  std::vector<DomePrim> domes;
  std::vector<TorusPrim> tori;

  bool flat() const { return !boxes.empty(); }
  bool curved() const { return !tubes.empty() || !cyls.empty() || !domes.empty() || !tori.empty(); }
  bool empty() const { return !flat() && !curved(); }

  Shape& box(V3 lo, V3 hi, double cell = 0) {
    V3 h = (hi - lo) * 0.5;
    boxes.push_back({(lo + hi) * 0.5, {V3(h.x(), 0, 0), V3(0, h.y(), 0), V3(0, 0, h.z())}, cell});
    return *this;
  }
  // Oriented box; a2 is flipped if needed to keep the axes right-handed.
  Shape& obox(V3 c, V3 a0, V3 a1, V3 a2, double cell = 0) {
    if ((a0 ^ a1) * a2 < 0) a2 = -a2;
    boxes.push_back({c, {a0, a1, a2}, cell});
    return *this;
  }
  Shape& tube(std::vector<V3> path, double r, double weight = 1) {
    TubePrim t;
    t.path = std::move(path);
    t.r = r;
    t.weight = weight;
    tubes.push_back(std::move(t));
    return *this;
  }
  Shape& cyl(const CylPrim& c) {
    cyls.push_back(c);
    return *this;
  }
  Shape& dome(const DomePrim& d) {
    domes.push_back(d);
    return *this;
  }
  Shape& torus(const TorusPrim& t) {
    tori.push_back(t);
    return *this;
  }
  // Applies a rigid transform (rotation + translation) to every primitive.
  Shape& transform(const osg::Matrixd& m) {
    auto vec = [&](const V3& v) { return osg::Matrixd::transform3x3(v, m); };
    for (auto& b : boxes) {
      b.c = b.c * m;
      for (auto& a : b.a) a = vec(a);
    }
    for (auto& t : tubes)
      for (auto& p : t.path) p = p * m;
    for (auto& c : cyls) c.base = c.base * m, c.axis = vec(c.axis);
    for (auto& d : domes) d.c = d.c * m, d.up = vec(d.up);
    for (auto& t : tori) t.c = t.c * m, t.axis = vec(t.axis), t.start = vec(t.start);
    return *this;
  }
};

Shape flatShape(int colour) {
  Shape s;
  s.colour = colour;
  return s;
}
Shape curvedShape(int colour) {
  return flatShape(colour);
}

V3 normalized(V3 v) {
  v.normalize();
  return v;
}

// Some unit vector perpendicular to t (deterministic).
V3 perpendicular(const V3& t) {
  V3 p = t ^ (std::fabs(t.z()) < 0.9 * t.length() ? kZ : V3(1, 0, 0));
  return normalized(p);
}

// Splits a polyline into straights and circular elbows of radius 1.5 r, the
// cut at each corner clamped to 45% of the shorter neighbouring segment.
void finishTube(TubePrim& t) {
  t.pieces.clear();
  std::vector<V3> p;  // without repeated points, which have no direction
  for (const V3& q : t.path)
    if (p.empty() || (q - p.back()).length() > 1e-6) p.push_back(q);
  t.path = p;
  size_t n = p.size();
  if (n < 2) return;
  std::vector<double> cut(n, 0.0);
  std::vector<double> angle(n, 0.0);
  for (size_t i = 1; i + 1 < n; ++i) {
    V3 din = p[i] - p[i - 1], dout = p[i + 1] - p[i];
    double lin = din.normalize(), lout = dout.normalize();
    double th = std::acos(std::clamp(din * dout, -1.0, 1.0));
    if (th < 1e-6 || th > kPi * 0.99) continue;  // straight on, or a reversal: no elbow
    angle[i] = th;
    cut[i] = std::min(1.5 * t.r * std::tan(th / 2), 0.45 * std::min(lin, lout));
  }
  for (size_t i = 0; i + 1 < n; ++i) {
    V3 d = normalized(p[i + 1] - p[i]);
    TubePiece s;
    s.a = p[i] + d * cut[i];
    s.b = p[i + 1] - d * cut[i + 1];
    s.length = (s.b - s.a).length();
    if (s.length > 1e-9) t.pieces.push_back(s);
    if (i + 2 < n && angle[i + 1] > 0) {
      V3 dout = normalized(p[i + 2] - p[i + 1]);
      TubePiece arc;
      arc.arc = true;
      arc.angle = angle[i + 1];
      arc.axis = normalized(d ^ dout);
      double bend = cut[i + 1] / std::tan(arc.angle / 2);
      arc.a = p[i + 1] - d * cut[i + 1];
      arc.centre = arc.a + (arc.axis ^ d) * bend;
      arc.length = bend * arc.angle;
      t.pieces.push_back(arc);
    }
  }
}

// ------------------------------------------------------------------ tessellation steps

int clampRound(double v, int lo, int hi) {
  return int(std::lround(std::clamp(v, double(lo), double(hi))));
}
int ringSegments(double r, double weight, double d) {
  return clampRound(d * weight * 12.0 * std::cbrt(r / 0.5), 4, 512);
}
int straightSteps(double length, double r, int s, double aspect) {
  return clampRound(length * s / (2 * kPi * r * aspect), 1, 256);
}
int arcSteps(double angle, int s) {
  return clampRound(s * angle / (2 * kPi), 1, 256);
}
int domeBands(int s) {
  return clampRound(s / 4.0, 1, 128);
}
int gridCells(double extent, double cell, double d) {
  return cell <= 0 ? 1 : clampRound(extent * d / cell, 1, 512);
}
std::array<int, 3> boxCells(const BoxPrim& b, double d) {
  std::array<int, 3> n;
  for (int k = 0; k < 3; ++k) n[k] = gridCells(2 * b.a[k].length(), b.cell, d);
  return n;
}
int tubeSteps(const TubePiece& p, const TubePrim& t, int s) {
  return p.arc ? arcSteps(p.angle, s) : straightSteps(p.length, t.r, s, t.aspect);
}

// ------------------------------------------------------------------ triangle counts

uint64_t capTriangles(Cap cap, int s) {
  if (cap == Cap::Flat) return s;
  if (cap == Cap::Dome) return uint64_t(s) * (2 * domeBands(s) - 1);
  return 0;
}

uint64_t shapeTriangles(const Shape& sh, double d) {
  uint64_t n = 0;
  for (const auto& b : sh.boxes) {
    auto c = boxCells(b, d);
    n += 4ull * (uint64_t(c[0]) * c[1] + uint64_t(c[1]) * c[2] + uint64_t(c[2]) * c[0]);
  }
  for (const auto& t : sh.tubes) {
    int s = ringSegments(t.r, t.weight, d);
    uint64_t steps = 0;
    for (const auto& p : t.pieces) steps += tubeSteps(p, t, s);
    n += 2ull * s * steps;
  }
  for (const auto& c : sh.cyls) {
    int s = ringSegments(c.r, c.weight, d);
    n += 2ull * s * straightSteps(c.axis.length(), c.r, s, c.aspect);
    n += capTriangles(c.cap0, s) + capTriangles(c.cap1, s);
  }
  for (const auto& dm : sh.domes) n += capTriangles(Cap::Dome, ringSegments(dm.r, dm.weight, d));
  for (const auto& t : sh.tori) {
    int s = ringSegments(t.r, t.weight, d);
    n += 2ull * s * arcSteps(t.sweep, ringSegments(t.R, t.weight, d));
  }
  return n;
}

// ------------------------------------------------------------------ mesh building

class Mesh {
 public:
  explicit Mesh(bool normals)
      : v_(new osg::Vec3Array), n_(normals ? new osg::Vec3Array : nullptr) {}
  uint32_t vertex(const V3& p) {
    v_->push_back(osg::Vec3(p));
    return uint32_t(v_->size() - 1);
  }
  uint32_t vertex(const V3& p, const V3& n) {
    n_->push_back(osg::Vec3(normalized(n)));
    return vertex(p);
  }
  void tri(uint32_t a, uint32_t b, uint32_t c) { idx_.insert(idx_.end(), {a, b, c}); }
  void quad(uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
    tri(a, b, c);
    tri(a, c, d);
  }
  uint64_t triangles() const { return idx_.size() / 3; }
  osg::Vec3Array* vertices() const { return v_.get(); }
  osg::ref_ptr<osg::Geometry> finish() const;

 private:
  osg::ref_ptr<osg::Vec3Array> v_, n_;
  std::vector<uint32_t> idx_;
};

// 16-bit indices where they fit: half the index memory for most geodes.
osg::ref_ptr<osg::Geometry> Mesh::finish() const {
  osg::ref_ptr<osg::Geometry> g = new osg::Geometry;
  g->setUseDisplayList(false);
  g->setUseVertexBufferObjects(true);
  g->setVertexArray(v_.get());
  if (n_) g->setNormalArray(n_.get(), osg::Array::BIND_PER_VERTEX);
  if (v_->size() <= 65536) {
    osg::ref_ptr<osg::DrawElementsUShort> e = new osg::DrawElementsUShort(GL_TRIANGLES);
    e->reserve(idx_.size());
    for (uint32_t i : idx_) e->push_back(uint16_t(i));
    g->addPrimitiveSet(e.get());
  } else {
    g->addPrimitiveSet(new osg::DrawElementsUInt(GL_TRIANGLES, idx_.begin(), idx_.end()));
  }
  return g;
}

void emitBox(Mesh& m, const BoxPrim& b, double d) {
  auto n = boxCells(b, d);
  if (n[0] == 1 && n[1] == 1 && n[2] == 1) {
    // Shared corners: without normals, faces need no vertices of their own.
    uint32_t c[8];
    for (int i = 0; i < 8; ++i)
      c[i] = m.vertex(b.c + b.a[0] * ((i & 1) ? 1 : -1) + b.a[1] * ((i & 2) ? 1 : -1) +
                      b.a[2] * ((i & 4) ? 1 : -1));
    static const int kFaces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                     {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    for (const auto& f : kFaces) m.quad(c[f[0]], c[f[1]], c[f[2]], c[f[3]]);
    return;
  }
  for (int k = 0; k < 3; ++k) {
    for (int sign : {1, -1}) {
      V3 u = b.a[(k + 1) % 3], v = b.a[(k + 2) % 3];
      int nu = n[(k + 1) % 3], nv = n[(k + 2) % 3];
      if (sign < 0) std::swap(u, v), std::swap(nu, nv);  // keep u x v outward
      V3 o = b.c + b.a[k] * sign;
      uint32_t first = 0;
      for (int j = 0; j <= nv; ++j)
        for (int i = 0; i <= nu; ++i) {
          uint32_t id = m.vertex(o + u * (2.0 * i / nu - 1) + v * (2.0 * j / nv - 1));
          if (i == 0 && j == 0) first = id;
        }
      for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
          uint32_t a = first + j * (nu + 1) + i;
          m.quad(a, a + 1, a + 1 + (nu + 1), a + (nu + 1));
        }
    }
  }
}

// A ring station of a swept tube: centre, tangent, a normal-plane axis, radius.
struct Station {
  V3 p, t, u;
  double r;
};

struct Ring {
  std::vector<double> c, s;
  explicit Ring(int n) : c(n), s(n) {
    for (int k = 0; k < n; ++k) c[k] = std::cos(2 * kPi * k / n), s[k] = std::sin(2 * kPi * k / n);
  }
};

// Rings of s vertices at each station joined by quads, outward CCW. Flutes
// vary the radius with angle; normals follow the fluted profile.
void emitSweep(Mesh& m, const std::vector<Station>& st, int s, double flute = 0, int flutes = 0) {
  Ring ring(s);
  uint32_t first = 0;
  for (size_t i = 0; i < st.size(); ++i) {
    const Station& q = st[i];
    V3 v = q.t ^ q.u;
    for (int k = 0; k < s; ++k) {
      V3 e = q.u * ring.c[k] + v * ring.s[k];
      V3 tang = v * ring.c[k] - q.u * ring.s[k];
      double th = 2 * kPi * k / s;
      double r = q.r * (1 + flute * std::cos(flutes * th));
      double dr = -q.r * flute * flutes * std::sin(flutes * th);
      uint32_t id = m.vertex(q.p + e * r, e * r - tang * dr);
      if (i == 0 && k == 0) first = id;
    }
  }
  for (size_t i = 0; i + 1 < st.size(); ++i)
    for (int k = 0; k < s; ++k) {
      uint32_t a0 = first + uint32_t(i * s + k), a1 = first + uint32_t(i * s + (k + 1) % s);
      m.quad(a0, a1, a1 + s, a0 + s);
    }
}

// Flat disc closing a sweep at station q; `end` picks the +t side.
void emitDisc(Mesh& m, const Station& q, int s, bool end) {
  Ring ring(s);
  V3 v = q.t ^ q.u, n = end ? q.t : -q.t;
  uint32_t c = m.vertex(q.p, n);
  for (int k = 0; k < s; ++k) m.vertex(q.p + (q.u * ring.c[k] + v * ring.s[k]) * q.r, n);
  for (int k = 0; k < s; ++k) {
    uint32_t a = c + 1 + k, b = c + 1 + (k + 1) % s;
    end ? m.tri(c, a, b) : m.tri(c, b, a);
  }
}

// Half ellipsoid of base radius r and height h over centre c, bulging along out.
void emitDome(Mesh& m, V3 c, V3 out, V3 u, double r, double h, int s) {
  out.normalize();
  V3 v = out ^ u;
  int bands = domeBands(s);
  Ring ring(s);
  uint32_t first = 0;
  for (int j = 0; j < bands; ++j) {
    double phi = kPi / 2 * j / bands, cp = std::cos(phi), sp = std::sin(phi);
    for (int k = 0; k < s; ++k) {
      V3 e = u * ring.c[k] + v * ring.s[k];
      uint32_t id = m.vertex(c + e * (r * cp) + out * (h * sp), e * (cp / r) + out * (sp / h));
      if (j == 0 && k == 0) first = id;
    }
  }
  uint32_t pole = m.vertex(c + out * h, out);
  for (int j = 0; j < bands; ++j)
    for (int k = 0; k < s; ++k) {
      uint32_t a0 = first + j * s + k, a1 = first + j * s + (k + 1) % s;
      if (j + 1 < bands)
        m.quad(a0, a1, a1 + s, a0 + s);
      else
        m.tri(a0, a1, pole);
    }
}

void emitCap(Mesh& m, Cap cap, const Station& q, int s, bool end, double ratio) {
  if (cap == Cap::Flat) emitDisc(m, q, s, end);
  if (cap == Cap::Dome) emitDome(m, q.p, end ? q.t : -q.t, q.u, q.r, q.r * ratio, s);
}

void emitTube(Mesh& m, const TubePrim& t, double d) {
  if (t.pieces.empty()) return;
  int s = ringSegments(t.r, t.weight, d);
  V3 t0 = normalized(t.pieces[0].arc ? t.path[1] - t.path[0] : t.pieces[0].b - t.pieces[0].a);
  std::vector<Station> st{{t.pieces[0].a, t0, perpendicular(t0), t.r}};
  for (const auto& p : t.pieces) {
    int n = tubeSteps(p, t, s);
    Station prev = st.back();
    for (int k = 1; k <= n; ++k) {
      if (!p.arc) {
        st.push_back({p.a + (p.b - p.a) * (double(k) / n), prev.t, prev.u, t.r});
      } else {
        osg::Quat q(p.angle * k / n, p.axis);
        st.push_back({p.centre + q * (p.a - p.centre), q * prev.t, q * prev.u, t.r});
      }
    }
  }
  emitSweep(m, st, s);
}

void emitCyl(Mesh& m, const CylPrim& c, double d) {
  int s = ringSegments(c.r, c.weight, d);
  double len = c.axis.length();
  int n = straightSteps(len, c.r, s, c.aspect);
  V3 t = c.axis / len, u = perpendicular(t);
  std::vector<Station> st;
  for (int k = 0; k <= n; ++k) {
    double f = double(k) / n;
    st.push_back({c.base + c.axis * f, t, u, c.r * (1 - c.taper * f)});
  }
  emitSweep(m, st, s, c.flute, c.flutes);
  emitCap(m, c.cap0, st.front(), s, false, c.domeRatio);
  emitCap(m, c.cap1, st.back(), s, true, c.domeRatio);
}

void emitTorus(Mesh& m, const TorusPrim& t, double d) {
  int s = ringSegments(t.r, t.weight, d);
  int e = arcSteps(t.sweep, ringSegments(t.R, t.weight, d));
  V3 ax = normalized(t.axis), x = normalized(t.start), y = ax ^ x;
  std::vector<Station> st;
  for (int k = 0; k <= e; ++k) {
    double phi = t.sweep * k / e;
    V3 dir = x * std::cos(phi) + y * std::sin(phi);
    st.push_back({t.c + dir * t.R, y * std::cos(phi) - x * std::sin(phi), ax, t.r});
  }
  emitSweep(m, st, s);
}

struct Palette {
  std::array<osg::Vec4, 8> colours;
  int accent;  // blended into per-vertex colours
};

// Per-vertex colours: bands of the accent colour across the base colour, so a
// renderer that ignores them is visibly wrong.
osg::ref_ptr<osg::Vec4Array> vertexColours(const osg::Vec3Array& v, const Palette& pal,
                                           int colour) {
  osg::ref_ptr<osg::Vec4Array> c = new osg::Vec4Array;
  c->reserve(v.size());
  const osg::Vec4 &a = pal.colours[colour], &b = pal.colours[pal.accent];
  for (const auto& p : v) {
    float f = 0.5f + 0.5f * std::sin(p.z() * 2.1f + p.x() * 0.7f + p.y() * 0.3f);
    c->push_back(a * (1 - f) + b * f);
  }
  return c;
}

osg::ref_ptr<osg::Geometry> buildGeometry(const Shape& sh, double d, const Palette& pal) {
  Mesh m(sh.curved());
  for (const auto& b : sh.boxes) emitBox(m, b, d);
  for (const auto& t : sh.tubes) emitTube(m, t, d);
  for (const auto& c : sh.cyls) emitCyl(m, c, d);
  for (const auto& dm : sh.domes) {
    int s = ringSegments(dm.r, dm.weight, d);
    emitDome(m, dm.c, dm.up, perpendicular(dm.up), dm.r, dm.r * dm.ratio, s);
  }
  for (const auto& t : sh.tori) emitTorus(m, t, d);
  DMMR_CHECK_MSG(m.triangles() == shapeTriangles(sh, d), "tessellation count mismatch");
  osg::ref_ptr<osg::Geometry> g = m.finish();
  if (sh.vertexColours)
    g->setColorArray(vertexColours(*m.vertices(), pal, sh.colour).get(),
                     osg::Array::BIND_PER_VERTEX);
  return g;
}

// ------------------------------------------------------------------ scene assembly

struct Leaf {
  osg::ref_ptr<osg::Geode> geode;
  Shape shape;
};

osg::ref_ptr<osg::StateSet> materialState(const osg::Vec4& diffuse, bool vertexColours) {
  osg::ref_ptr<osg::Material> mat = new osg::Material;
  mat->setDiffuse(osg::Material::FRONT_AND_BACK, diffuse);
  mat->setAmbient(osg::Material::FRONT_AND_BACK, diffuse * 0.3f);
  mat->setSpecular(osg::Material::FRONT_AND_BACK, osg::Vec4(0.1f, 0.1f, 0.1f, 1));
  mat->setShininess(osg::Material::FRONT_AND_BACK, 16);
  if (vertexColours) mat->setColorMode(osg::Material::AMBIENT_AND_DIFFUSE);
  osg::ref_ptr<osg::StateSet> ss = new osg::StateSet;
  ss->setAttribute(mat.get());
  return ss;
}

// Collects geodes with their shapes; geometry is made once the detail factor is known.
class SceneBuilder {
 public:
  SceneBuilder(uint64_t seed, const Palette& pal) : rng_(substream(seed, 0xC0105)), pal_(pal) {
    for (int i = 0; i < 8; ++i) {
      plain_[i] = materialState(pal.colours[i], false);
      coloured_[i] = materialState(pal.colours[i], true);
    }
  }
  void add(osg::Group* parent, const char* name, Shape shape) {
    DMMR_CHECK(shape.flat() != shape.curved());
    shape.vertexColours = rng_.chance(0.03);
    for (auto& t : shape.tubes) finishTube(t);
    osg::ref_ptr<osg::Geode> g = new osg::Geode;
    g->setName(name);
    g->setStateSet((shape.vertexColours ? coloured_ : plain_)[shape.colour].get());
    parent->addChild(g.get());
    leaves.push_back({g, std::move(shape)});
  }
  std::vector<Leaf> leaves;

 private:
  Rng rng_;
  Palette pal_;
  std::array<osg::ref_ptr<osg::StateSet>, 8> plain_, coloured_;
};

// A geode budget. Children carve sub-budgets whose use counts against the parent.
class Emitter {
 public:
  Emitter(SceneBuilder& sb, uint32_t quota) : sb_(sb), left_(quota) {}
  uint32_t left() const { return left_; }
  Emitter sub(uint32_t quota) {
    Emitter e(sb_, std::min(quota, left_));
    e.parent_ = this;
    return e;
  }
  // Adds a geode unless the budget is spent or the shape is empty.
  bool add(osg::Group* parent, const char* name, Shape shape) {
    if (left_ == 0 || shape.empty()) return false;
    sb_.add(parent, name, std::move(shape));
    for (Emitter* e = this; e; e = e->parent_) --e->left_;
    return true;
  }

 private:
  SceneBuilder& sb_;
  uint32_t left_;
  Emitter* parent_ = nullptr;
};

osg::Group* addGroup(osg::Group* parent, const std::string& name) {
  osg::ref_ptr<osg::Group> g = new osg::Group;
  g->setName(name);
  parent->addChild(g.get());
  return g.get();
}

osg::MatrixTransform* addTransform(osg::Group* parent, const osg::Matrixd& m,
                                   const std::string& name) {
  osg::ref_ptr<osg::MatrixTransform> t = new osg::MatrixTransform(m);
  t->setName(name);
  parent->addChild(t.get());
  return t.get();
}

osg::Matrixd rotZ(double angle) {
  return osg::Matrixd::rotate(angle, kZ);
}
osg::Matrixd at(double x, double y, double z) {
  return osg::Matrixd::translate(x, y, z);
}

// Groups left empty when a budget ran out are dropped.
void pruneEmpty(osg::Group& g) {
  for (unsigned i = g.getNumChildren(); i-- > 0;) {
    osg::Group* c = g.getChild(i)->asGroup();
    if (!c || dynamic_cast<osg::Geode*>(c)) continue;
    pruneEmpty(*c);
    if (c->getNumChildren() == 0) g.removeChild(i);
  }
}

uint64_t totalTriangles(const std::vector<Leaf>& leaves, double d) {
  uint64_t n = 0;
  for (const auto& l : leaves) n += shapeTriangles(l.shape, d);
  return n;
}

constexpr double kMinDetail = 1e-3, kMaxDetail = 4096;

// The detail factor whose total triangle count is nearest `target` (the total
// is a non-decreasing step function of d; bisect in log space).
double solveDetail(const std::vector<Leaf>& leaves, uint64_t target) {
  double lo = kMinDetail, hi = 1;
  if (totalTriangles(leaves, lo) >= target) return lo;
  while (hi < kMaxDetail && totalTriangles(leaves, hi) < target) lo = hi, hi *= 2;
  if (totalTriangles(leaves, hi) < target) return hi;
  for (int i = 0; i < 40; ++i) {
    double mid = std::sqrt(lo * hi);
    (totalTriangles(leaves, mid) < target ? lo : hi) = mid;
  }
  auto miss = [&](double d) {
    return std::llabs(int64_t(totalTriangles(leaves, d)) - int64_t(target));
  };
  return miss(lo) <= miss(hi) ? lo : hi;
}

using LayoutFn = std::function<void(SceneBuilder&, osg::Group& root, uint32_t geodes)>;

void checkSize(uint64_t triangles, uint32_t geodes) {
  if (triangles == 0) throw Error("scene generator: triangles must be at least 1");
  if (geodes == 0) throw Error("scene generator: geodes must be at least 1");
  if (triangles > 2'000'000'000ull)
    throw Error("scene generator: triangles must be at most 2000000000");
}

// Lays out `geodes` geodes (fewer when even the coarsest tessellation would
// overshoot the budget), then tessellates them at the detail hitting `triangles`.
osg::ref_ptr<osg::Node> generate(const char* name, uint64_t seed, uint64_t triangles,
                                 uint32_t geodes, const Palette& pal, const LayoutFn& layout) {
  checkSize(triangles, geodes);
  for (int attempt = 0;; ++attempt) {
    SceneBuilder sb(seed, pal);
    osg::ref_ptr<osg::Group> root = new osg::Group;
    root->setName(name);
    layout(sb, *root, geodes);
    uint64_t coarsest = totalTriangles(sb.leaves, kMinDetail);
    if (coarsest > triangles && geodes > 1 && attempt < 8) {
      geodes = std::max<uint32_t>(1, uint32_t(double(geodes) * triangles / coarsest * 0.9));
      continue;
    }
    double d = solveDetail(sb.leaves, triangles);
    for (auto& l : sb.leaves) l.geode->addDrawable(buildGeometry(l.shape, d, pal).get());
    pruneEmpty(*root);
    return root;
  }
}

osg::Vec4 rgb(float r, float g, float b) {
  return {r, g, b, 1};
}

// ================================================================== plant

namespace plant {

enum Colour { Steel, Yellow, Green, Blue, Red, Concrete, White, Rust };
const Palette kPalette{
    {rgb(0.55f, 0.57f, 0.60f), rgb(0.90f, 0.75f, 0.10f), rgb(0.25f, 0.50f, 0.30f),
     rgb(0.20f, 0.35f, 0.65f), rgb(0.70f, 0.15f, 0.12f), rgb(0.70f, 0.68f, 0.63f),
     rgb(0.88f, 0.88f, 0.85f), rgb(0.60f, 0.35f, 0.20f)},
    Rust};

constexpr double kHalf = 50, kStoreyH = 10, kSlab = 0.3;
constexpr int kStoreys = 4;

struct Bay {
  double w;                  // bay edge length
  bool top;                  // top storey: has a roof slab
  std::array<bool, 4> edge;  // sides +x, +y, -x, -y lie on the section boundary
  double ceiling() const { return kStoreyH - (top ? kSlab : 0); }
};

// A unit's room: footprint half-size and free height above the floor slab.
struct Room {
  double rho, hmax;
};

int pipeColour(Rng& rng) {
  return rng.pick({Green, Blue, Red, Yellow, Steel, White});
}

// Pipe through the given points, radius r.
Shape pipe(Rng& rng, std::vector<V3> path, double r) {
  return curvedShape(pipeColour(rng)).tube(std::move(path), r);
}

// H-section member from z0 to z1 at (x, y), flange width f.
void hColumn(Shape& s, double x, double y, double z0, double z1, double f) {
  double t = f * 0.1, h = f / 2;
  s.box({x - h, y - h, z0}, {x + h, y - h + t, z1});
  s.box({x - h, y + h - t, z0}, {x + h, y + h, z1});
  s.box({x - t / 3, y - h, z0}, {x + t / 3, y + h, z1});
}

// I-beam along x from x0 to x1, top at z, depth dz, flange width f, centred on y.
void iBeamX(Shape& s, double x0, double x1, double y, double z, double dz, double f) {
  double t = dz * 0.08;
  s.box({x0, y - f / 2, z - t}, {x1, y + f / 2, z});
  s.box({x0, y - f / 2, z - dz}, {x1, y + f / 2, z - dz + t});
  s.box({x0, y - t / 3, z - dz}, {x1, y + t / 3, z});
}

// Wall on side k of the bay, with a door or window opening most of the time.
Shape wall(const Bay& b, int k, Rng& rng) {
  Shape s = flatShape(rng.pick({Concrete, Concrete, White}));
  double h = b.w / 2, x0 = h - 0.25, z0 = kSlab, z1 = b.ceiling();
  if (b.w < 3.5 || rng.chance(0.2)) {
    s.box({x0, -h, z0}, {h, h, z1});
  } else {
    double ow = rng.uniform(1.2, std::min(4.0, b.w * 0.4));
    double oc = rng.uniform(-h + ow / 2 + 0.4, h - ow / 2 - 0.4);
    bool door = rng.chance(0.5);
    double oz0 = door ? z0 : rng.uniform(1.0, 2.5);
    double oz1 = std::min(z1 - 0.5, oz0 + rng.uniform(2.0, 3.5));
    s.box({x0, -h, z0}, {h, oc - ow / 2, z1});
    s.box({x0, oc + ow / 2, z0}, {h, h, z1});
    s.box({x0, oc - ow / 2, oz1}, {h, oc + ow / 2, z1});
    if (!door) s.box({x0, oc - ow / 2, z0}, {h, oc + ow / 2, oz0});
  }
  s.transform(rotZ(k * kPi / 2));
  return s;
}

// Two flights with a landing, stringers as oriented boxes along the slope.
Shape stairs(const Bay& b, Rng& rng) {
  Shape s = flatShape(rng.pick({Yellow, Steel}));
  double z0 = kSlab, z2 = b.ceiling(), z1 = (z0 + z2) / 2;
  int n = std::max(4, int(std::lround((z1 - z0) / 0.25)));
  double rise = (z1 - z0) / n, run = std::min(0.28, (b.w - 2.2) / n);
  if (run < 0.12) return s;  // bay too small for stairs
  double x0 = -b.w / 2 + 0.5, y0 = -b.w / 2 + 0.5, yl = y0 + n * run;
  for (int k = 0; k < n; ++k) {
    s.box({x0, y0 + k * run, z0 + k * rise}, {x0 + 1.1, y0 + (k + 1) * run, z0 + (k + 1) * rise});
    s.box({x0 + 1.2, yl - (k + 1) * run, z1 + k * rise},
          {x0 + 2.3, yl - k * run, z1 + (k + 1) * rise});
  }
  s.box({x0, yl, z1 - 0.15}, {x0 + 2.3, yl + 1.1, z1});
  for (int f = 0; f < 2; ++f) {
    V3 slope(0, (f ? -1 : 1) * n * run, z1 - z0);
    V3 c(x0 + (f ? 2.35 : -0.05), y0 + n * run / 2, (f ? z1 : z0) + (z1 - z0) / 2 - 0.1);
    V3 across = normalized(V3(0, -slope.z(), slope.y())) * 0.15;
    s.obox(c, V3(0.05, 0, 0), slope * 0.5, across);
  }
  return s;
}

void structure(Emitter& e, osg::Group* bay, const Bay& b, Rng& rng, double stairChance) {
  osg::Group* g = addGroup(bay, "structure");
  double h = b.w / 2;
  e.add(g, "floor", flatShape(Concrete).box({-h, -h, 0}, {h, h, kSlab}));
  if (b.top) e.add(g, "roof", flatShape(Concrete).box({-h, -h, b.ceiling()}, {h, h, kStoreyH}));
  Shape col = flatShape(rng.pick({Steel, Yellow, Blue}));
  hColumn(col, -h + 0.2, -h + 0.2, kSlab, b.ceiling(), 0.35);
  e.add(g, "column", std::move(col));
  for (int k = 0; k < 4; ++k)
    if (b.edge[k] ? rng.chance(0.8) : rng.chance(0.08)) e.add(g, "wall", wall(b, k, rng));
  Shape beams = flatShape(rng.pick({Steel, Yellow, Blue}));
  iBeamX(beams, -h, h, -h + 0.2, b.ceiling(), 0.5, 0.25);
  Shape cross = flatShape(0);
  iBeamX(cross, -h, h, h - 0.2, b.ceiling(), 0.5, 0.25);
  cross.transform(rotZ(kPi / 2));  // now along y at x = -h + 0.2
  beams.boxes.insert(beams.boxes.end(), cross.boxes.begin(), cross.boxes.end());
  e.add(g, "beams", std::move(beams));
  if (rng.chance(stairChance)) e.add(g, "stairs", stairs(b, rng));
}

// ---- equipment units, each in its own frame: origin on the floor at the unit centre

void tank(Emitter& e, osg::Group* u, const Room& room, Rng& rng) {
  osg::Group* g = addGroup(u, "tank");
  double r = room.rho * rng.uniform(0.45, 0.8), legH = rng.uniform(0.3, 1.0);
  double h = std::max(1.0, rng.uniform(0.35, 0.85) * (room.hmax - legH - 0.5 * r));
  e.add(g, "vessel",
        curvedShape(rng.pick({White, Steel, Blue, Green}))
            .cyl({.base = {0, 0, legH},
                  .axis = {0, 0, h},
                  .r = r,
                  .cap0 = Cap::Flat,
                  .cap1 = Cap::Dome}));
  Shape legs = flatShape(Steel);
  for (int i = 0; i < 4; ++i) {
    double x = (i & 1 ? 0.7 : -0.7) * r, y = (i & 2 ? 0.7 : -0.7) * r;
    legs.box({x - 0.08, y - 0.08, 0}, {x + 0.08, y + 0.08, legH + 0.3});
  }
  e.add(g, "legs", std::move(legs));
  double a = rng.uniform(0, 2 * kPi), pr = rng.uniform(0.05, 0.15), side = rng.chance(0.5) ? 1 : -1;
  V3 dir(std::cos(a), std::sin(a), 0), tang = kZ ^ dir;
  V3 p0 = dir * (r * 0.9) + V3(0, 0, legH + h * rng.uniform(0.15, 0.6));
  V3 p1 = p0 + dir * rng.uniform(0.4, 1.0);
  V3 p2(p1.x(), p1.y(), 0.15 + pr);
  e.add(g, "nozzle", pipe(rng, {p0, p1, p2, p2 + tang * (side * rng.uniform(0.5, 1.5))}, pr));
  if (rng.chance(0.4)) {
    Shape ladder = flatShape(Yellow);
    for (double y : {-0.25, 0.2}) ladder.box({r + 0.2, y, legH}, {r + 0.25, y + 0.05, legH + h});
    for (double z = legH + 0.4; z < legH + h; z += 0.6)
      ladder.box({r + 0.2, -0.2, z}, {r + 0.24, 0.2, z + 0.03});
    e.add(g, "ladder", std::move(ladder.transform(rotZ(a + kPi))));
  }
  if (rng.chance(0.7)) {
    double tr = rng.uniform(0.04, 0.12);
    V3 q0(0, 0, legH + h + 0.4 * r), q1 = q0 + kZ * rng.uniform(0.4, 1.0);
    V3 q2 = q1 + tang * (room.rho * rng.uniform(0.8, 1.2));
    e.add(g, "pipe", pipe(rng, {q0, q1, q2, V3(q2.x(), q2.y(), rng.uniform(0.2, 1.0))}, tr));
  }
}

void hvessel(Emitter& e, osg::Group* u, const Room& room, Rng& rng) {
  osg::Group* g = addGroup(u, "vessel");
  double len = 2 * room.rho * rng.uniform(0.6, 0.95);
  double r = std::min(room.rho * 0.45, len * 0.25) * rng.uniform(0.7, 1.0);
  double zc = r + rng.uniform(0.3, 0.8);
  e.add(g, "drum",
        curvedShape(rng.pick({White, Steel, Green}))
            .cyl({.base = {-len / 2 + r * 0.5, 0, zc},
                  .axis = {len - r, 0, 0},
                  .r = r,
                  .cap0 = Cap::Dome,
                  .cap1 = Cap::Dome}));
  Shape saddles = flatShape(Steel);
  for (double x : {-0.3 * len, 0.3 * len})
    saddles.box({x - 0.15, -r * 0.8, 0}, {x + 0.15, r * 0.8, zc - r * 0.5});
  e.add(g, "saddles", std::move(saddles));
  int nozzles = rng.range(1, 2);
  for (int i = 0; i < nozzles; ++i) {
    double pr = rng.uniform(0.05, 0.12), x = rng.uniform(-0.3, 0.3) * len;
    V3 p0(x, 0, zc + r * 0.9), p1 = p0 + kZ * rng.uniform(0.5, 1.2);
    V3 p2 = p1 + V3(0, rng.chance(0.5) ? room.rho : -room.rho, 0);
    e.add(g, "nozzle", pipe(rng, {p0, p1, p2, p2 + kZ * rng.uniform(0.5, 2.0)}, pr));
  }
}

void pump(Emitter& e, osg::Group* u, const Room& room, Rng& rng) {
  osg::Group* g = addGroup(u, "pump");
  double l = room.rho * 0.8, rc = std::min(0.4, room.rho * 0.2) * rng.uniform(0.7, 1.0);
  double zc = 0.2 + rc + 0.1;
  e.add(g, "skid", flatShape(Steel).box({-l, -l / 2, 0}, {l, l / 2, 0.2}));
  Shape body = curvedShape(rng.pick({Blue, Green, Red}));
  body.cyl({.base = {-l * 0.4, -rc * 0.6, zc},
            .axis = {0, rc * 1.2, 0},
            .r = rc,
            .cap0 = Cap::Flat,
            .cap1 = Cap::Flat});
  body.cyl({.base = {-l * 0.4 + rc + 0.15, 0, zc},
            .axis = {l * 1.1, 0, 0},
            .r = rc * 0.8,
            .cap0 = Cap::Flat,
            .cap1 = Cap::Dome,
            .domeRatio = 0.3});
  e.add(g, "body", std::move(body));
  double pr = rc * 0.5;
  V3 s0(-l * 0.4 - rc * 0.9, 0, zc), s1(-l - 0.3, 0, zc);
  e.add(g, "suction", pipe(rng, {s0, s1, s1 + kZ * rng.uniform(0.5, 2.0)}, pr));
  V3 d0(-l * 0.4, 0, zc + rc * 0.9), d1 = d0 + kZ * rng.uniform(0.6, 1.2);
  V3 d2 = d1 + V3(0, rng.chance(0.5) ? l : -l, 0);
  V3 d3(d2.x(), d2.y(), room.hmax * rng.uniform(0.5, 0.9));
  e.add(g, "discharge", pipe(rng, {d0, d1, d2, d3}, pr * 0.8));
  e.add(g, "guard",
        flatShape(Yellow).box({-l * 0.4 + rc, -rc * 0.7, 0.2},
                              {-l * 0.4 + rc + 0.3, rc * 0.7, zc + rc * 0.7}));
}

void exchanger(Emitter& e, osg::Group* u, const Room& room, Rng& rng) {
  osg::Group* g = addGroup(u, "exchanger");
  double len = 2 * room.rho * 0.9, r = room.rho * rng.uniform(0.2, 0.35), zc = r + 0.5;
  Shape shell = curvedShape(rng.pick({Steel, White, Rust}));
  shell.cyl({.base = {-len / 2 + 0.6, 0, zc},
             .axis = {len - 0.6 - r * 0.5, 0, 0},
             .r = r,
             .cap1 = Cap::Dome});
  shell.cyl({.base = {-len / 2, 0, zc},
             .axis = {0.6, 0, 0},
             .r = r * 1.1,
             .cap0 = Cap::Flat,
             .cap1 = Cap::Flat});
  for (double x : {-len / 4, len / 4})
    shell.cyl(
        {.base = {x, 0, zc + r * 0.8}, .axis = {0, 0, r * 0.6}, .r = r * 0.25, .cap1 = Cap::Flat});
  e.add(g, "shell", std::move(shell));
  Shape saddles = flatShape(Steel);
  for (double x : {-len / 3, len / 3}) saddles.box({x - 0.12, -r, 0}, {x + 0.12, r, zc - r * 0.6});
  e.add(g, "saddles", std::move(saddles));
  for (double x : {-len / 4, len / 4}) {
    V3 p0(x, 0, zc + r * 1.3), p1 = p0 + kZ * rng.uniform(0.4, 1.5);
    V3 p2 = p1 + V3(0, rng.chance(0.5) ? room.rho * 1.2 : -room.rho * 1.2, 0);
    e.add(g, "pipe", pipe(rng, {p0, p1, p2}, r * 0.2));
  }
}

// Pipe rack: two portal frames carrying parallel pipes, some turning down at the end.
void rack(Emitter& e, osg::Group* u, const Room& room, Rng& rng, double span) {
  osg::Group* g = addGroup(u, "rack");
  double zr = room.hmax * rng.uniform(0.5, 0.8), w = std::min(2.0, room.rho), L = span / 2;
  Shape frame = flatShape(rng.pick({Steel, Yellow}));
  for (double x : {-L + 0.15, L - 0.15}) {
    for (double y : {-w / 2, w / 2}) frame.box({x - 0.1, y - 0.1, 0}, {x + 0.1, y + 0.1, zr - 0.2});
    frame.box({x - 0.1, -w / 2 - 0.1, zr - 0.2}, {x + 0.1, w / 2 + 0.1, zr});
  }
  for (double y : {-w / 2, w / 2}) frame.box({-L, y - 0.08, zr - 0.15}, {L, y + 0.08, zr});
  e.add(g, "frame", std::move(frame));
  int n = rng.range(2, 6);
  for (int i = 0; i < n; ++i) {
    double pr = rng.uniform(0.05, std::min(0.2, w / (2.5 * n))), y = -w / 2 + w * (i + 0.5) / n;
    double z = zr + pr + 0.02;
    std::vector<V3> path{{-L, y, z}, {L, y, z}};
    if (rng.chance(0.35)) {
      double x = L - rng.uniform(0.4, 1.5);
      path = {{-L, y, z}, {x, y, z}, {x, y, rng.uniform(0.3, std::max(0.4, z - 1.0))}};
    }
    e.add(g, "pipe", pipe(rng, std::move(path), pr));
  }
}

void duct(Emitter& e, osg::Group* u, const Room& room, Rng& rng, double span) {
  Shape s = flatShape(rng.pick({Steel, White}));
  double a = rng.uniform(0.3, 0.5), b = rng.uniform(0.2, 0.3), L = span / 2;
  double zd = room.hmax * rng.uniform(0.6, 0.9), x1 = L * rng.uniform(0.2, 0.8);
  s.box({-L, -a, zd - b}, {x1 + a, a, zd + b});
  double zb = rng.chance(0.5) ? 0.5 : room.hmax;
  s.box({x1 - a, -a, std::min(zb, zd - b)}, {x1 + a, a, std::max(zb, zd + b)});
  for (double x : {-L + 0.1, (x1 - L) / 2})
    s.box({x - 0.04, -a - 0.05, zd - b - 0.05}, {x + 0.04, a + 0.05, zd + b + 0.05});
  e.add(u, "duct", std::move(s));
}

// Random walks along the axes, the typical tangle of small-bore pipework.
void pipework(Emitter& e, osg::Group* u, const Room& room, Rng& rng) {
  osg::Group* g = addGroup(u, "pipework");
  int runs = rng.range(2, 4);
  double lim[3] = {room.rho * 1.3, room.rho * 1.3, room.hmax};
  for (int i = 0; i < runs; ++i) {
    double pr = rng.uniform(0.03, 0.15), lo[3] = {-lim[0], -lim[1], 0.3 + pr};
    V3 p(rng.uniform(lo[0], lim[0]), rng.uniform(lo[1], lim[1]), rng.uniform(lo[2], lim[2]));
    std::vector<V3> path{p};
    int axis = -1, segs = rng.range(2, 6);
    for (int k = 0; k < segs; ++k) {
      axis = (axis + rng.range(1, 2)) % 3;  // never the same axis twice: only 90 degree elbows
      double v = rng.uniform(lo[axis], lim[axis]);
      if (std::fabs(v - p[axis]) < 0.8) v = p[axis] + (p[axis] + 0.8 <= lim[axis] ? 0.8 : -0.8);
      p[axis] = v;
      path.push_back(p);
    }
    e.add(g, "pipe", pipe(rng, std::move(path), pr));
  }
}

void manifold(Emitter& e, osg::Group* u, const Room& room, Rng& rng) {
  osg::Group* g = addGroup(u, "manifold");
  double zh = rng.uniform(0.6, 1.4), hr = rng.uniform(0.08, 0.15), L = room.rho * 0.9;
  Shape s = curvedShape(pipeColour(rng));
  s.tube({{-L, 0, zh}, {L, 0, zh}}, hr);
  int n = rng.range(3, 6);
  for (int i = 0; i < n; ++i) {
    double x = -L + 2 * L * (i + 0.5) / n, br = hr * 0.6, zv = zh * 0.5;
    bool up = rng.chance(0.3);
    s.tube({{x, 0, zh}, {x, 0, up ? zh + rng.uniform(0.5, 2.0) : 0.2}}, br);
    if (up) continue;
    s.cyl({.base = {x, 0, zv - 0.15},
           .axis = {0, 0, 0.3},
           .r = br * 2,
           .cap0 = Cap::Flat,
           .cap1 = Cap::Flat});
    s.torus({.c = {x, -br * 2 - 0.1, zv},
             .axis = {0, 1, 0},
             .start = {1, 0, 0},
             .R = 0.12,
             .r = 0.012});
  }
  e.add(g, "header", std::move(s));
  Shape stand = flatShape(Steel);
  for (double x : {-L * 0.8, L * 0.8}) stand.box({x - 0.05, -0.05, 0}, {x + 0.05, 0.05, zh - hr});
  e.add(g, "stand", std::move(stand));
}

void cabinets(Emitter& e, osg::Group* u, const Room& room, Rng& rng) {
  osg::Group* g = addGroup(u, "cabinets");
  int n = std::max(1, std::min(rng.range(2, 5), int(2 * room.rho / 0.82)));
  double x0 = -n * 0.41, h = rng.uniform(2.0, 2.3);
  Shape s = flatShape(rng.pick({Steel, White, Blue}));
  for (int i = 0; i < n; ++i) s.box({x0 + i * 0.82, -0.3, 0.1}, {x0 + i * 0.82 + 0.8, 0.3, h});
  s.box({x0, -0.32, 0}, {-x0, 0.32, 0.1});
  e.add(g, "cabinet", std::move(s));
  Shape tray = flatShape(Yellow);
  tray.box({x0, -0.15, h}, {x0 + 0.3, 0.15, room.hmax});
  tray.box({x0, -0.15, room.hmax - 0.1}, {x0 + 2 * room.rho, 0.15, room.hmax});
  e.add(g, "tray", std::move(tray));
}

enum Kind { Tank, HVessel, Pump, Exchanger, Rack, Duct, Pipework, Manifold, Cabinets };

// Floor equipment first; later passes over the same slots add overhead services.
Kind pickKind(int pass, Rng& rng) {
  static const double kFirst[] = {3, 2, 2, 1.5, 1, 0.5, 1.5, 1.5, 1};
  static const double kLater[] = {0.5, 0.3, 0.5, 0.2, 2, 1, 3.5, 1, 0.5};
  const double* w = pass == 0 ? kFirst : kLater;
  double sum = 0;
  for (int i = 0; i < 9; ++i) sum += w[i];
  double x = rng.uniform(0, sum);
  for (int i = 0; i < 9; ++i)
    if ((x -= w[i]) < 0) return Kind(i);
  return Cabinets;
}

void unitContent(Kind kind, Emitter& e, osg::Group* u, const Room& room, Rng& rng, double slot) {
  switch (kind) {
    case Tank:
      return tank(e, u, room, rng);
    case HVessel:
      return hvessel(e, u, room, rng);
    case Pump:
      return pump(e, u, room, rng);
    case Exchanger:
      return exchanger(e, u, room, rng);
    case Rack:
      return rack(e, u, room, rng, slot);
    case Duct:
      return duct(e, u, room, rng, slot);
    case Pipework:
      return pipework(e, u, room, rng);
    case Manifold:
      return manifold(e, u, room, rng);
    case Cabinets:
      return cabinets(e, u, room, rng);
  }
}

// Fills the bay's slots with equipment units until the bay's geode quota is spent.
void equipment(Emitter& e, osg::Group* bay, const Bay& b, Rng& rng) {
  int m = std::max(1, int(std::lround(b.w / 4.5)));
  double sw = b.w / m;
  std::vector<int> order(m * m);
  for (int i = 0; i < m * m; ++i) order[i] = i;
  for (int i = m * m - 1; i > 0; --i) std::swap(order[i], order[rng.range(0, i)]);
  Room room{0.42 * sw, b.ceiling() - kSlab - 1.0};
  for (int n = 0; e.left() > 0 && n < 100000; ++n) {
    int slot = order[n % (m * m)], pass = n / (m * m);
    double x = -b.w / 2 + (slot % m + 0.5) * sw + rng.uniform(-0.05, 0.05) * sw;
    double y = -b.w / 2 + (slot / m + 0.5) * sw + rng.uniform(-0.05, 0.05) * sw;
    Kind kind = pickKind(pass, rng);
    bool aligned = kind == Rack || kind == Duct || rng.chance(pass == 0 ? 0.7 : 0.5);
    double angle = aligned ? rng.range(0, 3) * kPi / 2 : rng.uniform(0, 2 * kPi);
    osg::MatrixTransform* u = addTransform(bay, rotZ(angle) * at(x, y, kSlab), "unit");
    unitContent(kind, e, u, room, rng, sw);
  }
}

void layout(SceneBuilder& sb, osg::Group& root, uint32_t geodes, uint64_t seed) {
  // ~80 geodes a bay at any size: more geodes means more, smaller bays.
  int nb = std::max(1, int(std::lround(std::sqrt(geodes / (16 * 80.0)))));
  double w = kHalf / nb;
  uint64_t bays = 16ull * nb * nb, index = 0;
  Emitter all(sb, geodes);
  Rng top = substream(seed, 1);
  for (int sec = 0; sec < 4; ++sec) {
    double cx = (sec & 1 ? 0.5 : -0.5) * kHalf, cy = (sec & 2 ? 0.5 : -0.5) * kHalf;
    osg::MatrixTransform* section = addTransform(
        &root, rotZ(top.range(0, 3) * kPi / 2) * at(cx, cy, 0), "section-" + std::to_string(sec));
    for (int st = 0; st < kStoreys; ++st) {
      osg::MatrixTransform* storey =
          addTransform(section, at(0, 0, st * kStoreyH), "storey-" + std::to_string(st));
      for (int j = 0; j < nb; ++j) {
        osg::Group* row = addGroup(storey, "row-" + std::to_string(j));
        for (int i = 0; i < nb; ++i, ++index) {
          Bay b{w, st == kStoreys - 1, {i == nb - 1, j == nb - 1, i == 0, j == 0}};
          uint32_t quota = uint32_t(geodes * (index + 1) / bays - geodes * index / bays);
          Emitter e = all.sub(quota);
          Rng rng = substream(seed, 1000 + index);
          osg::MatrixTransform* bay = addTransform(
              row, at(-kHalf / 2 + (i + 0.5) * w, -kHalf / 2 + (j + 0.5) * w, 0), "bay");
          {
            // Structure takes at most half the bay, so tiny budgets still get
            // curved equipment whose tessellation can absorb the triangle target.
            Emitter es = e.sub(std::max<uint32_t>(1, quota / 2));
            structure(es, bay, b, rng, std::min(1.0, 1.5 / (nb * nb)));
          }
          equipment(e, bay, b, rng);
        }
      }
    }
  }
}

}  // namespace plant

// ================================================================== monument

namespace monument {

enum Colour { Marble, Sandstone, Granite, Terracotta, Verdigris, Gold, Slate, Brick };
const Palette kPalette{
    {rgb(0.92f, 0.90f, 0.85f), rgb(0.82f, 0.70f, 0.50f), rgb(0.50f, 0.48f, 0.47f),
     rgb(0.72f, 0.40f, 0.28f), rgb(0.35f, 0.60f, 0.50f), rgb(0.85f, 0.68f, 0.25f),
     rgb(0.35f, 0.38f, 0.42f), rgb(0.60f, 0.30f, 0.22f)},
    Gold};

constexpr double kHalf = 200, kWallT = 2.5, kWallH = 12, kCell = 1.5;

// A fluted, tapering column with base, echinus and capital, under its own transform.
void column(Emitter& e, osg::Group* parent, V3 pos, double r, double h, Rng& rng) {
  if (e.left() == 0) return;
  osg::MatrixTransform* t =
      addTransform(parent, rotZ(rng.uniform(0, 2 * kPi)) * at(pos.x(), pos.y(), pos.z()), "col");
  double hb = h * 0.04, hc = h * 0.05, hs = h - hb - hc;
  Shape s = curvedShape(rng.pick({Marble, Marble, Sandstone}));
  s.cyl({.base = {0, 0, 0},
         .axis = {0, 0, hb},
         .r = r * 1.3,
         .cap0 = Cap::Flat,
         .cap1 = Cap::Flat,
         .weight = 1.5});
  s.cyl({.base = {0, 0, hb},
         .axis = {0, 0, hs},
         .r = r,
         .weight = 2,
         .aspect = 3,
         .taper = 0.12,
         .flute = 0.035,
         .flutes = 20});
  s.torus({.c = {0, 0, hb + hs},
           .axis = kZ,
           .start = {1, 0, 0},
           .R = r * 0.92,
           .r = r * 0.2,
           .weight = 1.5});
  s.cyl({.base = {0, 0, hb + hs},
         .axis = {0, 0, hc},
         .r = r * 1.35,
         .cap0 = Cap::Flat,
         .cap1 = Cap::Flat,
         .weight = 1.5});
  e.add(t, "column", std::move(s));
}

// A ring of n tangential beams at radius rc between heights z0 and z1.
Shape ringBeam(int colour, double rc, double depth, double z0, double z1, int n) {
  Shape s = flatShape(colour);
  for (int i = 0; i < n; ++i) {
    double a = 2 * kPi * (i + 0.5) / n, half = rc * std::sin(kPi / n) * 1.03;
    V3 rad(std::cos(a), std::sin(a), 0), tan = kZ ^ rad;
    s.obox(rad * rc + kZ * ((z0 + z1) / 2), rad * (depth / 2), tan * half, kZ * ((z1 - z0) / 2),
           kCell);
  }
  return s;
}

void rotunda(Emitter& e, osg::Group& root, Rng& rng) {
  osg::MatrixTransform* c = addTransform(&root, rotZ(rng.uniform(0, 2 * kPi)), "centre");
  osg::Group* g = addGroup(c, "rotunda");
  const double rp = 38, zp = 1.6, rc = 31, colH = 16, rd = 24, drumH = 18;
  e.add(g, "podium", flatShape(Marble).box({-rp, -rp, 0}, {rp, rp, zp}, 2.0));
  e.add(g, "dome",
        curvedShape(Verdigris).dome(
            {.c = {0, 0, zp + drumH}, .up = kZ, .r = rd, .ratio = 1, .weight = 1.5}));
  e.add(g, "drum",
        curvedShape(Sandstone).cyl(
            {.base = {0, 0, zp}, .axis = {0, 0, drumH}, .r = rd, .aspect = 6}));
  e.add(g, "entablature", ringBeam(Marble, rc, 3.4, zp + colH, zp + colH + 2.2, 32));
  e.add(g, "lantern",
        curvedShape(Gold).cyl({.base = {0, 0, zp + drumH + rd - 0.5},
                               .axis = {0, 0, 5},
                               .r = 3,
                               .cap1 = Cap::Dome,
                               .domeRatio = 1}));
  Shape steps = flatShape(Marble);
  for (int k = 0; k < 4; ++k) {
    Shape side = flatShape(Marble);
    for (int i = 0; i < 3; ++i) side.box({rp, -10, 0}, {rp + (3 - i) * 0.6, 10, zp * (i + 1) / 4});
    side.transform(rotZ(k * kPi / 2));
    steps.boxes.insert(steps.boxes.end(), side.boxes.begin(), side.boxes.end());
  }
  e.add(g, "steps", std::move(steps));
  osg::Group* ring = addGroup(g, "colonnade");
  uint32_t n = e.left();
  for (uint32_t i = 0; i < n; ++i) {
    double a = 2 * kPi * i / n;
    column(e, ring, {rc * std::cos(a), rc * std::sin(a), zp}, 1.2, colH, rng);
  }
}

constexpr double kGate0 = 93, kGate1 = 107, kEdgeEnd = kHalf - 14;  // tower plinth at the corner
constexpr double kWallRun = kGate0 + (kEdgeEnd - kGate1);           // wall length per edge

// Wall from run position u0 to u1 along one edge (the x = kHalf edge when
// alongY, else y = kHalf), skipping the gateway, with merlons on top.
Shape wallSegment(double u0, double u1, bool alongY, Rng& rng) {
  Shape s = flatShape(rng.chance(0.8) ? Sandstone : Brick);
  auto box = [&](double a, double b, double z0, double z1, double cell) {
    V3 lo(kHalf - kWallT, a, z0), hi(kHalf, b, z1);
    if (!alongY) lo = V3(lo.y(), lo.x(), z0), hi = V3(hi.y(), hi.x(), z1);
    s.box(lo, hi, cell);
  };
  auto piece = [&](double a, double b) {
    box(a, b, 0, kWallH, kCell);
    for (double u = a + 0.75; u + 1.5 <= b; u += 3.0) box(u, u + 1.5, kWallH, kWallH + 1.3, 0);
  };
  if (u0 < kGate0) piece(u0, std::min(u1, kGate0));
  if (u1 > kGate0) piece(std::max(u0, kGate0) - kGate0 + kGate1, u1 - kGate0 + kGate1);
  return s;
}

void gate(Emitter& e, osg::Group* parent, const osg::Matrixd& m, Rng& rng) {
  osg::MatrixTransform* t = addTransform(parent, m, "gate");
  Shape pylons = flatShape(Sandstone);
  for (double y : {-7.0, 3.0}) pylons.box({-2, y, 0}, {2, y + 4, 16}, kCell);
  e.add(t, "pylons", std::move(pylons));
  e.add(t, "arch",
        curvedShape(Marble).torus({.c = {0, 0, 8},
                                   .axis = {1, 0, 0},
                                   .start = {0, 1, 0},
                                   .R = 3.4,
                                   .r = 0.5,
                                   .sweep = kPi,
                                   .weight = 1.5}));
  e.add(t, "attic", flatShape(Marble).box({-1.6, -3, 12}, {1.6, 3, 15}, kCell));
  Shape domes = curvedShape(rng.pick({Verdigris, Gold}));
  for (double y : {-5.0, 5.0}) domes.dome({.c = {0, y, 16}, .up = kZ, .r = 2, .ratio = 1.3});
  e.add(t, "domes", std::move(domes));
}

// Walls, a corner tower and two gateways along the quarter's outer edges.
void enclosure(Emitter& e, osg::Group* quarter, Rng& rng) {
  osg::Group* g = addGroup(quarter, "enclosure");
  int segs = std::max(4, int(e.left()) - 10);
  for (int i = 0; i < segs; ++i) {
    bool alongY = i % 2 == 0;  // alternate edges so a small budget still walls both
    int n = alongY ? (segs + 1) / 2 : segs / 2, k = i / 2;
    e.add(g, "wall", wallSegment(kWallRun * k / n, kWallRun * (k + 1) / n, alongY, rng));
  }
  osg::MatrixTransform* tw = addTransform(g, at(kHalf - 7, kHalf - 7, 0), "tower");
  e.add(tw, "tower",
        curvedShape(Sandstone).cyl({.base = {0, 0, 1.5},
                                    .axis = {0, 0, 20},
                                    .r = 6.5,
                                    .cap1 = Cap::Dome,
                                    .domeRatio = 0.9,
                                    .aspect = 6}));
  e.add(tw, "plinth", flatShape(Granite).box({-7, -7, 0}, {7, 7, 1.5}, kCell));
  gate(e, g, at(kHalf - kWallT / 2, 100, 0), rng);
  gate(e, g, rotZ(kPi / 2) * at(100, kHalf - kWallT / 2, 0), rng);
}

// A round tholos: podium, ring of columns, ring beam and dome.
void pavilion(Emitter& e, osg::Group* s, double f, Rng& rng) {
  double rc = f * 0.32, cr = std::clamp(f * 0.022, 0.25, 0.8), ch = std::clamp(f * 0.28, 3.0, 10.0);
  e.add(s, "podium", flatShape(Marble).box({-f / 2, -f / 2, 0}, {f / 2, f / 2, 1.0}, kCell));
  e.add(s, "dome",
        curvedShape(rng.pick({Verdigris, Terracotta, Gold}))
            .dome({.c = {0, 0, 1.0 + ch + 1.2},
                   .up = kZ,
                   .r = rc + cr * 1.5,
                   .ratio = 0.7,
                   .weight = 1.2}));
  e.add(s, "beam", ringBeam(Marble, rc, cr * 3, 1.0 + ch, 1.0 + ch + 1.2, 12));
  osg::Group* cols = addGroup(s, "columns");
  uint32_t n = e.left();
  for (uint32_t i = 0; i < n; ++i) {
    double a = 2 * kPi * i / n;
    column(e, cols, {rc * std::cos(a), rc * std::sin(a), 1.0}, cr, ch, rng);
  }
}

// A stoa: stylobate, one or two rows of columns, architrave and pitched roof.
void stoa(Emitter& e, osg::Group* s, double f, Rng& rng) {
  double dd = f * 0.3, ch = std::clamp(f * 0.2, 3.0, 8.0), zb = 0.8, zt = zb + ch;
  e.add(s, "stylobate", flatShape(Marble).box({-f / 2, -dd / 2, 0}, {f / 2, dd / 2, zb}, kCell));
  e.add(s, "architrave",
        flatShape(Marble).box({-f / 2 + 0.3, -dd / 2 + 0.3, zt},
                              {f / 2 - 0.3, dd / 2 - 0.3, zt + 1}, kCell));
  Shape roof = flatShape(Terracotta);
  double pitch = 0.35, half = dd / 4 / std::cos(pitch);
  for (int side : {-1, 1}) {
    V3 slope(0, -side * std::cos(pitch), std::sin(pitch));
    roof.obox({0, side * dd / 4, zt + 1 + dd / 4 * std::tan(pitch) + 0.15}, {f / 2, 0, 0},
              slope * half, (V3(1, 0, 0) ^ slope) * 0.15, kCell);
  }
  e.add(s, "roof", std::move(roof));
  osg::Group* cols = addGroup(s, "columns");
  int n = int(e.left()), rows = n >= 8 ? 2 : 1, per = (n + rows - 1) / std::max(rows, 1);
  double cr = std::clamp(f / std::max(per, 1) * 0.15, 0.2, 0.7);
  for (int i = 0; i < n; ++i) {
    int row = i / std::max(per, 1), k = i % std::max(per, 1);
    double y = rows == 1 ? 0 : (row ? 1 : -1) * (dd / 2 - 0.8);
    column(e, cols, {-f / 2 + (k + 0.5) * f / per, y, zb}, cr, ch, rng);
  }
}

// A round basin with an obelisk, ringed by free-standing columns.
void fountain(Emitter& e, osg::Group* s, double f, Rng& rng) {
  double rb = f * 0.25;
  Shape basin = curvedShape(Marble);
  basin.torus({.c = {0, 0, 0.6}, .axis = kZ, .start = {1, 0, 0}, .R = rb, .r = 0.3});
  basin.cyl({.base = {0, 0, 0}, .axis = {0, 0, 0.6}, .r = rb, .aspect = 8});
  e.add(s, "basin", std::move(basin));
  Shape ob = flatShape(rng.pick({Granite, Slate}));
  double h = rng.uniform(8, 16), w = 1.2;
  ob.box({-w, -w, 0}, {w, w, 1.2}, kCell);
  for (int i = 0; i < 4; ++i) {
    double z0 = 1.2 + h * i / 4, z1 = 1.2 + h * (i + 1) / 4, ww = w * (0.8 - 0.12 * i);
    ob.box({-ww, -ww, z0}, {ww, ww, z1}, kCell);
  }
  double top = 1.2 + h, tw = w * 0.3;
  ob.obox({0, 0, top + tw * 0.5}, {tw, tw, 0}, {-tw, tw, 0}, {0, 0, tw * 0.5});
  e.add(s, "obelisk", std::move(ob));
  osg::Group* cols = addGroup(s, "columns");
  uint32_t n = e.left();
  for (uint32_t i = 0; i < n; ++i) {
    double a = 2 * kPi * i / n;
    column(e, cols, {f * 0.42 * std::cos(a), f * 0.42 * std::sin(a), 0}, 0.3, 4.5, rng);
  }
}

// The tile's structures: up to ~16 geodes each on a sub-grid of the tile.
void courtyard(Emitter& e, osg::Group* court, V3 origin, double ts, Rng& rng) {
  uint32_t q = e.left(), m = std::max<uint32_t>(1, (q + 15) / 16);
  int g = int(std::ceil(std::sqrt(double(m))));
  double sub = ts / g;
  for (uint32_t i = 0; i < m; ++i) {
    Emitter es = e.sub(uint32_t(uint64_t(q) * (i + 1) / m - uint64_t(q) * i / m));
    V3 c = origin + V3((i % g + 0.5) * sub, (i / g + 0.5) * sub, 0);
    double angle = rng.chance(0.7) ? rng.range(0, 3) * kPi / 2 : rng.uniform(0, 2 * kPi);
    osg::MatrixTransform* s = addTransform(court, rotZ(angle) * at(c.x(), c.y(), 0), "structure");
    double x = rng.uniform(), f = std::min(sub * 0.75, 40.0);
    if (x < 0.45)
      pavilion(es, s, f, rng);
    else if (x < 0.8)
      stoa(es, s, f, rng);
    else
      fountain(es, s, f, rng);
  }
}

void layout(SceneBuilder& sb, osg::Group& root, uint32_t geodes, uint64_t seed) {
  Emitter all(sb, geodes);
  Rng rng = substream(seed, 1);
  {
    Emitter e = all.sub(std::clamp<uint32_t>(geodes / 25, 4, 60));
    rotunda(e, root, rng);
  }
  int k = std::clamp(int(std::lround(std::sqrt(geodes / 64.0))), 1, 10);
  double ts = (kHalf - kWallT) / k;
  struct Tile {
    osg::Group* group;
    V3 origin;
    Rng rng;
  };
  std::vector<Tile> tiles;
  for (int q = 0; q < 4; ++q) {
    Rng rq = substream(seed, 100 + q);
    osg::MatrixTransform* quarter =
        addTransform(&root, rotZ(q * kPi / 2), "quarter-" + std::to_string(q));
    Emitter e = all.sub(std::clamp<uint32_t>(geodes / 40, 3, 60));
    enclosure(e, quarter, rq);
    for (int j = 0; j < k; ++j)
      for (int i = 0; i < k; ++i) {
        osg::Group* court =
            addGroup(quarter, "court-" + std::to_string(i) + "-" + std::to_string(j));
        V3 o(i * ts, j * ts, 0);
        Shape slab = flatShape((i + j) % 2 ? Marble : rq.pick({Sandstone, Granite}));
        all.add(court, "slab", std::move(slab.box(o + V3(0, 0, -0.4), o + V3(ts, ts, 0), 2.0)));
        if (k == 1 || std::hypot(o.x(), o.y()) >= 42)  // the rotunda owns the centre
          tiles.push_back({court, o, substream(seed, 10000 + tiles.size() + q * 1000)});
      }
  }
  uint32_t rest = all.left();
  for (size_t t = 0; t < tiles.size(); ++t) {
    Emitter e = all.sub(
        uint32_t(uint64_t(rest) * (t + 1) / tiles.size() - uint64_t(rest) * t / tiles.size()));
    courtyard(e, tiles[t].group, tiles[t].origin, ts, tiles[t].rng);
  }
}

}  // namespace monument

// ------------------------------------------------------------------ statistics

struct TriangleCounter {
  uint64_t n = 0;
  void operator()(unsigned, unsigned, unsigned) { ++n; }
};

class StatsVisitor : public osg::NodeVisitor {
 public:
  StatsVisitor() : osg::NodeVisitor(TRAVERSE_ALL_CHILDREN) {}
  void apply(osg::Geode& geode) override {
    ++stats.geodeInstances;
    if (geodes_.insert(&geode).second) ++stats.geodes;
    for (unsigned i = 0; i < geode.getNumDrawables(); ++i) {
      const osg::Geometry* g = geode.getDrawable(i)->asGeometry();
      if (!g) continue;
      auto [it, fresh] = tris_.try_emplace(g, 0);
      if (fresh) {
        it->second = countTriangles(*g);
        ++stats.geometries;
        stats.triangles += it->second;
      }
      stats.instancedTriangles += it->second;
    }
  }
  SceneStats stats;

 private:
  std::unordered_set<const osg::Geode*> geodes_;
  std::unordered_map<const osg::Geometry*, uint64_t> tris_;
};

}  // namespace

// ================================================================== public API

osg::ref_ptr<osg::Node> makePlant(const PlantParams& p) {
  return generate("plant", p.seed, p.triangles, p.geodes, plant::kPalette,
                  [&](SceneBuilder& sb, osg::Group& root, uint32_t geodes) {
                    plant::layout(sb, root, geodes, p.seed);
                  });
}

osg::ref_ptr<osg::Node> makeMonument(const MonumentParams& p) {
  return generate("monument", p.seed, p.triangles, p.geodes, monument::kPalette,
                  [&](SceneBuilder& sb, osg::Group& root, uint32_t geodes) {
                    monument::layout(sb, root, geodes, p.seed);
                  });
}

osg::ref_ptr<osg::Node> replicate(osg::Node* input, uint32_t copies, double spacing) {
  if (!input) throw Error("replicate: no input scene");
  if (copies == 0) throw Error("replicate: copies must be at least 1");
  if (!std::isfinite(spacing)) throw Error("replicate: spacing must be a finite number");
  const osg::BoundingSphere& bs = input->getBound();
  if (!bs.valid()) throw Error("replicate: the input scene has no geometry");
  if (spacing <= 0) spacing = bs.radius() > 0 ? 2 * bs.radius() * 1.1 : 1.0;
  uint32_t cols = uint32_t(std::ceil(std::sqrt(double(copies))));
  uint32_t rows = (copies + cols - 1) / cols;
  osg::ref_ptr<osg::Group> root = new osg::Group;
  root->setName("replicate");
  for (uint32_t i = 0; i < copies; ++i) {
    double x = (double(i % cols) - (cols - 1) / 2.0) * spacing;
    double y = (double(i / cols) - (rows - 1) / 2.0) * spacing;
    addTransform(root.get(), at(x, y, 0), "copy-" + std::to_string(i))->addChild(input);
  }
  return root;
}

namespace {

// Subdivides one geometry (see subdivide in scenegen.h); null when it has no
// triangles over a Vec3Array.
osg::ref_ptr<osg::Geometry> subdivideGeometry(const osg::Geometry& src, uint32_t n) {
  auto* pos = dynamic_cast<const osg::Vec3Array*>(src.getVertexArray());
  if (!pos || pos->empty()) return nullptr;
  struct Collect {
    std::vector<uint32_t>* out;
    void operator()(unsigned a, unsigned b, unsigned c) { out->insert(out->end(), {a, b, c}); }
  };
  std::vector<uint32_t> tris;
  osg::TriangleIndexFunctor<Collect> f;
  f.out = &tris;
  const_cast<osg::Geometry&>(src).accept(f);
  size_t nv = pos->size();
  for (uint32_t v : tris)
    if (v >= nv) return nullptr;
  if (tris.empty()) return nullptr;
  auto perVertex = [&](const osg::Array* a) {
    return a && a->getBinding() == osg::Array::BIND_PER_VERTEX && a->getNumElements() == nv
               ? a
               : nullptr;
  };
  auto* nrm = dynamic_cast<const osg::Vec3Array*>(perVertex(src.getNormalArray()));
  auto* col = dynamic_cast<const osg::Vec4Array*>(perVertex(src.getColorArray()));
  auto* uv = dynamic_cast<const osg::Vec2Array*>(perVertex(src.getTexCoordArray(0)));
  osg::ref_ptr<osg::Vec3Array> opos = new osg::Vec3Array, onrm = nrm ? new osg::Vec3Array : nullptr;
  osg::ref_ptr<osg::Vec4Array> ocol = col ? new osg::Vec4Array : nullptr;
  osg::ref_ptr<osg::Vec2Array> ouv = uv ? new osg::Vec2Array : nullptr;
  // A new vertex at sum(w_k * v_k) / n over (vertex, weight) pairs, in the
  // order given.
  auto mix = [&](std::initializer_list<std::pair<uint32_t, uint32_t>> w) {
    auto blend = [&](const auto* a, auto* out) {
      if (!a) return;
      using V = typename std::decay_t<decltype(*a)>::value_type;
      double acc[4] = {0, 0, 0, 0};
      for (auto [v, k] : w)
        for (int i = 0; i < V::num_components; ++i) acc[i] += double((*a)[v][i]) * k;
      V r;
      for (int i = 0; i < V::num_components; ++i) r[i] = float(acc[i] / n);
      out->push_back(r);
    };
    blend(pos, opos.get());
    blend(nrm, onrm.get());
    blend(col, ocol.get());
    blend(uv, ouv.get());
    return uint32_t(opos->size() - 1);
  };
  std::vector<uint32_t> corner(nv, UINT32_MAX);
  auto vertex = [&](uint32_t v) {
    if (corner[v] == UINT32_MAX) corner[v] = mix({{v, n}});
    return corner[v];
  };
  std::unordered_map<uint64_t, uint32_t> edges;  // (lo, hi) -> its n - 1 inner points, lo to hi
  auto onEdge = [&](uint32_t u, uint32_t v, uint32_t t) {  // t steps of n from u towards v
    if (t == 0) return vertex(u);
    if (t == n) return vertex(v);
    uint32_t lo = std::min(u, v), hi = std::max(u, v);
    auto [it, fresh] = edges.try_emplace(uint64_t(lo) << 32 | hi, 0);
    if (fresh) {
      it->second = uint32_t(opos->size());
      for (uint32_t k = 1; k < n; ++k) mix({{lo, n - k}, {hi, k}});
    }
    return it->second + (u == lo ? t : n - t) - 1;
  };
  auto* out = new osg::DrawElementsUInt(GL_TRIANGLES);
  out->reserve(tris.size() * n * n);
  std::vector<uint32_t> grid;  // point (i, j) of the current triangle, i along a-b, j along a-c
  for (size_t t = 0; t < tris.size(); t += 3) {
    uint32_t a = tris[t], b = tris[t + 1], c = tris[t + 2];
    grid.assign(size_t(n + 1) * (n + 1), 0);
    auto at = [&](uint32_t i, uint32_t j) -> uint32_t& { return grid[size_t(i) * (n + 1) + j]; };
    for (uint32_t i = 0; i <= n; ++i)
      for (uint32_t j = 0; i + j <= n; ++j) {
        if (j == 0)
          at(i, j) = onEdge(a, b, i);
        else if (i == 0)
          at(i, j) = onEdge(a, c, j);
        else if (i + j == n)
          at(i, j) = onEdge(b, c, j);
        else
          at(i, j) = mix({{a, n - i - j}, {b, i}, {c, j}});
      }
    for (uint32_t i = 0; i < n; ++i)
      for (uint32_t j = 0; i + j < n; ++j) {
        for (uint32_t v : {at(i, j), at(i + 1, j), at(i, j + 1)}) out->push_back(v);
        if (i + j + 1 < n)
          for (uint32_t v : {at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)}) out->push_back(v);
      }
  }
  osg::ref_ptr<osg::Geometry> g = new osg::Geometry;
  g->setName(src.getName());
  g->setStateSet(const_cast<osg::StateSet*>(src.getStateSet()));
  g->setVertexArray(opos);
  if (onrm) g->setNormalArray(onrm, osg::Array::BIND_PER_VERTEX);
  if (ocol) g->setColorArray(ocol, osg::Array::BIND_PER_VERTEX);
  if (ouv) g->setTexCoordArray(0, ouv, osg::Array::BIND_PER_VERTEX);
  g->addPrimitiveSet(out);
  return g;
}

// Copies every geode once (instances stay shared) with subdivided geometry.
osg::ref_ptr<osg::Node> subdivideNode(
    osg::Node* node, uint32_t n, std::unordered_map<osg::Node*, osg::ref_ptr<osg::Node>>& done) {
  if (auto it = done.find(node); it != done.end()) return it->second;
  osg::ref_ptr<osg::Node> result = node;
  if (auto* geode = node->asGeode()) {
    osg::ref_ptr<osg::Geode> copy = new osg::Geode(*geode, osg::CopyOp::SHALLOW_COPY);
    for (unsigned i = 0; i < copy->getNumDrawables(); ++i)
      if (auto* g = copy->getDrawable(i)->asGeometry())
        if (auto s = subdivideGeometry(*g, n)) copy->setDrawable(i, s);
    result = copy;
  } else if (auto* group = node->asGroup()) {
    osg::ref_ptr<osg::Group> copy =
        dynamic_cast<osg::Group*>(group->clone(osg::CopyOp::SHALLOW_COPY));
    for (unsigned i = 0; i < copy->getNumChildren(); ++i)
      copy->setChild(i, subdivideNode(copy->getChild(i), n, done));
    result = copy;
  }
  done[node] = result;
  return result;
}

}  // namespace

osg::ref_ptr<osg::Node> subdivide(osg::Node* input, uint32_t n) {
  if (!input) throw Error("subdivide: no input scene");
  if (n == 0 || n > 1000) throw Error("subdivide: n must be in 1..1000");
  if (n == 1) return input;
  std::unordered_map<osg::Node*, osg::ref_ptr<osg::Node>> done;
  return subdivideNode(input, n, done);
}

osg::BoundingBox sceneBounds(osg::Node& node) {
  osg::ComputeBoundsVisitor cbv;
  node.accept(cbv);
  return cbv.getBoundingBox();
}

Walkthrough makeWalkthrough(const osg::BoundingBox& box, uint32_t frames, PathKind kind) {
  if (frames == 0) throw Error("walkthrough: frames must be at least 1");
  if (!box.valid()) throw Error("walkthrough: the scene has no geometry");
  Vec3d c{box.center().x(), box.center().y(), box.center().z()};
  double dx = box.xMax() - box.xMin(), dy = box.yMax() - box.yMin(), dz = box.zMax() - box.zMin();
  double radius = box.radius() > 0 ? box.radius() : 1.0;
  Walkthrough w;
  for (uint32_t i = 0; i < frames; ++i) {
    double u = frames == 1 ? 0.5 : double(i) / (frames - 1);
    Vec3d eye, target;
    if (kind == PathKind::FlyThrough) {
      // x from 0.2 dx outside to 0.9 dx in; y on a parabola peaking just off the
      // centre line, where symmetric scenes tend to have walls.
      double v = 2 * u - 1;
      eye = {box.xMin() - 0.2 * dx + 1.1 * dx * u, c.y + 0.05 * dy - 0.12 * dy * v * v,
             box.zMin() + dz / 3};
      Vec3d heading{1.1 * dx, -0.48 * dy * v, 0};
      heading = length(heading) > 0 ? normalize(heading) : Vec3d{1, 0, 0};
      const double pitch = 10 * kPi / 180;
      target = eye + heading * std::cos(pitch) + Vec3d{0, 0, -std::sin(pitch)};
    } else if (kind == PathKind::Around) {
      double phi = 2 * kPi * i / frames, r = 0.4 * std::hypot(dx, dy);
      if (!(r > 0)) r = radius;
      eye = c + Vec3d{std::cos(phi) * r, std::sin(phi) * r, 0.25 * dz};
      target = c;
    } else {
      double phi = 2 * kPi * i / frames, elev = 20 * kPi / 180, r = 2.2 * radius;
      eye =
          c +
          Vec3d{std::cos(phi) * std::cos(elev), std::sin(phi) * std::cos(elev), std::sin(elev)} * r;
      target = c;
    }
    w.points.push_back({i / 30.0, eye, lookAtRotation(eye, target, {0, 0, 1})});
  }
  return w;
}

SceneStats sceneStats(osg::Node& node) {
  StatsVisitor v;
  node.accept(v);
  return v.stats;
}

uint64_t countTriangles(const osg::Geometry& geometry) {
  osg::TriangleIndexFunctor<TriangleCounter> f;
  const_cast<osg::Geometry&>(geometry).accept(f);
  return f.n;
}

}  // namespace dmmr::scenegen
