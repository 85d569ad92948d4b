#include "probebake/sampling/spherical_rectangle.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "probebake/sampling/sampler.h"
#include "sampling/stats.h"

namespace probebake {
namespace {

using testing::ChiSquareTest;
using testing::GaussLegendre;

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kAlpha = 1e-6;  // significance of every chi-square test in this file

struct Config {
  const char* name;
  Vec3d o, s, ex, ey;
};

// Overhead, grazing, seen from behind (normal flipped), off-axis and far away (small solid angle).
const Config kConfigs[] = {
    {"overhead", {0.3, 0.2, 1}, {-0.5, -0.5, 0}, {1, 0, 0}, {0, 1, 0}},
    {"grazing", {3, 0.5, 0.3}, {-0.5, -0.5, 0}, {1, 0, 0}, {0, 2, 0}},
    {"tilted_behind", {0.2, -1, -2}, {0, 0, 0}, {1, 1, 0}, {-1, 1, 1}},
    {"off_axis", {-4, 3, 2}, {1, 1, 1}, {0, 0.5, 0}, {0, 0, 0.25}},
    {"far", {50, 60, 70}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}},
};

// Solid angle of a sub-rectangle [a0, a1] x [b0, b1] (in edge fractions) by Gauss-Legendre on
// panels x panels, order 8: integral of |cos theta'| / r^2 dA = |n.(p - o)| / r^3 dA.
double QuadratureSolidAngle(const Config& c, double a0, double a1, double b0, double b1,
                            int panels) {
  const Vec3d n = Cross(c.ex, c.ey);
  const double area = Length(n);
  const Vec3d nUnit = n / area;
  double sum = 0;
  for (int i = 0; i < panels; ++i) {
    const auto qa =
        GaussLegendre(8, a0 + (a1 - a0) * i / panels, a0 + (a1 - a0) * (i + 1) / panels);
    for (int j = 0; j < panels; ++j) {
      const auto qb =
          GaussLegendre(8, b0 + (b1 - b0) * j / panels, b0 + (b1 - b0) * (j + 1) / panels);
      for (int x = 0; x < 8; ++x)
        for (int y = 0; y < 8; ++y) {
          const Vec3d d = c.s + c.ex * qa.x[x] + c.ey * qb.x[y] - c.o;
          const double r = Length(d);
          sum += qa.w[x] * qb.w[y] * area * std::abs(Dot(nUnit, d)) / (r * r * r);
        }
    }
  }
  return sum;
}

// Van Oosterom-Strackee: solid angle of the triangle (a, b, c) seen from the origin.
double TriangleSolidAngle(const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const double la = Length(a), lb = Length(b), lc = Length(c);
  const double num = std::abs(Dot(a, Cross(b, c)));
  const double den = la * lb * lc + Dot(a, b) * lc + Dot(a, c) * lb + Dot(b, c) * la;
  return 2 * std::atan2(num, den);
}

TEST(SphericalRectangle, SolidAngleMatchesClosedFormAndQuadrature) {
  for (const Config& c : kConfigs) {
    const double omega = SphericalRectangleSolidAngle(c.o, c.s, c.ex, c.ey);
    const Vec3d p00 = c.s - c.o, p10 = p00 + c.ex, p11 = p10 + c.ey, p01 = p00 + c.ey;
    const double vos = TriangleSolidAngle(p00, p10, p11) + TriangleSolidAngle(p00, p11, p01);
    // Urena's form is a sum of four angles minus 2 pi: absolute error ~ 16 eps * 2 pi.
    EXPECT_NEAR(omega, vos, 32 * kEps * 2 * std::numbers::pi) << c.name;
    // Quadrature of an analytic integrand on 8 x 8 panels of order 8: converged to ~1e-12
    // relative for these configurations (o is at least 0.3 edge lengths off the plane).
    EXPECT_NEAR(omega / QuadratureSolidAngle(c, 0, 1, 0, 1, 8), 1, 1e-10) << c.name;
    EXPECT_EQ(SphericalRectanglePdf(c.o, c.s, c.ex, c.ey), 1 / omega) << c.name;
  }
}

// A w x h rectangle seen from height d above its corner subtends atan(w h / (d sqrt(w^2 + h^2 +
// d^2))), a closed form accurate to a few eps relative (atan of a product and quotients). The
// solid angle keeps that relative accuracy down to 1e-14 sr: a sum of four angles minus 2 pi (the
// form before baker version 12) was off by ~1e-15 sr absolute: 2.3% of the smallest here, 5e-11
// relative at 1e-6 sr. And it is scale-free: the same view at 1e-60 and 1e60 times the size
// (where a product of six coordinates would underflow and overflow) gives the same angle.
TEST(SphericalRectangle, SolidAngleIsRelativelyAccurateAtAnySize) {
  for (const double d : {1.0, 1e3, 1e5, 1e7}) {
    for (const auto& [w, h] : {std::pair{1.0, 1.0}, std::pair{2.0, 0.5}}) {
      const double exact = std::atan(w * h / (d * std::sqrt(w * w + h * h + d * d)));
      for (const double scale : {1.0, 1e-60, 1e60}) {
        const Vec3d o{0, 0, d * scale}, s{0, 0, 0}, ex{w * scale, 0, 0}, ey{0, h * scale, 0};
        EXPECT_NEAR(SphericalRectangleSolidAngle(o, s, ex, ey) / exact, 1, 16 * kEps)
            << "d " << d << ", w " << w << ", scale " << scale;
      }
    }
  }
}

// Directions are uniform over the solid angle: bin the hit points in a 16 x 16 grid of
// sub-rectangles; expected share of cell = its solid angle / total (by quadrature).
TEST(SphericalRectangle, MatchesPdf) {
  constexpr int K = 16, kSamples = 1 << 20;
  for (const Config& c : kConfigs) {
    const double omega = SphericalRectangleSolidAngle(c.o, c.s, c.ex, c.ey);
    std::vector<double> observed(K * K, 0), expected(K * K);
    for (int i = 0; i < K; ++i)
      for (int j = 0; j < K; ++j)
        expected[i * K + j] = kSamples *
                              QuadratureSolidAngle(c, double(i) / K, double(i + 1) / K,
                                                   double(j) / K, double(j + 1) / K, 1) /
                              omega;
    const Vec3d n = Normalize(Cross(c.ex, c.ey));
    IndependentSampler s(31, Hash(c.name[0], c.name[1]));
    for (int k = 0; k < kSamples; ++k) {
      s.StartSample(k);
      const SphericalRectangleSample x = SampleSphericalRectangle(s.Get2D(), c.o, c.s, c.ex, c.ey);
      ASSERT_EQ(x.pdf, 1 / omega) << c.name;
      const Vec3d d = x.p - c.s;
      // On the plane to rounding of O(|o| + |s|) coordinates.
      ASSERT_NEAR(Dot(d, n), 0, 64 * kEps * (Length(c.o) + Length(c.s) + 1)) << c.name;
      const double a = Dot(d, c.ex) / Dot(c.ex, c.ex), b = Dot(d, c.ey) / Dot(c.ey, c.ey);
      ASSERT_TRUE(a > -1e-12 && a < 1 + 1e-12 && b > -1e-12 && b < 1 + 1e-12) << c.name;
      observed[std::clamp(int(a * K), 0, K - 1) * K + std::clamp(int(b * K), 0, K - 1)] += 1;
    }
    const auto r = ChiSquareTest(observed, expected, kAlpha);
    EXPECT_TRUE(r.pass) << c.name << ": " << r.ToString();
  }
}

TEST(SphericalRectangle, Inverts) {
  for (const Config& c : kConfigs) {
    const double omega = SphericalRectangleSolidAngle(c.o, c.s, c.ex, c.ey);
    // u.x is a ratio of solid angles each computed to ~16 eps * 2 pi absolute, so its error is
    // ~ 32 eps * 2 pi / omega; u.y comes from sines of elevations, a few eps over their spread
    // (>= sqrt(omega) / 4 here). Tolerance: 64 eps (2 pi / omega + 4 / sqrt(omega)).
    const double tolerance = 64 * kEps * (2 * std::numbers::pi / omega + 4 / std::sqrt(omega));
    IndependentSampler s(32, 0);
    for (int k = 0; k < 100000; ++k) {
      s.StartSample(k);
      const Vec2d u = s.Get2D();
      const SphericalRectangleSample x = SampleSphericalRectangle(u, c.o, c.s, c.ex, c.ey);
      const Vec2d v = InvertSphericalRectangleSample(x.p, c.o, c.s, c.ex, c.ey);
      ASSERT_NEAR(v.x, u.x, tolerance) << c.name << " u = " << u;
      ASSERT_NEAR(v.y, u.y, tolerance) << c.name << " u = " << u;
    }
  }
}

TEST(SphericalRectangle, DegenerateInputHasZeroPdf) {
  // Reference point in the rectangle's plane.
  const SphericalRectangleSample x =
      SampleSphericalRectangle({0.5, 0.5}, {2, 0, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
  EXPECT_EQ(x.pdf, 0);
  EXPECT_EQ(SphericalRectanglePdf({2, 0, 0}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}), 0);
}

}  // namespace
}  // namespace probebake
