#include "cost_model.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace dmmr {

namespace {

constexpr int kTerms = 6;
using Row = std::array<double, kTerms>;

Row termsOf(const CostSample& s) {
  return {s.drawn, s.triangles, s.tested, s.pixels, s.fill, s.raster};
}

// Solves the normal equations restricted to the terms in `mask` (Gaussian
// elimination with partial pivoting, columns scaled to unit norm so that
// pixels and objects, which differ by 10^4, are conditioned alike). Returns
// false when the system is singular.
bool solveSubset(const std::vector<Row>& x, const std::vector<double>& y, unsigned mask,
                 Row* coef) {
  std::vector<int> cols;
  for (int j = 0; j < kTerms; ++j)
    if (mask & (1u << j)) cols.push_back(j);
  const size_t n = cols.size();
  Row scale{};
  for (size_t a = 0; a < n; ++a) {
    double ss = 0;
    for (const Row& r : x) ss += r[size_t(cols[a])] * r[size_t(cols[a])];
    if (ss <= 0) return false;  // a term that never occurs cannot be fitted
    scale[a] = 1.0 / std::sqrt(ss);
  }
  std::vector<std::vector<double>> m(n, std::vector<double>(n + 1, 0.0));
  for (size_t i = 0; i < x.size(); ++i)
    for (size_t a = 0; a < n; ++a) {
      double xa = x[i][size_t(cols[a])] * scale[a];
      for (size_t b = 0; b < n; ++b) m[a][b] += xa * x[i][size_t(cols[b])] * scale[b];
      m[a][n] += xa * y[i];
    }
  for (size_t c = 0; c < n; ++c) {
    size_t p = c;
    for (size_t r = c + 1; r < n; ++r)
      if (std::fabs(m[r][c]) > std::fabs(m[p][c])) p = r;
    if (std::fabs(m[p][c]) < 1e-9) return false;  // collinear terms
    std::swap(m[p], m[c]);
    for (size_t r = 0; r < n; ++r) {
      if (r == c) continue;
      double f = m[r][c] / m[c][c];
      for (size_t k = c; k <= n; ++k) m[r][k] -= f * m[c][k];
    }
  }
  *coef = Row{};
  for (size_t a = 0; a < n; ++a) (*coef)[size_t(cols[a])] = m[a][n] / m[a][a] * scale[a];
  return true;
}

double residual(const std::vector<Row>& x, const std::vector<double>& y, const Row& c) {
  double r = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    double p = 0;
    for (int j = 0; j < kTerms; ++j) p += c[size_t(j)] * x[i][size_t(j)];
    r += (y[i] - p) * (y[i] - p);
  }
  return r;
}

}  // namespace

std::ostream& operator<<(std::ostream& os, const CostModel& m) {
  return os << "{drawn " << m.per_drawn << " ms, triangle " << m.per_triangle << " ms, tested "
            << m.per_tested << " ms, pixel " << m.per_pixel << " ms, fill " << m.per_fill
            << " ms, raster " << m.per_raster << " ms" << (m.fitted ? "" : ", unfitted") << "}";
}

double predictMs(const CostModel& m, const CostSample& s) {
  return m.per_drawn * s.drawn + m.per_triangle * s.triangles + m.per_tested * s.tested +
         m.per_pixel * s.pixels + m.per_fill * s.fill + m.per_raster * s.raster;
}

CostModel fitCostModel(const std::vector<CostSample>& samples, const std::vector<double>& speeds) {
  CostModel out;
  if (samples.size() < 4) return out;
  std::vector<Row> x;
  std::vector<double> y;
  for (const CostSample& s : samples) {
    if (!(std::isfinite(s.ms) && s.ms >= 0)) continue;
    double speed = size_t(s.client) < speeds.size() ? speeds[size_t(s.client)] : 1.0;
    x.push_back(termsOf(s));
    y.push_back(s.ms * speed);
  }
  if (x.size() < 4) return out;
  double best = INFINITY;
  Row coef{};
  for (unsigned mask = 1; mask < (1u << kTerms); ++mask) {
    Row c;
    if (!solveSubset(x, y, mask, &c)) continue;
    if (std::any_of(c.begin(), c.end(), [](double v) { return v < 0 || !std::isfinite(v); }))
      continue;
    double r = residual(x, y, c);
    if (r < best) {
      best = r;
      coef = c;
    }
  }
  if (!std::isfinite(best)) return out;
  out.per_drawn = coef[0];
  out.per_triangle = coef[1];
  out.per_tested = coef[2];
  out.per_pixel = coef[3];
  out.per_fill = coef[4];
  out.per_raster = coef[5];
  out.fitted = true;
  return out;
}

std::vector<double> clientSpeeds(const CostModel& m, const std::vector<CostSample>& samples,
                                 int clients) {
  std::vector<double> predicted(size_t(std::max(clients, 0)), 0.0), took(predicted.size(), 0.0);
  for (const CostSample& s : samples) {
    if (s.client < 0 || s.client >= clients || !(std::isfinite(s.ms) && s.ms >= 0)) continue;
    predicted[size_t(s.client)] += predictMs(m, s);
    took[size_t(s.client)] += s.ms;
  }
  std::vector<double> speeds(predicted.size(), 1.0);
  double sum = 0;
  int n = 0;
  for (size_t k = 0; k < speeds.size(); ++k)
    if (took[k] > 0 && predicted[k] > 0) {
      speeds[k] = predicted[k] / took[k];
      sum += speeds[k];
      ++n;
    }
  if (n == 0) return speeds;
  bool outside = false;
  for (size_t k = 0; k < speeds.size(); ++k) {
    if (!(took[k] > 0 && predicted[k] > 0)) continue;
    speeds[k] = std::clamp(speeds[k] * n / sum, 0.125, 8.0);
    outside = outside || speeds[k] > kSpeedDeadband || speeds[k] < 1 / kSpeedDeadband;
  }
  // Within the deadband the differences are the model's misfit of the
  // clients' regions, not the clients: on equal clients they moved splits
  // without balancing time (docs/benchmarks.md).
  if (!outside) std::fill(speeds.begin(), speeds.end(), 1.0);
  return speeds;
}

CostModel fitCostsAndSpeeds(const std::vector<CostSample>& samples, int clients,
                            std::vector<double>* speeds) {
  speeds->assign(size_t(std::max(clients, 0)), 1.0);
  CostModel m = fitCostModel(samples);
  if (!m.fitted) return m;
  for (int round = 0; round < 8; ++round) {
    std::vector<double> s = clientSpeeds(m, samples, clients);
    CostModel next = fitCostModel(samples, s);
    if (!next.fitted) break;
    m = next;
    *speeds = std::move(s);
  }
  return m;
}

void updateClientDebt(const std::vector<CostSample>& frame, std::vector<double>* debt,
                      double* frame_ms) {
  double sum = 0;
  int n = 0, clients = int(debt->size());
  for (const CostSample& c : frame)
    if (std::isfinite(c.ms) && c.ms >= 0 && c.client >= 0) {
      sum += c.ms;
      ++n;
      clients = std::max(clients, c.client + 1);
    }
  debt->resize(size_t(clients), 0.0);
  if (n == 0) return;
  const double mean = sum / n;
  *frame_ms = *frame_ms > 0 ? kDebtMemory * *frame_ms + (1 - kDebtMemory) * mean : mean;
  for (const CostSample& c : frame)
    if (std::isfinite(c.ms) && c.ms >= 0 && c.client >= 0)
      (*debt)[size_t(c.client)] = kDebtMemory * (*debt)[size_t(c.client)] + (c.ms - mean);
}

std::vector<double> clientDebtFactors(const std::vector<double>& debt, double frame_ms,
                                      int clients) {
  std::vector<double> f(size_t(std::max(clients, 0)), 1.0);
  if (!(frame_ms > 0) || !std::isfinite(frame_ms)) return f;
  for (size_t k = 0; k < f.size() && k < debt.size(); ++k)
    if (std::isfinite(debt[k]))
      f[k] = std::clamp(1.0 - debt[k] / (kDebtFrames * frame_ms), 0.5, 2.0);
  return f;
}

std::vector<double> projectedDebt(const std::vector<double>& debt,
                                  const std::vector<std::vector<double>>& in_flight,
                                  double frame_ms) {
  std::vector<double> d = debt;
  if (!(frame_ms > 0) || !std::isfinite(frame_ms)) return d;
  for (const std::vector<double>& f : in_flight)
    for (size_t k = 0; k < d.size() && k < f.size(); ++k)
      if (std::isfinite(f[k])) d[k] -= frame_ms * (1 - f[k]);
  return d;
}

}  // namespace dmmr
