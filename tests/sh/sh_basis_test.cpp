#include "probebake/sh/sh_basis.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "probebake/sh/sphere_quadrature.h"
#include "sh/sh_test_util.h"

namespace probebake {
namespace {

using test::kDoubleEps;
using test::kFloatEps;
using test::kPi;

// The test vector of docs/spherical-harmonics.md at d = (0.48, 0.6, 0.64), a unit vector
// (0.2304 + 0.36 + 0.4096 = 1).
constexpr std::array<double, 25> kTestVector = {
    0.282094792,                                                           // l = 0
    -0.293161507, 0.312705608,  -0.234529206,                              // l = 1
    0.314653948,  -0.419538597, 0.072161590,  -0.335630878, -0.070797138,  // l = 2
    -0.117253462, 0.532797501,  -0.287390399, -0.227368876, -0.229912319, -0.119879438,
    0.240624496,  // l = 3
    -0.093436775, -0.225126647, 0.508808849,  0.034118162,  -0.361360720, 0.027294530,
    -0.114481991, 0.461999033,  -0.197125640};  // l = 4

TEST(ShBasis, IndexHelpers) {
  EXPECT_EQ(ShCoeffCount(0), 1);
  EXPECT_EQ(ShCoeffCount(2), 9);
  EXPECT_EQ(ShCoeffCount(8), 81);
  EXPECT_GE(kMaxShOrder, 8);
  EXPECT_EQ(ShIndex(0, 0), 0);
  EXPECT_EQ(ShIndex(1, -1), 1);
  EXPECT_EQ(ShIndex(2, 2), 8);
  EXPECT_EQ(ShIndex(4, -4), 16);
  // Every (l, m) of an order maps to a distinct index in [0, count).
  for (int l = 0, expected = 0; l <= kMaxShOrder; ++l)
    for (int m = -l; m <= l; ++m) EXPECT_EQ(ShIndex(l, m), expected++);
}

TEST(ShBasis, TestVectorDouble) {
  const Vec3d d{0.48, 0.6, 0.64};
  // The test vector's values are rounded to 9 decimals: |error| <= 5e-10 < 1e-9.
  constexpr double kTol = 1e-9;
  for (int order = 0; order <= 4; ++order) {
    std::vector<double> y(ShCoeffCount(order)), r(ShCoeffCount(order));
    EvalShBasis(order, d, y.data());
    EvalShBasisRecurrence(order, d, r.data());
    for (int i = 0; i < ShCoeffCount(order); ++i) {
      EXPECT_NEAR(y[i], kTestVector[i], kTol) << "order " << order << " index " << i;
      EXPECT_NEAR(r[i], kTestVector[i], kTol) << "recurrence, order " << order << " index " << i;
    }
  }
}

TEST(ShBasis, TestVectorFloat) {
  const Vec3f d{0.48f, 0.6f, 0.64f};
  // Float: the input is rounded (relative 2^-24 per component) and each value takes at most ~12
  // roundings (closed forms; the recurrence to l = 4 a few more) on magnitudes <= 3 before the
  // final constant; 64 float ulps of 1 (7.6e-6) bounds that, plus the test vector's own 5e-10.
  constexpr double kTol = 64 * kFloatEps + 5e-10;
  for (int order = 0; order <= 4; ++order) {
    std::vector<float> y(ShCoeffCount(order)), r(ShCoeffCount(order));
    EvalShBasis(order, d, y.data());
    EvalShBasisRecurrence(order, d, r.data());
    for (int i = 0; i < ShCoeffCount(order); ++i) {
      EXPECT_NEAR(y[i], kTestVector[i], kTol) << "order " << order << " index " << i;
      EXPECT_NEAR(r[i], kTestVector[i], kTol) << "recurrence, order " << order << " index " << i;
    }
  }
}

// Gram matrix by a product rule exact for degree 2L (Y_i Y_j has degree <= 2L): the rule's only
// error is rounding, ~ (number of nodes) · eps · max|Y|² ≈ 200 · 2.2e-16 · 2 < 1e-13, so a bound
// of 1e-10 has room and any normalisation or sign slip (errors of O(1)) fails.
TEST(ShBasis, OrthonormalAtEveryOrderByExactQuadrature) {
  for (int order = 0; order <= kMaxShOrder; ++order) {
    const auto nodes = SphereQuadratureForDegree(2 * order);
    const int n = ShCoeffCount(order);
    for (int path = 0; path < 2; ++path) {
      std::vector<double> gram(n * n, 0.0), y(n);
      for (const auto& node : nodes) {
        if (path == 0) {
          EvalShBasis(order, node.direction, y.data());
        } else {
          EvalShBasisRecurrence(order, node.direction, y.data());
        }
        for (int i = 0; i < n; ++i)
          for (int j = 0; j < n; ++j) gram[i * n + j] += node.weight * y[i] * y[j];
      }
      double worst = 0;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) worst = std::max(worst, std::abs(gram[i * n + j] - (i == j)));
      EXPECT_LT(worst, 1e-10) << "order " << order << (path ? " recurrence" : " EvalShBasis");
    }
  }
}

// Directions that stress the evaluation: random, poles, equator, axes, tiny components.
std::vector<Vec3d> StressDirections() {
  std::vector<Vec3d> dirs = test::RandomDirections(500, 0x5eed);
  const Vec3d special[] = {{0, 0, 1},         {0, 0, -1},       {1, 0, 0},        {0, 1, 0},
                           {-1, 0, 0},        {0, -1, 0},       {0.6, 0.8, 0},    {-0.8, 0.6, 0},
                           {1e-30, 0, 1},     {0, 1e-30, -1},   {1e-8, -1e-8, 1}, {1, 1e-30, 0},
                           {1e-30, 1, 1e-30}, {0.48, 0.6, 0.64}};
  for (const Vec3d& d : special) dirs.push_back(Normalize(d));
  return dirs;
}

TEST(ShBasis, ClosedFormsMatchRecurrenceToOneEMinus12) {
  // Both paths are a handful of roundings on O(1) values: the difference is ~1e-15; 1e-12 is
  // the required agreement.
  for (const Vec3d& d : StressDirections()) {
    for (int order = 0; order <= 3; ++order) {
      std::vector<double> a(ShCoeffCount(order)), b(ShCoeffCount(order));
      EvalShBasis(order, d, a.data());
      EvalShBasisRecurrence(order, d, b.data());
      for (int i = 0; i < ShCoeffCount(order); ++i)
        ASSERT_NEAR(a[i], b[i], 1e-12) << "order " << order << " index " << i << " at " << d;
    }
  }
}

TEST(ShBasis, MatchesIndependentReferenceAtEveryOrder) {
  // Reference: std::sph_legendre and trig (a different algorithm). Its own error is a few ulps
  // of θ and φ propagated through O(l) derivatives: < 1e-13 for l <= 9. libstdc++'s
  // sph_legendre forms sin θ from cos θ and loses digits for sin θ < ~1e-4, so directions that
  // close to a pole (exact poles excepted) are left to TinyComponentsKeepRelativeAccuracy.
  for (const Vec3d& d : StressDirections()) {
    const double sinTheta = std::hypot(d.x, d.y);
    if (sinTheta > 0 && sinTheta < 1e-4) continue;
    std::vector<double> y(kMaxShCoeffCount);
    EvalShBasis(kMaxShOrder, d, y.data());
    for (int l = 0; l <= kMaxShOrder; ++l)
      for (int m = -l; m <= l; ++m)
        ASSERT_NEAR(y[ShIndex(l, m)], test::ReferenceSh(l, m, d), 1e-12)
            << "l " << l << " m " << m << " at " << d;
  }
}

// Tolerance 1e-14: the expected values are one sqrt and a product (<= 2 ulp of values <= 1.2)
// and the recurrence takes <= 9 steps of ~3 roundings on values of that size: ~30 ulp ≈ 7e-15.
TEST(ShBasis, PolesAndEquatorAreExact) {
  for (int order = 0; order <= kMaxShOrder; ++order) {
    for (const double s : {1.0, -1.0}) {
      std::vector<double> y(ShCoeffCount(order));
      EvalShBasis(order, Vec3d{0, 0, s}, y.data());
      for (int l = 0; l <= order; ++l) {
        for (int m = -l; m <= l; ++m) {
          // At the poles only zonal terms survive: Y_l0 = sqrt((2l+1)/(4π)) (±1)^l, and m != 0
          // terms carry (x+iy)^m = 0 exactly.
          const double expected =
              m != 0 ? 0.0 : std::sqrt((2 * l + 1) / (4 * kPi)) * ((l % 2 && s < 0) ? -1 : 1);
          if (m != 0) {
            EXPECT_EQ(y[ShIndex(l, m)], 0.0) << "l " << l << " m " << m << " pole " << s;
          } else {
            EXPECT_NEAR(y[ShIndex(l, m)], expected, 1e-14) << "l " << l << " pole " << s;
          }
        }
      }
    }
    // Equator, on +X: Y_l0 = sqrt((2l+1)/(4π)) P_l(0), with P_l(0) = 0 for odd l.
    std::vector<double> y(ShCoeffCount(order));
    EvalShBasis(order, Vec3d{1, 0, 0}, y.data());
    for (int l = 0; l <= order; ++l) {
      const double expected = std::sqrt((2 * l + 1) / (4 * kPi)) * test::Legendre(l, 0);
      EXPECT_NEAR(y[ShIndex(l, 0)], expected, 1e-14) << "l " << l;
      if (l % 2) {
        EXPECT_EQ(y[ShIndex(l, 0)], 0.0) << "l " << l;
      }
      // On +X, sin(mφ) = 0: every m < 0 term vanishes exactly.
      for (int m = 1; m <= l; ++m) EXPECT_EQ(y[ShIndex(l, -m)], 0.0) << "l " << l << " m " << m;
    }
  }
}

TEST(ShBasis, TinyComponentsKeepRelativeAccuracy) {
  // d = (ε cos φ0, ε sin φ0, sqrt(1-ε²)) with ε = 1e-30: Y_l±m = Q_l^m(1) ε^m (cos, sin)(mφ0)
  // (1 + O(ε²)), with Q_l^m(1) = (-1)^m sqrt(2) K_lm (l+m)! / (2^m m! (l-m)!). The reference is
  // that limit, formed from factorials in long double; the relative error of both is ~1e-15, so
  // 1e-12 relative is a tight check that nothing underflows or loses digits near the pole.
  const double eps = 1e-30;
  const double phi0 = 0.7;
  const Vec3d d{eps * std::cos(phi0), eps * std::sin(phi0), 1.0};  // |d|² rounds to 1: unit
  auto fact = [](int n) {
    long double f = 1;
    for (int k = 2; k <= n; ++k) f *= k;
    return f;
  };
  std::vector<double> y(kMaxShCoeffCount);
  EvalShBasis(kMaxShOrder, d, y.data());
  for (int l = 0; l <= kMaxShOrder; ++l) {
    for (int m = 0; m <= l; ++m) {
      const long double k =
          std::sqrt((2 * l + 1) / (4 * static_cast<long double>(kPi)) * fact(l - m) / fact(l + m));
      const long double q = (m % 2 ? -1 : 1) * (m ? std::sqrt(2.0L) : 1.0L) * k * fact(l + m) /
                            (std::pow(2.0L, m) * fact(m) * fact(l - m));
      const long double em = std::pow(static_cast<long double>(eps), m);
      const double cosm =
          static_cast<double>(q * em * std::cos(static_cast<long double>(m * phi0)));
      const double sinm =
          static_cast<double>(q * em * std::sin(static_cast<long double>(m * phi0)));
      EXPECT_NEAR(y[ShIndex(l, m)], cosm, 1e-12 * std::abs(cosm)) << "l " << l << " m " << m;
      if (m > 0) {
        EXPECT_NEAR(y[ShIndex(l, -m)], sinm, 1e-12 * std::abs(sinm)) << "l " << l << " m " << -m;
        EXPECT_NE(y[ShIndex(l, m)], 0.0) << "underflow at l " << l << " m " << m;
      }
    }
  }
  // The closed forms (order 3) agree with the same limit.
  std::vector<double> c(16);
  EvalShBasis(3, d, c.data());
  for (int i = 0; i < 16; ++i) EXPECT_NEAR(c[i], y[i], 1e-12 * std::abs(y[i])) << "index " << i;
}

TEST(ShBasis, FloatAgreesWithDouble) {
  // Float evaluation of O(1) values through <= 10 recurrence steps of ~3 roundings each, on
  // magnitudes <= ~4: a bound of 10 · 3 · 4 · 2^-24 ≈ 7e-6 absolute (observed ~1e-6).
  constexpr double kTol = 120 * kFloatEps;
  for (const Vec3d& dd : StressDirections()) {
    const Vec3f df(dd);
    const Vec3d d(df);  // the same (rounded) direction in double
    std::vector<double> yd(kMaxShCoeffCount);
    std::vector<float> yf(kMaxShCoeffCount);
    EvalShBasis(kMaxShOrder, Normalize(d), yd.data());
    EvalShBasis(kMaxShOrder, df, yf.data());
    for (int i = 0; i < kMaxShCoeffCount; ++i)
      ASSERT_NEAR(yf[i], yd[i], kTol) << "index " << i << " at " << d;
    for (int order = 0; order <= 3; ++order) {
      EvalShBasis(order, df, yf.data());
      for (int i = 0; i < ShCoeffCount(order); ++i)
        ASSERT_NEAR(yf[i], yd[i], kTol) << "order " << order << " index " << i << " at " << d;
    }
  }
}

TEST(ShBasis, NonUnitInputIsNormalised) {
  // Contract: directions further than 64 ulp from unit length are normalised first. Both sides
  // then differ only by the rounding of d/|d| (1 ulp per component) carried through O(1)
  // polynomials of degree <= 9: ~10 ulp of values <= 2, far below 1e-13 (double) and
  // 16 float ulps (float); forgetting to normalise gives errors of order |scale^l - 1|.
  for (const Vec3d& d : test::RandomDirections(50, 7)) {
    for (const double scale : {2.0, 0.001, 1e10, 1 + 1e-9}) {
      for (int order : {1, 2, 3, 6, kMaxShOrder}) {
        std::vector<double> a(ShCoeffCount(order)), b(ShCoeffCount(order));
        EvalShBasis(order, d, a.data());
        EvalShBasis(order, d * scale, b.data());
        for (int i = 0; i < ShCoeffCount(order); ++i)
          ASSERT_NEAR(a[i], b[i], 1e-13) << "scale " << scale << " order " << order;
      }
    }
    // Float: same rule with float ulps.
    std::vector<float> a(16), b(16);
    EvalShBasis(3, Vec3f(d), a.data());
    EvalShBasis(3, Vec3f(d) * 3.0f, b.data());
    for (int i = 0; i < 16; ++i) ASSERT_NEAR(a[i], b[i], 16 * kFloatEps);
  }
}

TEST(ShBasisDeathTest, ZeroAndNanDirectionsAreRejected) {
  std::vector<double> y(kMaxShCoeffCount);
  EXPECT_DEATH(EvalShBasis(2, Vec3d{0, 0, 0}, y.data()), "Check failed");
  EXPECT_DEATH(EvalShBasis(8, Vec3d{std::nan(""), 0, 1}, y.data()), "Check failed");
  EXPECT_DEATH(EvalShBasis(kMaxShOrder + 1, Vec3d{0, 0, 1}, y.data()), "Check failed");
}

}  // namespace
}  // namespace probebake
