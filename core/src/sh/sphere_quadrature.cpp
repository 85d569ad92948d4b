#include "probebake/sh/sphere_quadrature.h"

#include <cmath>
#include <numbers>

#include "probebake/base/check.h"

namespace probebake {

namespace {

// P_n'(x) for n >= 1 by Bonnet's recurrence; also returns P_n(x) in *pn.
double LegendreDerivative(int n, double x, double* pn) {
  double p0 = 1, p1 = x;  // P_{k-1}, P_k
  for (int k = 2; k <= n; ++k) {
    const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
    p0 = p1;
    p1 = p2;
  }
  *pn = p1;
  return n * (x * p1 - p0) / (x * x - 1);
}

}  // namespace

QuadratureRule1D GaussLegendreRule(int n) {
  PB_CHECK_GE(n, 1);
  QuadratureRule1D rule;
  rule.nodes.resize(n);
  rule.weights.resize(n);
  // Roots of P_n are symmetric: find the positive half by Newton from Tricomi's estimate.
  for (int i = 0; i < n / 2; ++i) {
    double x = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    for (int iter = 0; iter < 100; ++iter) {
      double pn;
      const double dx = LegendreDerivative(n, x, &pn);
      const double step = pn / dx;
      x -= step;
      if (std::abs(step) <= 2e-16) break;
    }
    double pn;
    const double dp = LegendreDerivative(n, x, &pn);
    const double w = 2 / ((1 - x * x) * dp * dp);
    rule.nodes[n - 1 - i] = x;
    rule.weights[n - 1 - i] = w;
    rule.nodes[i] = -x;
    rule.weights[i] = w;
  }
  if (n % 2 == 1) {
    double pn;
    const double dp = LegendreDerivative(n, 0, &pn);
    rule.nodes[n / 2] = 0;
    rule.weights[n / 2] = 2 / (dp * dp);
  }
  return rule;
}

std::vector<SphereQuadratureNode> SphereProductQuadrature(int nz, int nphi) {
  PB_CHECK_GE(nz, 1);
  PB_CHECK_GE(nphi, 1);
  const QuadratureRule1D gl = GaussLegendreRule(nz);
  std::vector<SphereQuadratureNode> nodes;
  nodes.reserve(static_cast<size_t>(nz) * nphi);
  const double dphi = 2 * std::numbers::pi / nphi;
  for (int i = 0; i < nz; ++i) {
    const double z = gl.nodes[i];
    const double r = std::sqrt((1 - z) * (1 + z));
    for (int j = 0; j < nphi; ++j) {
      const double phi = (j + 0.5) * dphi;
      nodes.push_back({{r * std::cos(phi), r * std::sin(phi), z}, gl.weights[i] * dphi});
    }
  }
  return nodes;
}

std::vector<SphereQuadratureNode> SphereQuadratureForDegree(int degree) {
  PB_CHECK_GE(degree, 0);
  return SphereProductQuadrature(degree / 2 + 1, degree + 1);
}

}  // namespace probebake
