#include "divide.h"

#include "error.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace dmmr {

std::ostream& operator<<(std::ostream& os, const Footprint& f) {
  os << "footprint[obj " << f.object << " x " << f.x0 << ".." << f.x1 << " y " << f.y0 << ".."
     << f.y1 << " w " << f.weight << (f.fill > 0 ? " fill " : "");
  if (f.fill > 0) os << f.fill;
  return os << "]";
}

double overlapArea(const Footprint& f, Rect rect) {
  double w = std::min(f.x1, rect.x1()) - std::max(f.x0, rect.x);
  double h = std::min(f.y1, rect.y1()) - std::max(f.y0, rect.y);
  return w > 0 && h > 0 ? w * h : 0.0;
}

std::ostream& operator<<(std::ostream& os, const Region& r) {
  return os << "region[" << r.rect << " objects " << r.objects.size() << " weight " << r.weight
            << "]";
}

// ---- footprints -----------------------------------------------------------

namespace {

// Eye-space points of the box, clipped to the half-space in front of the near
// plane (z_eye <= -near): the corners in front plus where edges cross it.
// Corners come from the eye-space centre and half-axes (additions only).
int clippedEyePoints(const Box3d& box, const Mat4d& view, double near, Vec3d out[20]) {
  Vec3d h = box.extent() * 0.5;
  Vec3d c0 = view.transformPoint(box.center());
  Vec3d ax = view.transformVector({h.x, 0, 0}), ay = view.transformVector({0, h.y, 0}),
        az = view.transformVector({0, 0, h.z});
  Vec3d c[8];
  bool allFront = true;
  for (int i = 0; i < 8; ++i) {
    c[i] = c0 + ((i & 1) ? ax : -ax) + ((i & 2) ? ay : -ay) + ((i & 4) ? az : -az);
    allFront = allFront && -c[i].z >= near;
  }
  if (allFront) {  // the common case: nothing to clip
    std::copy(c, c + 8, out);
    return 8;
  }
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

}  // namespace

Box3d tightBox(const ObjectBounds& o) {
  Vec3d r{o.sphere.radius, o.sphere.radius, o.sphere.radius};
  Box3d s{o.sphere.center - r, o.sphere.center + r};
  return Box3d{vmax(o.box.lo, s.lo), vmin(o.box.hi, s.hi)};  // both enclose the object
}

FootprintProjector::FootprintProjector(const Camera& camera, int width, int height)
    : view_(viewMatrix(camera)), near_(camera.near), width_(width), height_(height) {
  double ty = std::tan(camera.fovy_deg * M_PI / 360.0), tx = ty * camera.aspect;
  sx_ = 0.5 * width / tx;
  sy_ = 0.5 * height / ty;
}

bool FootprintProjector::operator()(const ObjectBounds& o, uint32_t index, Footprint* out) const {
  return (*this)(tightBox(o), o.weight, index, out);
}

bool FootprintProjector::operator()(const Box3d& box, uint64_t weight, uint32_t index,
                                    Footprint* out) const {
  if (!box.valid()) return false;
  double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
  auto project = [&](double x, double y, double z) {
    double inv = 1.0 / -z;  // depth >= near > 0
    double px = x * inv * sx_, py = y * inv * sy_;
    xmin = std::min(xmin, px);
    xmax = std::max(xmax, px);
    ymin = std::min(ymin, py);
    ymax = std::max(ymax, py);
  };
  // Fast path, plain doubles: eye-space centre +- half-axes, all in front.
  Vec3d h = box.extent() * 0.5;
  Vec3d c = view_.transformPoint(box.center());
  const auto& m = view_.m;  // column-major: m[col][row]
  double ax[3] = {m[0][0] * h.x, m[0][1] * h.x, m[0][2] * h.x};
  double ay[3] = {m[1][0] * h.y, m[1][1] * h.y, m[1][2] * h.y};
  double az[3] = {m[2][0] * h.z, m[2][1] * h.z, m[2][2] * h.z};
  double reach = std::fabs(ax[2]) + std::fabs(ay[2]) + std::fabs(az[2]);
  if (-(c.z + reach) >= near_) {
    // Eight corners as straight-line arrays so the compiler can vectorise;
    // float is ample here (camera-relative, with a one-pixel margin).
    float X[8], Y[8], W[8];
    for (int i = 0; i < 8; ++i) {
      float s0 = (i & 1) ? 1.f : -1.f, s1 = (i & 2) ? 1.f : -1.f, s2 = (i & 4) ? 1.f : -1.f;
      X[i] = float(c.x * sx_) + s0 * float(ax[0] * sx_) + s1 * float(ay[0] * sx_) +
             s2 * float(az[0] * sx_);
      Y[i] = float(c.y * sy_) + s0 * float(ax[1] * sy_) + s1 * float(ay[1] * sy_) +
             s2 * float(az[1] * sy_);
      W[i] = float(-c.z) - s0 * float(ax[2]) - s1 * float(ay[2]) - s2 * float(az[2]);
    }
    float fxmin = INFINITY, fxmax = -INFINITY, fymin = INFINITY, fymax = -INFINITY;
    for (int i = 0; i < 8; ++i) {
      float px = X[i] / W[i], py = Y[i] / W[i];
      fxmin = std::min(fxmin, px);
      fxmax = std::max(fxmax, px);
      fymin = std::min(fymin, py);
      fymax = std::max(fymax, py);
    }
    xmin = fxmin;
    xmax = fxmax;
    ymin = fymin;
    ymax = fymax;
  } else {  // the box reaches behind the near plane: clip it first
    Vec3d pts[20];
    int n = clippedEyePoints(box, view_, near_, pts);
    if (n == 0) return false;
    for (int i = 0; i < n; ++i) project(pts[i].x, pts[i].y, pts[i].z);
  }
  xmin += 0.5 * width_;
  xmax += 0.5 * width_;
  ymin += 0.5 * height_;
  ymax += 0.5 * height_;
  auto clampi = [](double v, int hi) { return int(std::clamp(v, -1.0, double(hi) + 1.0)); };
  Footprint f;
  f.object = index;
  f.weight = weight;
  f.x0 = std::max(0, clampi(std::floor(xmin), width_) - 1);
  f.x1 = std::min(width_, clampi(std::ceil(xmax), width_) + 1);
  f.y0 = std::max(0, clampi(std::floor(ymin), height_) - 1);
  f.y1 = std::min(height_, clampi(std::ceil(ymax), height_) + 1);
  if (f.x0 >= f.x1 || f.y0 >= f.y1) return false;
  *out = f;
  return true;
}

bool footprint(const ObjectBounds& o, uint32_t index, const Camera& camera, int width, int height,
               Footprint* out) {
  return FootprintProjector(camera, width, height)(o, index, out);
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
// Fill, spread over each footprint's pixel lines inside `rect`, comes from
// a second histogram (its per-line weight) summed twice.
// `sl` and `sr` are the two sides' shares (their clients' summed speeds;
// client counts when speeds are equal); `pixel` the weight per pixel of a
// side.
Split bestSplit(const std::vector<const Footprint*>& items, bool vertical, Rect rect, int first,
                int last, double sl, double sr, double pixel) {
  const int origin = vertical ? rect.x : rect.y, size = vertical ? rect.w : rect.h;
  const int across = vertical ? rect.h : rect.w, acrossLo = vertical ? rect.y : rect.x;
  std::vector<double> startsAt(size_t(size) + 1, 0.0), endsAt(size_t(size) + 1, 0.0);
  std::vector<double> fillSteps;  // difference array of fill per line; empty: no fill
  double total = 0, fillTotal = 0;
  for (const Footprint* f : items) {
    Span s = spanOf(*f, vertical);
    double w = double(std::max<uint64_t>(f->weight, 1));
    int lo = std::clamp(s.lo - origin, 0, size), hi = std::clamp(s.hi - origin, 0, size);
    startsAt[size_t(lo)] += w;
    endsAt[size_t(hi)] += w;
    total += w;
    if (f->fill > 0 && lo < hi) {
      Span c = spanOf(*f, !vertical);
      int rows = std::min(c.hi, acrossLo + across) - std::max(c.lo, acrossLo);
      if (rows <= 0) continue;
      if (fillSteps.empty()) fillSteps.assign(size_t(size) + 1, 0.0);
      double perLine = f->fill * rows;
      fillSteps[size_t(lo)] += perLine;
      fillSteps[size_t(hi)] -= perLine;
      fillTotal += perLine * (hi - lo);
    }
  }
  // fillLeftOf[k]: fill of the lines before line origin + k.
  std::vector<double> fillLeftOf;
  if (!fillSteps.empty()) {
    fillLeftOf.assign(size_t(size) + 1, 0.0);
    double perLine = 0;
    for (int k = 0; k < size; ++k) {
      perLine += fillSteps[size_t(k)];
      fillLeftOf[size_t(k) + 1] = fillLeftOf[size_t(k)] + perLine;
    }
  }
  const double line = pixel * across;  // a side's weight per pixel line
  const double objects = total;
  total += line * size + fillTotal;
  const double sd = sl + sr;
  const double lt = total * sl / sd, rt = total * sr / sd;
  const double geometric = origin + double(size) * sl / sd;
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
    double l = left + line * (at - origin), r = objects - endedUpTo + line * (origin + size - at);
    if (!fillLeftOf.empty()) {
      l += fillLeftOf[k];
      r += fillTotal - fillLeftOf[k];
    }
    // For uneven shares the per-client term alone would reward duplicating a
    // heavy straddler into both sides; charge the duplicate.
    double cost = std::fabs(l - lt) + std::fabs(r - rt) +
                  std::min(sl, sr) * std::fabs(l / sl - r / sr) + (sl != sr ? l + r - total : 0.0);
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

// Divides `rect` among clients [first_client, first_client + clients).
void divide(const std::vector<const Footprint*>& items, Rect rect, bool vertical, int clients,
            int first_client, const DivisionCosts& costs, std::vector<Region>* out) {
  if (clients == 1) {
    Region r;
    r.rect = rect;
    double fill = 0;
    for (const Footprint* f : items) {
      r.objects.push_back(f->object);
      r.weight += f->weight;
      if (f->fill > 0) fill += f->fill * overlapArea(*f, rect);
    }
    r.weight += uint64_t(std::llround(fill));
    if (!std::is_sorted(r.objects.begin(), r.objects.end()))  // usually already ascending
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
    divide(items, rect, vertical, 1, first_client, costs, out);
    for (int i = 1; i < clients; ++i)
      out->push_back(Region{Rect{rect.x1(), rect.y1(), 0, 0}, {}, 0});
    return;
  }
  // Leave each side at least as many pixels as it has clients, when possible.
  int minLeft = across > 0 ? (nl + across - 1) / across : 1;
  int minRight = across > 0 ? (nr + across - 1) / across : 1;
  int first = origin + std::max(1, minLeft), last = origin + size - std::max(1, minRight);
  if (first > last)
    first = last = origin + std::clamp(int(double(size) * nl / clients), 1, size - 1);
  double sl = nl, sr = nr;
  if (!costs.speeds.empty()) {
    auto sum = [&](int from, int n) {
      double s = 0;
      for (int i = from; i < from + n; ++i) s += costs.speeds[size_t(i)];
      return s;
    };
    sl = sum(first_client, nl);
    sr = sum(first_client + nl, nr);
  }
  Split s = bestSplit(items, vertical, rect, first, last, sl, sr, costs.pixel_weight);

  // Branch-free partition: random footprints make the branches unpredictable.
  std::vector<const Footprint*> left(items.size()), right(items.size());
  size_t nleft = 0, nright = 0;
  for (const Footprint* f : items) {
    Span sp = spanOf(*f, vertical);
    left[nleft] = f;
    nleft += sp.lo < s.at;
    right[nright] = f;
    nright += sp.hi > s.at;
  }
  left.resize(nleft);
  right.resize(nright);
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
  divide(left, lr, !vertical, nl, first_client, costs, out);
  divide(right, rr, !vertical, nr, first_client + nl, costs, out);
}

}  // namespace

std::vector<Region> divideFrame(const std::vector<Footprint>& items, Rect frame, int clients) {
  return divideFrame(items, frame, clients, DivisionCosts{});
}

std::vector<Region> divideFrame(const std::vector<Footprint>& items, Rect frame, int clients,
                                const DivisionCosts& costs) {
  std::vector<Region> out;
  if (clients <= 0) return out;
  DMMR_CHECK(costs.speeds.empty() || costs.speeds.size() == size_t(clients));
  for (double s : costs.speeds) DMMR_CHECK(std::isfinite(s) && s > 0);
  for (const Footprint& f : items) DMMR_CHECK(std::isfinite(f.fill) && f.fill >= 0);
  DMMR_CHECK(std::isfinite(costs.pixel_weight) && costs.pixel_weight >= 0);
  std::vector<const Footprint*> inside;
  inside.reserve(items.size());
  for (const Footprint& f : items)
    if (f.x0 < f.x1 && f.y0 < f.y1 &&  // a footprint with no pixels touches no region
        f.x0 < frame.x1() && f.x1 > frame.x && f.y0 < frame.y1() && f.y1 > frame.y)
      inside.push_back(&f);
  divide(inside, frame, frame.w >= frame.h, clients, 0, costs, &out);
  return out;
}

}  // namespace dmmr
