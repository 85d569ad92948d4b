#include "probebake/sh/sh_convolution.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "probebake/math/frame.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sphere_quadrature.h"
#include "sh/sh_test_util.h"

namespace probebake {
namespace {

using test::kDoubleEps;
using test::kPi;

TEST(IrradianceBandFactor, MatchesSpecList) {
  // SPEC 2: π, 2π/3, π/4, 0, -π/24, 0, π/64, 0, -π/128. Each factor takes <= 3 roundings.
  const double expected[] = {kPi, 2 * kPi / 3, kPi / 4, 0, -kPi / 24, 0, kPi / 64, 0, -kPi / 128};
  for (int l = 0; l <= 8; ++l) {
    EXPECT_NEAR(IrradianceBandFactor(l), expected[l], 4 * kDoubleEps * std::abs(expected[l]))
        << "l " << l;
  }
}

TEST(IrradianceBandFactor, OddBandsAboveOneAreExactlyZero) {
  for (int l = 3; l <= 201; l += 2) EXPECT_EQ(IrradianceBandFactor(l), 0.0) << "l " << l;
  EXPECT_NE(IrradianceBandFactor(1), 0.0);
}

TEST(IrradianceBandFactor, AgreesWithCosinePowerRecurrenceForLargeL) {
  // Two different exact forms (closed form with a central binomial vs the Gamma-ratio
  // recurrence at n = 1): each has O(l) roundings, so agree to ~l ulps; 1e-13 relative up to
  // l = 200 (the closed form switches from integer binomials to a product at l = 58).
  for (int l = 0; l <= 200; ++l) {
    const double a = IrradianceBandFactor(l), b = CosinePowerBandFactor(l, 1.0);
    EXPECT_NEAR(a, b, 1e-13 * std::abs(b) + 1e-300) << "l " << l;
  }
}

// factor_l = sqrt(4π/(2l+1)) h_l with h_l = ∫ max(0, z) Y_l0 dω, by a hemisphere product rule
// (Gauss–Legendre on z in [0, 1], where the integrand z Y_l0 is a polynomial of degree l+1, times
// φ) using the library basis: the rule is exact, so only rounding (< 1e-14) remains.
double NumericClampedCosineFactor(int l, double n) {
  const QuadratureRule1D gl = GaussLegendreRule(40);
  const int nphi = 2 * kMaxShOrder + 2;
  double h = 0;
  std::vector<double> y(kMaxShCoeffCount);
  for (int i = 0; i < 40; ++i) {
    const double z = 0.5 + 0.5 * gl.nodes[i];
    const double r = std::sqrt(1 - z * z);
    for (int j = 0; j < nphi; ++j) {
      const double phi = 2 * kPi * (j + 0.5) / nphi;
      EvalShBasis(l, Vec3d{r * std::cos(phi), r * std::sin(phi), z}, y.data());
      h += 0.5 * gl.weights[i] * (2 * kPi / nphi) * std::pow(z, n) * y[ShIndex(l, 0)];
    }
  }
  return std::sqrt(4 * kPi / (2 * l + 1)) * h;
}

TEST(IrradianceBandFactor, MatchesNumericConvolutionOfClampedCosine) {
  for (int l = 0; l <= kMaxShOrder; ++l) {
    EXPECT_NEAR(IrradianceBandFactor(l), NumericClampedCosineFactor(l, 1.0), 1e-13) << "l " << l;
  }
}

TEST(CosinePowerBandFactor, MatchesUe4ClosedFormsForLowBands) {
  // Seed 001, UE4 CalcDiffuseTransferSH3: L0 = 2π/(1+n), L1 = 2π/(2+n), L2 = n 2π/(3+4n+n²),
  // L3 = (n-1) 2π/(8+6n+n²). Different rounding order only: 8 ulps relative.
  for (const double n : {0.0, 0.25, 0.5, 1.0, 2.0, 3.7, 10.0, 64.0, 1000.0}) {
    const double ue4[] = {2 * kPi / (1 + n), 2 * kPi / (2 + n), n * 2 * kPi / (3 + 4 * n + n * n),
                          (n - 1) * 2 * kPi / (8 + 6 * n + n * n)};
    for (int l = 0; l <= 3; ++l) {
      EXPECT_NEAR(CosinePowerBandFactor(l, n), ue4[l], 8 * kDoubleEps * std::abs(ue4[l]) + 1e-300)
          << "l " << l << " n " << n;
    }
  }
}

TEST(CosinePowerBandFactor, MatchesNumericIntegralForRealExponents) {
  // 2π ∫_0^1 P_l(u) u^n du by Gauss–Legendre on panels graded toward u = 0, where u^n (n not an
  // integer) is not smooth: each panel's rule has converged to rounding (see GradedIntegral),
  // so the two agree to ~1e-15; 1e-13 absolute (factors are <= 2π).
  for (const double n : {0.0, 0.3, 0.5, 1.0, 1.5, 2.0, 3.7, 8.0, 20.0}) {
    for (int l = 0; l <= 12; ++l) {
      const double numeric =
          2 * kPi *
          test::GradedIntegral([&](double u) { return test::Legendre(l, u) * std::pow(u, n); }, 0.0,
                               1.0);
      EXPECT_NEAR(CosinePowerBandFactor(l, n), numeric, 1e-13) << "l " << l << " n " << n;
    }
  }
  // n = 1 is the clamped cosine, and the 2D numeric convolution agrees for a non-integer n too.
  for (int l = 0; l <= kMaxShOrder; ++l) {
    EXPECT_NEAR(CosinePowerBandFactor(l, 1.0), IrradianceBandFactor(l), 1e-14) << "l " << l;
    EXPECT_NEAR(CosinePowerBandFactor(l, 4.0), NumericClampedCosineFactor(l, 4.0), 1e-13)
        << "l " << l;
  }
}

TEST(CosinePowerBandFactor, VanishesExactlyWherePolynomialDegreeRunsOut) {
  // u^n with integer n is orthogonal to P_l for l > n with l - n even.
  for (int n = 0; n <= 6; ++n)
    for (int l = n + 2; l <= 20; l += 2)
      EXPECT_EQ(CosinePowerBandFactor(l, n), 0.0) << "l " << l << " n " << n;
}

// Projection of max(0, ω·d) onto SH of order L, integrated in a frame about d: Gauss–Legendre in
// u = ω·d on [0, 1] (the kink sits on the boundary, so the integrand is a polynomial of degree
// <= L + 1 on the panel) times uniform φ' (exact for trig degree < nphi). Exact up to rounding.
std::vector<double> ProjectClampedCosine(int order, const Vec3d& d) {
  const Framed frame = Framed::FromZ(d);
  const QuadratureRule1D gl = GaussLegendreRule(order + 2);
  const int nphi = 2 * order + 2;
  std::vector<double> c(ShCoeffCount(order), 0.0), y(ShCoeffCount(order));
  for (int i = 0; i < order + 2; ++i) {
    const double u = 0.5 + 0.5 * gl.nodes[i];
    const double r = std::sqrt(1 - u * u);
    for (int j = 0; j < nphi; ++j) {
      const double phi = 2 * kPi * (j + 0.5) / nphi;
      const Vec3d w = frame.FromLocal({r * std::cos(phi), r * std::sin(phi), u});
      EvalShBasis(order, w, y.data());
      const double weight = 0.5 * gl.weights[i] * (2 * kPi / nphi) * u;
      for (size_t k = 0; k < c.size(); ++k) c[k] += weight * y[k];
    }
  }
  return c;
}

TEST(Irradiance, OfADirectionalDeltaIsTheProjectedClampedCosine) {
  // Radiance δ(ω - d) has coefficients Y_lm(d). Its irradiance E(n) = max(0, n·d) exactly, so
  // the order-L irradiance must equal the order-L projection of max(0, n·d), reconstructed.
  const auto dirs = test::RandomDirections(40, 11);
  for (int order : {1, 2, 3, 4, 8, kMaxShOrder}) {
    for (int k = 0; k < 4; ++k) {
      const Vec3d d = dirs[k];
      std::vector<double> radiance(ShCoeffCount(order)), irradiance(ShCoeffCount(order));
      EvalShBasis(order, d, radiance.data());
      RadianceToIrradiance(order, radiance, irradiance);
      const std::vector<double> projected = ProjectClampedCosine(order, d);
      for (int i = 0; i < ShCoeffCount(order); ++i)
        ASSERT_NEAR(irradiance[i], projected[i], 1e-13) << "order " << order << " index " << i;
      for (const Vec3d& n : dirs) {
        std::vector<double> y(ShCoeffCount(order));
        EvalShBasis(order, n, y.data());
        double reconstructed = 0;
        for (int i = 0; i < ShCoeffCount(order); ++i) reconstructed += projected[i] * y[i];
        ASSERT_NEAR(IrradianceAt(order, radiance, n), reconstructed, 1e-12) << "order " << order;
      }
    }
  }
}

TEST(Irradiance, WhiteFurnace) {
  // Constant radiance 1: L00 = ∫ Y00 = 2 sqrt(π), every other coefficient 0; E = π everywhere.
  // E = Â_0 · L00 · Y00(n): three roundings of the product and of 2 sqrt(π): <= 4 ulp (8 for
  // the channel scaled by 2, which adds one).
  for (int order : {0, 1, 2, 5, kMaxShOrder}) {
    std::vector<Vec3d> radiance(ShCoeffCount(order));
    radiance[0] = Vec3d{1, 2, 0.5} * (2 * std::sqrt(kPi));
    for (const Vec3d& n : test::RandomDirections(20, 3)) {
      const Vec3d e = IrradianceAtRgb(order, radiance, n);
      EXPECT_NEAR(e.x, kPi, 4 * kDoubleEps * kPi) << e;
      EXPECT_NEAR(e.y, 2 * kPi, 8 * kDoubleEps * kPi) << e;
      EXPECT_NEAR(e.z, 0.5 * kPi, 4 * kDoubleEps * kPi) << e;
    }
  }
}

TEST(Irradiance, RgbMatchesPerChannel) {
  const int order = 4;
  std::vector<Vec3d> rgb(ShCoeffCount(order)), out(ShCoeffCount(order));
  std::vector<double> ch(ShCoeffCount(order)), chOut(ShCoeffCount(order));
  for (int i = 0; i < ShCoeffCount(order); ++i) rgb[i] = {0.1 * i, 1.0 / (i + 1), -0.3 * i};
  RadianceToIrradianceRgb(order, rgb, out);
  for (int c = 0; c < 3; ++c) {
    for (int i = 0; i < ShCoeffCount(order); ++i) ch[i] = rgb[i][c];
    RadianceToIrradiance(order, ch, chOut);
    const Vec3d n = Normalize(Vec3d{0.2, -0.5, 0.7});
    for (int i = 0; i < ShCoeffCount(order); ++i) EXPECT_EQ(out[i][c], chOut[i]) << i;
    EXPECT_EQ(IrradianceAtRgb(order, rgb, n)[c], IrradianceAt(order, ch, n));
  }
}

TEST(Lobes, CosinePowerLobeIntegratesToItsAnalyticValue) {
  // ∫ max(0, ω·d)^n dω = 2π/(n+1) = c_00 · sqrt(4π). A handful of roundings on values <= 2π:
  // 1e-14 absolute; the seed constants below are given to 20 digits, so 1e-15 covers our
  // ~2-ulp products.
  for (const double n : {0.0, 1.0, 2.5, 30.0}) {
    std::vector<double> c(ShCoeffCount(3));
    CosinePowerLobe(3, n, Normalize(Vec3d{1, 2, 3}), c);
    EXPECT_NEAR(c[0] * std::sqrt(4 * kPi), 2 * kPi / (n + 1), 1e-14) << "n " << n;
  }
  // The n = 1 lobe is seed 000's shEvaluateCosineLobe: 0.886227, ±1.023327 (y, z, x).
  std::vector<double> c(4);
  const Vec3d d = Normalize(Vec3d{0.3, -0.4, 0.5});
  CosinePowerLobe(1, 1.0, d, c);
  EXPECT_NEAR(c[0], 0.8862269254527580137, 1e-15);
  EXPECT_NEAR(c[1], -1.0233267079464884885 * d.y, 1e-15);
  EXPECT_NEAR(c[2], 1.0233267079464884885 * d.z, 1e-15);
  EXPECT_NEAR(c[3], -1.0233267079464884885 * d.x, 1e-15);
}

// Numeric projection of the HG lobe about d onto every Y_lm of order L, as a 2D integral in a
// frame about d: uniform φ' (trapezoid, exact for the trig degree <= L that Y_lm has in φ') and,
// in the polar variable, the substitution v = sqrt(1 + g² - 2gμ) (μ = cos θ'), under which
// p(μ) dμ = (1 - g²)/(4π g) dv / v² — the peak of width (1-g)² in μ becomes 1/v² on
// [|1-g|, 1+g], integrated by Gauss–Legendre on panels graded geometrically toward v = |1-g|
// (GradedIntegral). The integrand on each panel is (polynomial in v)/v² · (smooth in v) with its
// singularity at v = 0, at least one panel width away: every panel converges to rounding.
// g = 0 is the constant 1/(4π), integrated directly in μ.
std::vector<double> NumericHgProjection(int order, double g, const Vec3d& d) {
  const Framed frame = Framed::FromZ(d);
  const int n = ShCoeffCount(order);
  const int nphi = 2 * order + 2;
  std::vector<double> c(n, 0.0), y(n);
  for (int j = 0; j < nphi; ++j) {
    const double phi = 2 * kPi * (j + 0.5) / nphi;
    const double cphi = std::cos(phi), sphi = std::sin(phi);
    for (int k = 0; k < n; ++k) {
      auto integrandMu = [&](double mu) {
        const double r = std::sqrt(std::max(0.0, (1 - mu) * (1 + mu)));
        EvalShBasis(order, frame.FromLocal({r * cphi, r * sphi, mu}), y.data());
        return y[k];
      };
      double integral;
      if (g == 0) {
        integral = test::GradedIntegral([&](double mu) { return integrandMu(mu) / (4 * kPi); },
                                        -1.0, 1.0, 1, 20);
      } else {
        const double a = 1 - std::abs(g), b = 1 + std::abs(g);
        integral = (1 - g * g) / (4 * kPi * std::abs(g)) *
                   test::GradedIntegral(
                       [&](double v) {
                         const double mu = (1 + g * g - v * v) / (2 * g);
                         return integrandMu(std::clamp(mu, -1.0, 1.0)) / (v * v);
                       },
                       a, b);
      }
      c[k] += integral * (2 * kPi / nphi);
    }
  }
  return c;
}

TEST(Lobes, HenyeyGreensteinMatchesNumericProjection) {
  // The truncated lobe must equal the first coefficients of the full projection exactly. The
  // quadrature above has converged to rounding at every g (the panel grading absorbs the
  // sharpness of g = ±0.999, whose peak is 1.6e5 sr^-1 over 5e-7 in cos θ): its error is
  // ~(nodes per integral) · eps · ∫|p Y| ≈ 1300 · 2.2e-16 · O(1) ≈ 3e-13 worst case. Measured
  // (order 6, recorded as hg_max_error_g*): 1e-14 at g = ±0.999 (the 1/v² weights span six
  // decades, so cancellation costs ~2 digits), 2e-16 at g = -0.5, 0, 0.5, 0.9.
  // Tolerance 1e-12 absolute (coefficients are O(0.1..1)).
  const Vec3d d = Normalize(Vec3d{0.3, -0.5, 0.8});
  const int order = 6;
  for (const double g : {-0.999, -0.5, 0.0, 0.5, 0.9, 0.999}) {
    std::vector<double> lobe(ShCoeffCount(order));
    HenyeyGreensteinLobe(order, g, d, lobe);
    const std::vector<double> numeric = NumericHgProjection(order, g, d);
    double worst = 0;
    for (int i = 0; i < ShCoeffCount(order); ++i) {
      EXPECT_NEAR(lobe[i], numeric[i], 1e-12) << "g " << g << " index " << i;
      worst = std::max(worst, std::abs(lobe[i] - numeric[i]));
    }
    std::ostringstream key;
    key << "hg_max_error_g" << g;
    RecordProperty(key.str(), test::Sci(worst));
  }
}

TEST(Convolution, ZonalFactorsFollowTheDefinition) {
  // (h*f)_lm = sqrt(4π/(2l+1)) h_l f_lm.
  const int order = 3;
  const std::vector<double> h = {0.5, -1.0, 2.0, 0.25};
  std::vector<double> f(ShCoeffCount(order)), out(ShCoeffCount(order));
  for (int i = 0; i < ShCoeffCount(order); ++i) f[i] = 1.0 + i;
  ConvolveZonal(order, h, f, out);
  for (int l = 0; l <= order; ++l)
    for (int m = -l; m <= l; ++m)
      EXPECT_NEAR(out[ShIndex(l, m)], std::sqrt(4 * kPi / (2 * l + 1)) * h[l] * f[ShIndex(l, m)],
                  4 * kDoubleEps * std::abs(out[ShIndex(l, m)]));
}

}  // namespace
}  // namespace probebake
