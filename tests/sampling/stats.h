// Statistical and quadrature helpers for the sampling tests (no external stats library):
// Gauss-Legendre rules, the upper normal quantile, Wilson-Hilferty chi-square critical values and
// a Pearson chi-square goodness-of-fit test with pooling of low-expectation cells.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

namespace probebake::testing {

// n-point Gauss-Legendre nodes and weights on [a, b] (Newton on P_n from the Chebyshev guess;
// converged to ~1e-15 relative).
struct Quadrature {
  std::vector<double> x, w;
};

inline Quadrature GaussLegendre(int n, double a, double b) {
  Quadrature q;
  q.x.resize(n);
  q.w.resize(n);
  for (int i = 0; i < n; ++i) {
    double z = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (z * p1 - p0) / (z * z - 1);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    q.x[i] = 0.5 * (a + b) + 0.5 * (b - a) * z;
    q.w[i] = (b - a) / ((1 - z * z) * dp * dp);
  }
  return q;
}

// z with P(Z > z) = alpha for a standard normal Z, by bisection on erfc (alpha in (0, 0.5)).
inline double NormalUpperQuantile(double alpha) {
  double lo = 0, hi = 40;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(mid / std::sqrt(2.0)) > alpha ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Upper alpha critical value of chi-square with dof degrees of freedom by the Wilson-Hilferty
// cube-root normal approximation: (X/k)^(1/3) ~ N(1 - 2/(9k), 2/(9k)). Its relative error at
// alpha = 1e-6 is a few percent for k ~ 10 and below 1% for k >= 100.
inline double ChiSquareCritical(double dof, double alpha) {
  const double z = NormalUpperQuantile(alpha);
  const double c = 2 / (9 * dof);
  const double t = 1 - c + z * std::sqrt(c);
  return dof * t * t * t;
}

struct ChiSquareResult {
  double chi2 = 0;
  int dof = 0;
  double critical = 0;
  int cells = 0;  // after pooling
  bool pass = false;
  std::string ToString() const {
    std::ostringstream s;
    s << "chi2 = " << chi2 << ", dof = " << dof << ", critical = " << critical
      << ", cells = " << cells;
    return s.str();
  }
};

// Pearson chi-square test of observed counts against expected counts (same total). Cells with
// expected count < minExpected are pooled, smallest first, into one cell until it reaches
// minExpected (Cochran's rule of 5 keeps the chi-square approximation valid); an observed count
// in a cell with expected 0 fails outright.
inline ChiSquareResult ChiSquareTest(const std::vector<double>& observed,
                                     const std::vector<double>& expected, double alpha,
                                     double minExpected = 5) {
  ChiSquareResult r;
  std::vector<size_t> order(expected.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return expected[a] < expected[b]; });
  double pooledObs = 0, pooledExp = 0;
  bool impossible = false;
  for (size_t i : order) {
    if (expected[i] == 0) {
      if (observed[i] > 0) impossible = true;
      continue;
    }
    if (expected[i] < minExpected || (pooledExp > 0 && pooledExp < minExpected)) {
      pooledObs += observed[i];
      pooledExp += expected[i];
      continue;
    }
    const double d = observed[i] - expected[i];
    r.chi2 += d * d / expected[i];
    ++r.cells;
  }
  if (pooledExp > 0) {
    const double d = pooledObs - pooledExp;
    r.chi2 += d * d / pooledExp;
    ++r.cells;
  }
  r.dof = r.cells - 1;
  r.critical = r.dof > 0 ? ChiSquareCritical(r.dof, alpha) : 0;
  r.pass = !impossible && r.dof > 0 && r.chi2 <= r.critical;
  if (impossible) r.chi2 = INFINITY;
  return r;
}

// Least-squares line y = a + b x with the standard error of b from the residuals.
struct LineFit {
  double intercept = 0, slope = 0, slopeStdError = 0;
};

inline LineFit FitLine(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n;
  const double my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxx = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
  }
  LineFit f;
  f.slope = sxy / sxx;
  f.intercept = my - f.slope * mx;
  double ss = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    const double e = y[i] - (f.intercept + f.slope * x[i]);
    ss += e * e;
  }
  f.slopeStdError = std::sqrt(ss / (n - 2) / sxx);
  return f;
}

}  // namespace probebake::testing
