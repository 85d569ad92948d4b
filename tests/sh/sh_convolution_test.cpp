#include "probebake/sh/sh_convolution.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
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

TEST(IrradianceBandFactor, MatchesTheDocumentedList) {
  // docs/spherical-harmonics.md: π, 2π/3, π/4, 0, -π/24, 0, π/64, 0, -π/128. Each factor takes <= 3
  // roundings.
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
  // UE4's CalcDiffuseTransferSH3: L0 = 2π/(1+n), L1 = 2π/(2+n), L2 = n 2π/(3+4n+n²),
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
  // 1e-14 absolute; the HLSL constants below are given to 20 digits, so 1e-15 covers our
  // ~2-ulp products.
  for (const double n : {0.0, 1.0, 2.5, 30.0}) {
    std::vector<double> c(ShCoeffCount(3));
    CosinePowerLobe(3, n, Normalize(Vec3d{1, 2, 3}), c);
    EXPECT_NEAR(c[0] * std::sqrt(4 * kPi), 2 * kPi / (n + 1), 1e-14) << "n " << n;
  }
  // The n = 1 lobe is shEvaluateCosineLobe of SebH's HLSL spherical-harmonics helpers: 0.886227,
  // ±1.023327 (y, z, x).
  std::vector<double> c(4);
  const Vec3d d = Normalize(Vec3d{0.3, -0.4, 0.5});
  CosinePowerLobe(1, 1.0, d, c);
  EXPECT_NEAR(c[0], 0.8862269254527580137, 1e-15);
  EXPECT_NEAR(c[1], -1.0233267079464884885 * d.y, 1e-15);
  EXPECT_NEAR(c[2], 1.0233267079464884885 * d.z, 1e-15);
  EXPECT_NEAR(c[3], -1.0233267079464884885 * d.x, 1e-15);
}

// A polar rule for integrals against the HG lobe about d, in μ = cos θ' = ω·d:
// Σ_j w_j F(μ_j) ≈ ∫_{-1}^{1} F(μ) dμ, with p_j = p(μ_j) = (1 - g²)/(4π (1 + g² - 2gμ_j)^{3/2}).
// The substitution v = sqrt(1 + g² - 2gμ) (dμ = -v dv / g) maps μ in [-1, 1] onto
// v in [1-|g|, 1+|g|] for either sign of g, with p = (1 - g²)/(4π v³): the peak of width (1-g)²
// in μ becomes a pole of 1/v³ at v = 0, one panel width or more left of every panel of the
// geometric grading toward 1-|g| (GradedRule), where each 20-point panel converges like
// 5.83^-40 ≈ 1e-31 relative (sh_test_util.h): the rule has converged to rounding at every g,
// including ±0.999 (peak 1.6e5 sr^-1 over 5e-7 in μ). p_j is computed from v_j, not from μ_j, so
// the peak carries no cancellation of 1 + g² - 2gμ. g = 0 (p = 1/(4π)) uses one panel in μ.
struct HgPolarNode {
  double mu, w, p;
};

std::vector<HgPolarNode> HgPolarRule(double g, int points = 20) {
  std::vector<HgPolarNode> rule;
  if (g == 0) {
    const test::GradedNodes q = test::GradedRule(-1, 1, 1, points);
    for (size_t j = 0; j < q.x.size(); ++j) rule.push_back({q.x[j], q.w[j], 1 / (4 * kPi)});
    return rule;
  }
  const double a = 1 - std::abs(g), b = 1 + std::abs(g);
  const test::GradedNodes q = test::GradedRule(a, b, 64, points);
  for (size_t j = 0; j < q.x.size(); ++j) {
    const double v = q.x[j];
    const double mu = std::clamp((1 + g * g - v * v) / (2 * g), -1.0, 1.0);
    rule.push_back({mu, q.w[j] * v / std::abs(g), (1 - g * g) / (4 * kPi * v * v * v)});
  }
  return rule;
}

// Σ_j Σ_φ' weight · F(ω), ω = frame(μ_j, φ') about d, with F given the node and the basis of
// order `order` at ω. The uniform φ' rule with nphi = 2·order + 2 points integrates exactly every
// trigonometric polynomial of degree < nphi in φ'; after it, odd powers of sin θ' cancel, so every
// integrand below (p · Y_i: degree <= order in φ'; (p - Σ c_i Y_i)²: degree <= 2·order) reduces
// to p(μ)^k times a polynomial in μ, which HgPolarRule integrates to rounding.
template <typename F>
void ForEachHgNode(int order, double g, const Vec3d& d, int points, F&& f) {
  const Framed frame = Framed::FromZ(d);
  const int nphi = 2 * order + 2;
  std::vector<double> y(ShCoeffCount(order));
  for (const HgPolarNode& node : HgPolarRule(g, points)) {
    const double r = std::sqrt(std::max(0.0, (1 - node.mu) * (1 + node.mu)));
    for (int j = 0; j < nphi; ++j) {
      const double phi = 2 * kPi * (j + 0.5) / nphi;
      EvalShBasis(order, frame.FromLocal({r * std::cos(phi), r * std::sin(phi), node.mu}),
                  y.data());
      f(node, node.w * (2 * kPi / nphi), y);
    }
  }
}

// Numeric projection of the HG lobe about d onto every Y_i of order `order`: c_i = ∫ p Y_i dω.
std::vector<double> NumericHgProjection(int order, double g, const Vec3d& d) {
  std::vector<double> c(ShCoeffCount(order), 0.0);
  ForEachHgNode(order, g, d, 20,
                [&](const HgPolarNode& node, double weight, const std::vector<double>& y) {
                  for (size_t i = 0; i < c.size(); ++i) c[i] += weight * node.p * y[i];
                });
  return c;
}

TEST(Lobes, HenyeyGreensteinMatchesNumericProjection) {
  // The truncated lobe must equal the first coefficients of the full projection exactly, at
  // order 8 (the highest a job may ask for) and at kMaxShOrder. The quadrature has converged to
  // rounding at every g (HgPolarRule), so what remains is rounding: ~(nodes per integral) · eps ·
  // ∫|p Y| ≈ 1300 · 2.2e-16 · O(1) ≈ 3e-13 worst case. Measured (recorded as
  // hg_max_error_L*_g*): <= 4.1e-14 at g = ±0.999 (the 1/v² weights span six decades, so
  // cancellation costs digits), <= 1.7e-14 at g = ±0.5, 0.9, 6e-16 at g = 0. Tolerance 1e-12
  // absolute (coefficients are O(0.01..1); a missing g^l at l = 1 is an error >= 0.1 · |Y_1m(d)|).
  const Vec3d d = Normalize(Vec3d{0.3, -0.5, 0.8});
  for (const int order : {8, kMaxShOrder}) {
    for (const double g : {-0.999, -0.5, 0.0, 0.5, 0.9, 0.999}) {
      std::vector<double> lobe(ShCoeffCount(order));
      HenyeyGreensteinLobe(order, g, d, lobe);
      const std::vector<double> numeric = NumericHgProjection(order, g, d);
      double worst = 0;
      for (int i = 0; i < ShCoeffCount(order); ++i) {
        EXPECT_NEAR(lobe[i], numeric[i], 1e-12)
            << "order " << order << " g " << g << " index " << i;
        worst = std::max(worst, std::abs(lobe[i] - numeric[i]));
      }
      std::ostringstream key;
      key << "hg_max_error_L" << order << "_g" << g;
      RecordProperty(key.str(), test::Sci(worst));
    }
  }
}

// ||p||² = ∫ p² dω for the HG phase p(μ) = (1 - g²)/(4π (1 + g² - 2gμ)^{3/2}), two ways:
//  - directly: 2π ∫ p² dμ = (1 - g²)²/(8π) ∫_{-1}^{1} (1 + g² - 2gμ)^{-3} dμ
//    = (1 - g²)²/(32πg) [(1 - g)^{-4} - (1 + g)^{-4}] = (1 - g²)²/(32πg) · 8g(1 + g²)/(1 - g²)^4
//    = (1 + g²) / (4π (1 - g²)²);
//  - Parseval: c_lm = g^l Y_lm(d) and Σ_m Y_lm(d)² = (2l+1)/(4π) (addition theorem), so
//    ||p||² = Σ_l (2l+1) x^l / (4π) with x = g², and Σ_l (2l+1) x^l = 2x/(1-x)² + 1/(1-x)
//    = (1 + x)/(1 - x)²: the same.
// The truncation p_L = Σ_{l<=L} c_lm Y_lm is the orthogonal projection, so ||p - p_L||² is the
// tail Σ_{l>L} (2l+1) x^l/(4π) = x^{L+1} [(2L+3)/(1-x) + 2x/(1-x)²]/(4π), and
//    e_L² = ||p - p_L||² / ||p||² = x^{L+1} ((2L+3)(1 - x) + 2x) / (1 + x)
// (evaluated as the tail, so there is no cancellation of ||p||² - ||p_L||² at small g).
double HgNormSquared(double g) {
  return (1 + g * g) / (4 * kPi * (1 - g * g) * (1 - g * g));
}

double HgRelativeTruncationError(int order, double g) {
  const double x = g * g;
  return std::sqrt(std::pow(x, order + 1) * ((2 * order + 3) * (1 - x) + 2 * x) / (1 + x));
}

// ∫ p² dω and ∫ (p - Σ c_i Y_i)² dω with c = the library's order-L HG lobe, by the product rule of
// ForEachHgNode (points per panel given).
struct HgTruncationQuadrature {
  double normSquared = 0, errorSquared = 0;
};

HgTruncationQuadrature NumericHgTruncation(int order, double g, const Vec3d& d, int points) {
  std::vector<double> lobe(ShCoeffCount(order));
  HenyeyGreensteinLobe(order, g, d, lobe);
  HgTruncationQuadrature q;
  ForEachHgNode(order, g, d, points,
                [&](const HgPolarNode& node, double weight, const std::vector<double>& y) {
                  double s = 0;
                  for (size_t i = 0; i < lobe.size(); ++i) s += lobe[i] * y[i];
                  q.normSquared += weight * node.p * node.p;
                  q.errorSquared += weight * (node.p - s) * (node.p - s);
                });
  return q;
}

TEST(Lobes, HenyeyGreensteinTruncationErrorIsTheBandLimitTail) {
  // The accuracy an order-L HG lobe can reach is its band limit. Coefficients decay as g^l (band
  // energy (2l+1) g^{2l}/(4π)), so for small |g| e_L ≈ |g|^{L+1} sqrt(2L+3), but as |g| → 1,
  // e_L² ≈ x^{L+1} (1 + (L+1)(1 - x)) (x = g²) stays ≈ 1 until L is several times 1/(1 - |g|):
  // e_L < 1% needs L >= 8 at |g| = 0.5, 55 at 0.9 and 5875 at 0.999 (≈ 5.5–5.9/(1 - |g|); printed
  // as l_1pct). Closed form (HgRelativeTruncationError), printed below with the quadrature:
  //      g       e_2          e_8          e_9
  //   ±0.999   0.999991     0.999920     0.999901   (1/(1-|g|) = 1000: no order we store helps)
  //   ±0.5     2.68e-1      6.71e-3      3.52e-3
  //    0       0            0            0          (isotropic: band 0 only)
  //    0.9     9.31e-1      6.59e-1      6.14e-1    (1/(1-g) = 10: L = 8 is below the limit)
  // So the coefficient-level agreement of HenyeyGreensteinMatchesNumericProjection (1e-12) is the
  // accuracy of the lobe's stored coefficients, not of the lobe: the function itself is
  // reproduced to 0.7% at |g| = 0.5, order 8, and not at all at |g| >= 0.9.
  //
  // Numeric cross-check: ∫ (p - Σ c_i Y_i)² with the library's lobe c, by ForEachHgNode
  // (graded in v, so every g is covered including ±0.999; restricting to |g| <= 0.9 would skip
  // the hardest case). Error budget of e = sqrt(∫(p - s)² / ∫p²):
  //  - discretisation: the φ' rule is exact (trig degree <= 2L < nphi); after it the μ integrand
  //    is p² + p · poly_L(μ) + poly_2L(μ); in v the polynomial parts have degree <= 4L + 1 <= 37,
  //    integrated exactly by 20-point panels, and the p parts (poles at v = 0) converge like
  //    1e-31 per panel. Checked a posteriori: 20 and 30 points per panel agree to 1e-12 of ∫p²
  //    (asserted; measured <= 5e-14, which is summation rounding, not discretisation).
  //  - rounding of the integrand: s = Σ c_i Y_i has absolute error <= ~100 eps Σ|c_i Y_i|
  //    <= 100 eps ||p|| sqrt(100/(4π)) ≈ 6e-14 ||p|| (Cauchy–Schwarz, Σ_i Y_i² = (L+1)²/(4π)),
  //    and p a few eps relative; their L2 norm over the sphere (area 4π) moves e by <= ~3e-13.
  //  - summation: ~2.6e4 positive terms, relative error <= 2.6e4 eps = 6e-12 on ∫(p - s)² (a
  //    worst-case bound; 3e-12 on e).
  //  - the closed forms: 1 - g² at g = 0.999 carries 500 eps relative error (cancellation), so
  //    ||p||² = (1+g²)/(4π(1-g²)²) is good to ~1000 eps = 2.2e-13 relative (measured 1.4e-13).
  // Tolerances: 1e-12 + 5e-12 · e on e (measured <= 3.5e-14), 1e-12 relative on ||p||².
  // Mutations tried (each fails): a missing g^l (c = Y(d)) gives e_2 = 1.29 at g = 0.5 (closed
  // form 0.268) and 2.83 at g = 0; a wrong normalisation (c_lm = sqrt(4π/(2l+1)) g^l Y_lm(d),
  // the zonal h_l in place of the band factor) gives e_2 = 1.85 at g = 0.5. Even at g = 0.999,
  // where the lobe is barely resolved, both move e by >= 1e-5, a million times the tolerance.
  const Vec3d d = Normalize(Vec3d{-0.2, 0.7, 0.4});
  std::printf("HG lobe relative truncation error ||p - p_L|| / ||p|| (closed form | quadrature)\n");
  std::printf("%8s %12s %12s %12s %12s %12s %12s %8s\n", "g", "e_2", "e_2 quad", "e_8", "e_8 quad",
              "e_9", "e_9 quad", "l_1pct");
  for (const double g : {-0.999, -0.5, 0.0, 0.5, 0.9, 0.999}) {
    double closed[3], numeric[3];
    const int orders[3] = {2, 8, kMaxShOrder};
    for (int k = 0; k < 3; ++k) {
      const int order = orders[k];
      const HgTruncationQuadrature q = NumericHgTruncation(order, g, d, 20);
      const HgTruncationQuadrature q30 = NumericHgTruncation(order, g, d, 30);
      EXPECT_NEAR(q.normSquared, q30.normSquared, 1e-12 * q30.normSquared) << "g " << g;
      EXPECT_NEAR(q.errorSquared, q30.errorSquared, 1e-12 * q30.normSquared) << "g " << g;
      EXPECT_NEAR(q.normSquared, HgNormSquared(g), 1e-12 * HgNormSquared(g)) << "g " << g;
      closed[k] = HgRelativeTruncationError(order, g);
      numeric[k] = std::sqrt(q.errorSquared / q.normSquared);
      EXPECT_NEAR(numeric[k], closed[k], 1e-12 + 5e-12 * closed[k])
          << "order " << order << " g " << g;
      std::ostringstream key;
      key << "hg_truncation_L" << order << "_g" << g;
      RecordProperty(key.str(), test::Sci(numeric[k]));
    }
    int l1pct = 0;
    while (HgRelativeTruncationError(l1pct, g) > 0.01) ++l1pct;
    std::printf("%8.3f %12.5e %12.5e %12.5e %12.5e %12.5e %12.5e %8d\n", g, closed[0], numeric[0],
                closed[1], numeric[1], closed[2], numeric[2], l1pct);
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
