#include "divide.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace dmmr {

std::ostream& operator<<(std::ostream& os, const Footprint& f) {
  return os << "footprint[obj " << f.object << " x " << f.x0 << ".." << f.x1 << " y " << f.y0
            << ".." << f.y1 << " w " << f.weight << "]";
}

std::ostream& operator<<(std::ostream& os, const Region& r) {
  return os << "region[" << r.rect << " objects " << r.objects.size() << " weight " << r.weight
            << "]";
}

// ---- footprints -----------------------------------------------------------

namespace {

// Eye-space points of the box, clipped to the half-space in front of the near
// plane (z_eye <= -near): the corners in front plus where edges cross it.
int clippedEyePoints(const Box3d& box, const Mat4d& view, double near, Vec3d out[20]) {
  Vec3d c[8];
  for (int i = 0; i < 8; ++i) c[i] = view.transformPoint(box.corner(i));
  int n = 0;
  for (int i = 0; i < 8; ++i)
    if (-c[i].z >= near) out[n++] = c[i];
  for (int i = 0; i < 8; ++i)
    for (int bit = 1; bit < 8; bit <<= 1) {
      int j = i | bit;
      if (j == i) continue;
      double di = -c[i].z - near, dj = -c[j].z - near;
      if ((di < 0) == (dj < 0)) continue;
      double t = di / (di - dj);
      out[n++] = c[i] + (c[j] - c[i]) * t;
    }
  return n;
}

Box3d boundsBox(const ObjectBounds& o) {
  if (o.use_box) return o.box;
  Vec3d r{o.sphere.radius, o.sphere.radius, o.sphere.radius};
  Box3d s{o.sphere.center - r, o.sphere.center + r};
  return Box3d{vmax(o.box.lo, s.lo), vmin(o.box.hi, s.hi)};  // both enclose the object
}

}  // namespace

bool footprint(const ObjectBounds& o, uint32_t index, const Camera& camera, int width, int height,
               Footprint* out) {
  Box3d box = boundsBox(o);
  if (!box.valid()) return false;
  Vec3d pts[20];
  int n = clippedEyePoints(box, viewMatrix(camera), camera.near, pts);
  if (n == 0) return false;
  double ty = std::tan(camera.fovy_deg * M_PI / 360.0), tx = ty * camera.aspect;
  double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
  for (int i = 0; i < n; ++i) {
    double d = -pts[i].z;  // >= near > 0
    double sx = (pts[i].x / (d * tx) * 0.5 + 0.5) * width;
    double sy = (pts[i].y / (d * ty) * 0.5 + 0.5) * height;
    xmin = std::min(xmin, sx);
    xmax = std::max(xmax, sx);
    ymin = std::min(ymin, sy);
    ymax = std::max(ymax, sy);
  }
  auto clampi = [](double v, int hi) { return int(std::clamp(v, -1.0, double(hi) + 1.0)); };
  Footprint f;
  f.object = index;
  f.weight = o.weight;
  f.x0 = std::max(0, clampi(std::floor(xmin), width) - 1);
  f.x1 = std::min(width, clampi(std::ceil(xmax), width) + 1);
  f.y0 = std::max(0, clampi(std::floor(ymin), height) - 1);
  f.y1 = std::min(height, clampi(std::ceil(ymax), height) + 1);
  if (f.x0 >= f.x1 || f.y0 >= f.y1) return false;
  *out = f;
  return true;
}

// ---- division -------------------------------------------------------------

namespace {

struct Span {  // a footprint's extent along the split axis
  int lo, hi;
};

Span spanOf(const Footprint& f, bool vertical) {
  return vertical ? Span{f.x0, f.x1} : Span{f.y0, f.y1};
}

struct Split {
  int at = 0;  // first pixel of the right/top side
};

// The best split line in [first, last] (pixel coordinates) of `items` along
// one axis. Weights of spans starting before each line (exclusive prefix
// sums) and ending after it (suffix sums) come from histograms over the
// rectangle's pixels, so one split costs O(items + pixels).
Split bestSplit(const std::vector<const Footprint*>& items, bool vertical, int origin, int size,
                int first, int last, int nl, int nr) {
  std::vector<double> startsAt(size_t(size) + 1, 0.0), endsAt(size_t(size) + 1, 0.0);
  double total = 0;
  for (const Footprint* f : items) {
    Span s = spanOf(*f, vertical);
    double w = double(std::max<uint64_t>(f->weight, 1));
    startsAt[size_t(std::clamp(s.lo - origin, 0, size))] += w;
    endsAt[size_t(std::clamp(s.hi - origin, 0, size))] += w;
    total += w;
  }
  const int nd = nl + nr;
  const double lt = total * nl / nd, rt = total * nr / nd;
  const double geometric = origin + double(size) * nl / nd;
  // left(at) = weight of spans with lo < at; right(at) = spans with hi > at
  // = total - spans with hi <= at.
  double left = 0, endedUpTo = 0;
  for (int k = 0; k < first - origin; ++k) {
    left += startsAt[size_t(k)];
    endedUpTo += endsAt[size_t(k)];
  }
  Split best{first};
  double bestCost = std::numeric_limits<double>::infinity(), bestDist = bestCost;
  for (int at = first; at <= last; ++at) {
    size_t k = size_t(at - origin);
    endedUpTo += endsAt[k];
    double right = total - endedUpTo;
    double cost = std::fabs(left - lt) + std::fabs(right - rt) +
                  std::min(nl, nr) * std::fabs(left / nl - right / nr);
    double dist = std::fabs(at - geometric);
    double eps = 1e-9 * total;
    if (cost < bestCost - eps || (cost <= bestCost + eps && dist < bestDist)) {
      bestCost = cost;
      bestDist = dist;
      best.at = at;
    }
    left += startsAt[k];
  }
  return best;
}

void divide(const std::vector<const Footprint*>& items, Rect rect, bool vertical, int clients,
            std::vector<Region>* out) {
  if (clients == 1) {
    Region r;
    r.rect = rect;
    for (const Footprint* f : items) {
      r.objects.push_back(f->object);
      r.weight += f->weight;
    }
    std::sort(r.objects.begin(), r.objects.end());
    out->push_back(std::move(r));
    return;
  }
  // A side of one pixel (or less) cannot be cut: use the other direction.
  if ((vertical ? rect.w : rect.h) < 2) vertical = !vertical;
  const int size = vertical ? rect.w : rect.h, across = vertical ? rect.h : rect.w;
  const int origin = vertical ? rect.x : rect.y;
  const int nl = clients / 2, nr = clients - nl;
  if (size < 2) {  // a single pixel (or an empty rectangle): the rest get nothing
    divide(items, rect, vertical, 1, out);
    for (int i = 1; i < clients; ++i) out->push_back(Region{Rect{rect.x1(), rect.y1(), 0, 0}, {}, 0});
    return;
  }
  // Leave each side at least as many pixels as it has clients, when possible.
  int minLeft = across > 0 ? (nl + across - 1) / across : 1;
  int minRight = across > 0 ? (nr + across - 1) / across : 1;
  int first = origin + std::max(1, minLeft), last = origin + size - std::max(1, minRight);
  if (first > last) first = last = origin + std::clamp(int(double(size) * nl / clients), 1, size - 1);
  Split s = bestSplit(items, vertical, origin, size, first, last, nl, nr);

  std::vector<const Footprint*> left, right;
  for (const Footprint* f : items) {
    Span sp = spanOf(*f, vertical);
    if (sp.lo < s.at) left.push_back(f);
    if (sp.hi > s.at) right.push_back(f);
  }
  Rect lr = rect, rr = rect;
  if (vertical) {
    lr.w = s.at - rect.x;
    rr.x = s.at;
    rr.w = rect.x1() - s.at;
  } else {
    lr.h = s.at - rect.y;
    rr.y = s.at;
    rr.h = rect.y1() - s.at;
  }
  divide(left, lr, !vertical, nl, out);
  divide(right, rr, !vertical, nr, out);
}

}  // namespace

std::vector<Region> divideFrame(const std::vector<Footprint>& items, Rect frame, int clients) {
  std::vector<Region> out;
  if (clients <= 0) return out;
  std::vector<const Footprint*> inside;
  inside.reserve(items.size());
  for (const Footprint& f : items)
    if (f.x0 < f.x1 && f.y0 < f.y1 &&  // a footprint with no pixels touches no region
        f.x0 < frame.x1() && f.x1 > frame.x && f.y0 < frame.y1() && f.y1 > frame.y)
      inside.push_back(&f);
  divide(inside, frame, frame.w >= frame.h, clients, &out);
  return out;
}

}  // namespace dmmr
