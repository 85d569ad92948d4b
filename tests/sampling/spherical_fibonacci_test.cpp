// Spherical Fibonacci sets and uniform random rotations (probebake/sampling/spherical_fibonacci.h):
// the point set's layout, the rotation's uniformity (which makes every batch of the probe's
// estimate unbiased) and the set's accuracy on smooth integrands.
#include "probebake/sampling/spherical_fibonacci.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace probebake {
namespace {

constexpr double kPi = std::numbers::pi;

double Unit53(uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1p-53;
}

TEST(SphericalFibonacci, OnePointPerEqualAreaBandAlongTheGoldenSpiral) {
  for (const uint64_t n : {1, 2, 7, 64, 1000}) {
    for (uint64_t j = 0; j < n; ++j) {
      const Vec3d p = SphericalFibonacci(j, n);
      EXPECT_NEAR(Length(p), 1, 1e-15) << j << " of " << n;
      // z = 1 - (2j + 1) / n: the middle of band j of n equal heights (equal areas).
      EXPECT_NEAR(p.z, 1 - (2.0 * double(j) + 1) / double(n), 1e-15) << j << " of " << n;
      if (std::abs(p.z) < 1 - 1e-9) {
        // Azimuth j / phi turns: j times the golden angle.
        const double turns = std::fmod(double(j) * 0.6180339887498949, 1.0);
        const double azimuth = std::atan2(p.y, p.x) / (2 * kPi);
        const double d = std::abs(azimuth - turns - std::round(azimuth - turns));
        EXPECT_LT(d, 1e-9) << j << " of " << n;
      }
    }
  }
}

TEST(UniformRotation, IsARotation) {
  for (uint64_t k = 0; k < 1000; ++k) {
    const Mat3d r = UniformRotation(Unit53(Hash(k, 0)), Unit53(Hash(k, 1)), Unit53(Hash(k, 2)));
    const Mat3d rtr = Transpose(r) * r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(rtr(i, j), i == j ? 1 : 0, 1e-14) << k;
    EXPECT_NEAR(Determinant(r), 1, 1e-14) << k;
  }
}

TEST(UniformRotation, TurnsAnyPointUniformlyOverTheSphere) {
  // A point turned by a uniform rotation is uniform on the sphere: the means of x, y, z, xy, yz,
  // zx and x^2 - y^2, 3 z^2 - 1 over N rotations are 0 within their standard errors (each has
  // variance at most 4/5 over the sphere: sqrt(0.8 / N) = 2.8e-3 for N = 1e5); five of them.
  // Checked for the pole (the worst case of a z-biased rotation) and an arbitrary point.
  constexpr int kN = 100000;
  for (const Vec3d& x : {Vec3d{0, 0, 1}, Normalize(Vec3d{0.3, -0.8, 0.2})}) {
    double m[8] = {};
    for (uint64_t k = 0; k < kN; ++k) {
      const Mat3d r =
          UniformRotation(Unit53(Hash(7, k, 0)), Unit53(Hash(7, k, 1)), Unit53(Hash(7, k, 2)));
      const Vec3d p = r * x;
      const double f[8] = {
          p.x, p.y, p.z, p.x * p.y, p.y * p.z, p.z * p.x, p.x * p.x - p.y * p.y, 3 * p.z * p.z - 1};
      for (int i = 0; i < 8; ++i) m[i] += f[i];
    }
    for (int i = 0; i < 8; ++i) EXPECT_NEAR(m[i] / kN, 0, 5 * std::sqrt(0.8 / kN)) << i;
  }
}

TEST(RotatedSphericalFibonacci, IsAFunctionOfSeedAndStream) {
  const RotatedSphericalFibonacci a(64, 1, 42), b(64, 1, 42), c(64, 1, 43), d(64, 2, 42);
  EXPECT_EQ(a.size(), 64u);
  for (uint64_t j = 0; j < 64; ++j) {
    EXPECT_EQ(a.Point(j), b.Point(j));
    EXPECT_NE(a.Point(j), c.Point(j));
    EXPECT_NE(a.Point(j), d.Point(j));
    // A rotation keeps the set's shape: the angle between points 0 and j is unchanged.
    EXPECT_NEAR(Dot(a.Point(0), a.Point(j)),
                Dot(SphericalFibonacci(0, 64), SphericalFibonacci(j, 64)), 1e-14);
  }
}

TEST(RotatedSphericalFibonacci, IntegratesSmoothFunctionsFarBetterThanRandomPoints) {
  // f(w) = exp(a . w) has mean sinh|a| / |a| over the sphere and mean square sinh 2|a| / 2|a|.
  // Over 200 rotations the RMS error of the n-point rule falls much faster than random points'
  // sqrt(Var f / n): measured 1.2e-3, 1.5e-4 and 9e-6 for n = 64, 256 and 1024, against 0.091,
  // 0.045 and 0.023.
  const Vec3d a{0.8, -0.4, 0.6};
  const double exact = std::sinh(Length(a)) / Length(a);
  const double variance = std::sinh(2 * Length(a)) / (2 * Length(a)) - exact * exact;
  double previous = 0;
  for (const uint64_t n : {64, 256, 1024}) {
    double sq = 0;
    for (uint64_t t = 0; t < 200; ++t) {
      const RotatedSphericalFibonacci set(n, 5, t);
      double mean = 0;
      for (uint64_t j = 0; j < n; ++j) mean += std::exp(Dot(a, set.Point(j)));
      sq += std::pow(mean / double(n) - exact, 2);
    }
    const double rms = std::sqrt(sq / 200);
    std::printf("[measured] n = %llu: RMS error %.2e of a mean of %.4f\n", (unsigned long long)n,
                rms, exact);
    EXPECT_LT(rms, std::sqrt(variance / double(n)) / 20) << n;
    if (previous > 0) {
      EXPECT_LT(rms, previous / 4) << n;  // faster than n^-1
    }
    previous = rms;
  }
}

}  // namespace
}  // namespace probebake
