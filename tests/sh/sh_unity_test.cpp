#include "probebake/sh/sh_unity.h"

#include <gtest/gtest.h>

#include <algorithm>
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

// Unity's ConvertSHConstants, transcribed from its published text (not through the library):
//   fC0 = 1/(2 sqrtπ), fC1 = sqrt(3)/(3 sqrtπ), fC2 = sqrt(15)/(8 sqrtπ), fC3 = sqrt(5)/(16 sqrtπ),
//   fC4 = 0.5 fC2;  for iC in 0..2:
//   SHArBrC[iC]     = (-fC1 sh[3][iC], -fC1 sh[1][iC], fC1 sh[2][iC], fC0 sh[0][iC] - fC3
//   sh[6][iC]) SHArBrC[iC + 3] = (fC2 sh[4][iC], -fC2 sh[5][iC], 3 fC3 sh[6][iC], -fC2 sh[7][iC])
//   SHArBrC[6]      = (fC4 sh[8][0], fC4 sh[8][1], fC4 sh[8][2], 1)
// Evaluated in double (Unity uses float constants; the contract is the formula). Also returns,
// per entry, the sum of the absolute values of its terms (the scale of its rounding error).
struct UnityPacking {
  double value[7][4], scale[7][4];
};

UnityPacking UnityConvertShConstants(const double (&sh)[9][3]) {
  const double sqrtPi = std::sqrt(kPi);
  const double fC0 = 1.0 / (2.0 * sqrtPi), fC1 = std::sqrt(3.0) / (3.0 * sqrtPi);
  const double fC2 = std::sqrt(15.0) / (8.0 * sqrtPi), fC3 = std::sqrt(5.0) / (16.0 * sqrtPi);
  const double fC4 = 0.5 * fC2;
  UnityPacking p;
  for (int iC = 0; iC < 3; ++iC) {
    const double a[4] = {-fC1 * sh[3][iC], -fC1 * sh[1][iC], fC1 * sh[2][iC],
                         fC0 * sh[0][iC] - fC3 * sh[6][iC]};
    const double as[4] = {std::abs(a[0]), std::abs(a[1]), std::abs(a[2]),
                          std::abs(fC0 * sh[0][iC]) + std::abs(fC3 * sh[6][iC])};
    const double b[4] = {fC2 * sh[4][iC], -fC2 * sh[5][iC], 3.0 * fC3 * sh[6][iC],
                         -fC2 * sh[7][iC]};
    for (int k = 0; k < 4; ++k) {
      p.value[iC][k] = a[k];
      p.scale[iC][k] = as[k];
      p.value[iC + 3][k] = b[k];
      p.scale[iC + 3][k] = std::abs(b[k]);
    }
    p.value[6][iC] = fC4 * sh[8][iC];
    p.scale[6][iC] = std::abs(p.value[6][iC]);
  }
  p.value[6][3] = 1.0;
  p.scale[6][3] = 1.0;
  return p;
}

// One arbitrary vector: distinct, non-round values in every (coefficient, channel), mixed signs,
// so a swapped index, channel, sign or factor changes some entry by ~ the entry itself.
constexpr double kArbitrarySh[9][3] = {
    {1.731, 0.912, 2.404},   {-0.377, 0.158, -0.629}, {0.843, -0.266, 0.512},
    {-0.195, 0.701, 0.333},  {0.467, -0.588, -0.049}, {-0.724, 0.091, 0.386},
    {0.259, -0.413, -0.817}, {0.632, 0.374, -0.148},  {-0.551, 0.207, 0.694}};

// got (float) = float(x) for the library's double x = expected + δ, |δ| <= a few double roundings
// of the entry's terms (<= 16 eps · scale, generously: each term is one product, the w entry one
// more subtraction; the kUnityYUp case adds the SH rotation, accurate to ~10 eps of the inputs,
// which the caller folds into scale). Rounding to float adds <= 2^-24 |x|. A wrong sign, index
// or constant moves an entry by O(|entry|) >> 2^-24 |entry|.
void ExpectPackingEquals(const UnitySh9Constants& got, const UnityPacking& expected,
                         double extraScale) {
  static const char* const kNames[7] = {"SHAr", "SHAg", "SHAb", "SHBr", "SHBg", "SHBb", "SHC"};
  for (int v = 0; v < 7; ++v) {
    for (int k = 0; k < 4; ++k) {
      const double e = expected.value[v][k];
      const double tol = std::ldexp(std::abs(e), -24) +
                         16 * test::kDoubleEps * (expected.scale[v][k] + extraScale);
      EXPECT_NEAR(got.v[v][k], e, tol) << kNames[v] << "[" << k << "]";
    }
  }
}

TEST(UnitySh9, PackingMatchesConvertShConstantsLiterally) {
  // Unity's constants are probebake's basis constants (docs/spherical-harmonics.md, 9 digits) times
  // Â_l/π (Â = π, 2π/3, π/4): fC0 = Y00, fC1 = 0.488602512 · 2/3, fC2 = 1.092548431/4,
  // 3 fC3 = 0.946174696/4, fC4 = 0.546274215/4. The documented constants are rounded to 9 decimals
  // (<= 5e-10), so they agree to 1e-9 absolute.
  const double sqrtPi = std::sqrt(kPi);
  EXPECT_NEAR(1.0 / (2.0 * sqrtPi), 0.282094792, 1e-9);
  EXPECT_NEAR(std::sqrt(3.0) / (3.0 * sqrtPi), 0.488602512 * 2 / 3, 1e-9);
  EXPECT_NEAR(std::sqrt(15.0) / (8.0 * sqrtPi), 1.092548431 / 4, 1e-9);
  EXPECT_NEAR(3 * std::sqrt(5.0) / (16.0 * sqrtPi), 0.946174696 / 4, 1e-9);
  EXPECT_NEAR(0.5 * std::sqrt(15.0) / (8.0 * sqrtPi), 0.546274215 / 4, 1e-9);

  std::vector<Vec3d> radiance(9);
  for (int i = 0; i < 9; ++i)
    radiance[i] = {kArbitrarySh[i][0], kArbitrarySh[i][1], kArbitrarySh[i][2]};
  const UnitySh9Constants ours = PackUnitySh9(radiance, UnityAxes::kProbebake);
  ExpectPackingEquals(ours, UnityConvertShConstants(kArbitrarySh), 0);
  EXPECT_EQ(ours.v[6][3], 1.0f);

  // kUnityYUp: Unity's formula applied to the coefficients of L'(n_u) = L(M n_u), M: (x, y, z)
  // -> (x, z, y). c'_i = ∫ L(ω) Y_i(M ω) dω, and by the closed forms of docs/spherical-harmonics.md
  // at M ω = (x, z, y) (k1 = 0.488602512, k2 = 1.092548431, k6 = 0.946174696, k8 = 0.546274215):
  //   Y1(Mω) = -k1 z = -Y2, Y2(Mω) = k1 y = -Y1, Y3(Mω) = Y3, Y4(Mω) = k2 xz = -Y7,
  //   Y5(Mω) = -k2 zy = Y5, Y7(Mω) = -k2 xy = -Y4,
  //   Y6(Mω) = k6 (y² - 1/3) = -Y6/2 - (√3/2) Y8, Y8(Mω) = k8 (x² - z²) = -(√3/2) Y6 + Y8/2
  // (using x² + y² + z² = 1 and k6/k8 = √3).
  const double h = std::sqrt(3.0) / 2;
  double yUp[9][3];
  double maxAbs = 0;
  for (int ch = 0; ch < 3; ++ch) {
    double c[9];
    for (int i = 0; i < 9; ++i) {
      c[i] = kArbitrarySh[i][ch];
      maxAbs = std::max(maxAbs, std::abs(c[i]));
    }
    yUp[0][ch] = c[0];
    yUp[1][ch] = -c[2];
    yUp[2][ch] = -c[1];
    yUp[3][ch] = c[3];
    yUp[4][ch] = -c[7];
    yUp[5][ch] = c[5];
    yUp[6][ch] = -0.5 * c[6] - h * c[8];
    yUp[7][ch] = -c[4];
    yUp[8][ch] = -h * c[6] + 0.5 * c[8];
  }
  // The library rotates by an exact-up-to-rounding SH rotation: each rotated coefficient is off
  // by <= ~10 eps · max|c| (a 5-term dot product of O(1) matrix entries): fold max|c| into scale.
  ExpectPackingEquals(PackUnitySh9(radiance, UnityAxes::kUnityYUp), UnityConvertShConstants(yUp),
                      maxAbs);
}

TEST(UnitySh9, Prints) {
  std::ostringstream os;
  os << PackUnitySh9(RandomRadiance(1), UnityAxes::kProbebake);
  EXPECT_NE(os.str().find("SHAr ("), std::string::npos) << os.str();
  EXPECT_NE(os.str().find("SHC ("), std::string::npos) << os.str();
}

}  // namespace
}  // namespace probebake
