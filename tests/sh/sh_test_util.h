// Helpers shared by the SH tests: an independent reference basis (std::sph_legendre and trig),
// deterministic random directions and rotations, and 1D reference integrals.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "probebake/math/mat3.h"
#include "probebake/math/vec3.h"
#include "probebake/sh/sphere_quadrature.h"

namespace probebake::test {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kDoubleEps = 2.220446049250313e-16;
inline constexpr double kFloatEps = 1.1920928955078125e-07;

// Y_lm(d) from the textbook definition, independent of the library: std::sph_legendre(l, m, θ)
// is (-1)^m K_lm P_l^m(cos θ) (Condon–Shortley phase included), times sqrt(2) cos(mφ) or
// sqrt(2) sin(|m|φ). θ and φ come from atan2, accurate everywhere except at tiny sin θ.
inline double ReferenceSh(int l, int m, const Vec3d& d) {
  const double theta = std::atan2(std::hypot(d.x, d.y), d.z);
  const double phi = std::atan2(d.y, d.x);
  const int am = std::abs(m);
  const double p = std::sph_legendre(l, am, theta);
  if (m == 0) return p;
  return std::sqrt(2.0) * p * (m > 0 ? std::cos(am * phi) : std::sin(am * phi));
}

// x in scientific notation, for RecordProperty.
inline std::string Sci(double x) {
  std::ostringstream os;
  os << std::scientific << x;
  return os.str();
}

// Deterministic uniform directions (fixed seed: tests are reproducible).
inline std::vector<Vec3d> RandomDirections(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3d> dirs;
  for (int i = 0; i < n; ++i) {
    const double z = 1 - 2 * u(rng);
    const double phi = 2 * kPi * u(rng);
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    dirs.push_back(Normalize(Vec3d{r * std::cos(phi), r * std::sin(phi), z}));
  }
  return dirs;
}

// Uniformly distributed rotation from a random unit quaternion.
inline Mat3d RandomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0, 1);
  double w = n(rng), x = n(rng), y = n(rng), z = n(rng);
  const double s = 1 / std::sqrt(w * w + x * x + y * y + z * z);
  w *= s, x *= s, y *= s, z *= s;
  return Mat3d::FromRows({1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                         {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                         {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)});
}

// Legendre polynomial P_l(u) by Bonnet's recurrence.
inline double Legendre(int l, double u) {
  double p0 = 1, p1 = u;
  if (l == 0) return p0;
  for (int k = 2; k <= l; ++k) {
    const double p2 = ((2 * k - 1) * u * p1 - (k - 1) * p0) / k;
    p0 = p1;
    p1 = p2;
  }
  return p1;
}

// ∫_a^b f by composite Gauss–Legendre on panels graded geometrically toward a: [a, a + w/2^k]
// style panels, so integrands with a (near-)singularity at a converge at full speed. For a
// function analytic on each panel with its nearest singularity no closer than the panel width
// (true for u^n and for 1/(c + v)^p with the singular point at or left of a), the n-point rule
// on a panel converges like ρ^(-2n) with ρ = 3 + sqrt(8) ≈ 5.83, i.e. 1e-30 at n = 20:
// what remains is rounding.
inline double GradedIntegral(const std::function<double(double)>& f, double a, double b,
                             int panels = 64, int points = 20) {
  static const QuadratureRule1D gl = GaussLegendreRule(20);
  const QuadratureRule1D rule = points == 20 ? gl : GaussLegendreRule(points);
  double sum = 0;
  double hi = b;
  for (int k = 0; k < panels; ++k) {
    const double lo = (k + 1 == panels) ? a : a + (hi - a) / 2;
    const double mid = (lo + hi) / 2, half = (hi - lo) / 2;
    double panel = 0;
    for (int i = 0; i < points; ++i) panel += rule.weights[i] * f(mid + half * rule.nodes[i]);
    sum += panel * half;
    hi = lo;
  }
  return sum;
}

// The nodes and weights of GradedIntegral's rule on [a, b] (same panels, same convergence), so
// that several integrands can share one evaluation per node: Σ_j w_j f(x_j) ≈ ∫_a^b f. Nodes
// run panel by panel from b toward a (not sorted).
struct GradedNodes {
  std::vector<double> x, w;
};

inline GradedNodes GradedRule(double a, double b, int panels = 64, int points = 20) {
  const QuadratureRule1D rule = GaussLegendreRule(points);
  GradedNodes out;
  double hi = b;
  for (int k = 0; k < panels; ++k) {
    const double lo = (k + 1 == panels) ? a : a + (hi - a) / 2;
    const double mid = (lo + hi) / 2, half = (hi - lo) / 2;
    for (int i = 0; i < points; ++i) {
      out.x.push_back(mid + half * rule.nodes[i]);
      out.w.push_back(half * rule.weights[i]);
    }
    hi = lo;
  }
  return out;
}

}  // namespace probebake::test
