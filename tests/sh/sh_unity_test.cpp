#include "probebake/sh/sh_unity.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <sstream>
#include <vector>

#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "sh/sh_test_util.h"

namespace probebake {
namespace {

using test::kFloatEps;
using test::kPi;

std::vector<Vec3d> RandomRadiance(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec3d> r(9);
  for (Vec3d& c : r) c = {u(rng), u(rng), u(rng)};
  r[0] += Vec3d{3, 3, 3};  // a positive mean, as real radiance has
  return r;
}

// Tolerance: the packed constants are floats (relative rounding 2^-24 each, on top of a few
// double roundings); ShadeSH9 sums 9 terms each bounded by |constant| · 1, so its error is at
// most Σ|constants| · 2^-24 · (1 + tiny). Using 4 float ulps of that sum leaves room for the
// double-side rounding while any wrong sign or factor (errors ~ the terms themselves) fails.
double Tolerance(const UnitySh9Constants& c, int ch) {
  double sum = 0;
  for (int k = 0; k < 4; ++k) sum += std::abs(c.v[ch][k]) + std::abs(c.v[3 + ch][k]);
  sum += std::abs(c.v[6][ch]);
  return 4 * kFloatEps * sum;
}

TEST(UnitySh9, ShadeSh9IsIrradianceOverPiInOurAxes) {
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    const std::vector<Vec3d> radiance = RandomRadiance(seed);
    const UnitySh9Constants c = PackUnitySh9(radiance, UnityAxes::kProbebake);
    EXPECT_EQ(c.v[6][3], 1.0f);
    for (const Vec3d& n : test::RandomDirections(200, seed)) {
      const Vec3d expected = IrradianceAtRgb(2, radiance, n) / kPi;
      const Vec3d got = EvalUnityShadeSh9(c, n);
      for (int ch = 0; ch < 3; ++ch)
        ASSERT_NEAR(got[ch], expected[ch], Tolerance(c, ch)) << "n " << n << " channel " << ch;
    }
  }
}

TEST(UnitySh9, YUpConversionMapsDirectionsAsDocumented) {
  // Unity (x, y, z) = probebake (x, z, y): ShadeSH9 at the mapped normal equals E(n)/π.
  const Mat3d m = UnityFromProbebakeAxes();
  EXPECT_EQ(m * Vec3d(1, 2, 3), Vec3d(1, 3, 2));
  EXPECT_EQ(Determinant(m), -1.0);
  for (uint64_t seed = 11; seed <= 20; ++seed) {
    const std::vector<Vec3d> radiance = RandomRadiance(seed);
    const UnitySh9Constants c = PackUnitySh9(radiance, UnityAxes::kUnityYUp);
    for (const Vec3d& n : test::RandomDirections(200, seed)) {
      const Vec3d expected = IrradianceAtRgb(2, radiance, n) / kPi;
      const Vec3d got = EvalUnityShadeSh9(c, Vec3d{n.x, n.z, n.y});
      for (int ch = 0; ch < 3; ++ch)
        ASSERT_NEAR(got[ch], expected[ch], Tolerance(c, ch)) << "n " << n << " channel " << ch;
    }
  }
}

TEST(UnitySh9, SkyLightIsUpInBothFrames) {
  // A directional light from straight up (probebake +Z): the brightest normal is +Z in our frame
  // and +Y in Unity's; its opposite is the darkest.
  std::vector<Vec3d> radiance(9);
  std::vector<double> y(9);
  EvalShBasis(2, Vec3d{0, 0, 1}, y.data());
  for (int i = 0; i < 9; ++i) radiance[i] = Vec3d{1, 1, 1} * y[i];
  const UnitySh9Constants ours = PackUnitySh9(radiance, UnityAxes::kProbebake);
  const UnitySh9Constants unity = PackUnitySh9(radiance, UnityAxes::kUnityYUp);
  EXPECT_GT(EvalUnityShadeSh9(ours, {0, 0, 1}).x, EvalUnityShadeSh9(ours, {0, 1, 0}).x);
  EXPECT_GT(EvalUnityShadeSh9(unity, {0, 1, 0}).x, EvalUnityShadeSh9(unity, {0, 0, 1}).x);
  EXPECT_GT(EvalUnityShadeSh9(unity, {0, 1, 0}).x, EvalUnityShadeSh9(unity, {0, -1, 0}).x);
  // E(up)/π of a unit delta from up, order 2: (π Y00² + 2π/3 · 3/(4π) + π/4 · 5/(4π)) / π.
  // Float constants: relative 2^-24 on terms summing to ~0.34: 1e-6 leaves room.
  const double expected = (0.25 + 0.5 + 5.0 / 16) / kPi;
  EXPECT_NEAR(EvalUnityShadeSh9(unity, {0, 1, 0}).y, expected, 1e-6);
}

TEST(UnitySh9, Prints) {
  std::ostringstream os;
  os << PackUnitySh9(RandomRadiance(1), UnityAxes::kProbebake);
  EXPECT_NE(os.str().find("SHAr ("), std::string::npos) << os.str();
  EXPECT_NE(os.str().find("SHC ("), std::string::npos) << os.str();
}

}  // namespace
}  // namespace probebake
