#include "probebake/sh/sh_rotation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <sstream>
#include <vector>

#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sphere_quadrature.h"
#include "sh/sh_test_util.h"

namespace probebake {
namespace {

using test::kDoubleEps;

std::vector<double> RandomCoefficients(int order, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> f(ShCoeffCount(order));
  for (double& c : f) c = u(rng);
  return f;
}

double Reconstruct(int order, const std::vector<double>& f, const Vec3d& w) {
  std::vector<double> y(ShCoeffCount(order));
  EvalShBasis(order, w, y.data());
  double sum = 0;
  for (int i = 0; i < ShCoeffCount(order); ++i) sum += f[i] * y[i];
  return sum;
}

ShRotation MustCreate(int order, const Mat3d& r) {
  absl::StatusOr<ShRotation> rot = ShRotation::Create(order, r);
  EXPECT_TRUE(rot.ok()) << rot.status();
  return *std::move(rot);
}

// Matrices to test: random rotations, axis-aligned quarter turns, and improper ones.
std::vector<Mat3d> TestMatrices(bool improper) {
  std::mt19937_64 rng(1234);
  std::vector<Mat3d> ms;
  for (int i = 0; i < 12; ++i) ms.push_back(test::RandomRotation(rng));
  ms.push_back(Mat3d::Identity());
  ms.push_back(Mat3d::Rotation({0, 0, 1}, test::kPi / 2));
  ms.push_back(Mat3d::Rotation({1, 0, 0}, test::kPi));
  ms.push_back(Mat3d::Rotation(Normalize(Vec3d{1, 1, 1}), 2 * test::kPi / 3));
  if (improper) {
    const Mat3d swapYz = Mat3d::FromRows({1, 0, 0}, {0, 0, 1}, {0, 1, 0});
    const Mat3d mirrorZ = Mat3d::FromRows({1, 0, 0}, {0, 1, 0}, {0, 0, -1});
    const Mat3d inversion = Mat3d::FromRows({-1, 0, 0}, {0, -1, 0}, {0, 0, -1});
    const size_t proper = ms.size();
    for (size_t i = 0; i < proper; ++i) ms[i] = ms[i] * (i % 2 ? swapYz : mirrorZ);
    ms.push_back(swapYz);
    ms.push_back(mirrorZ);
    ms.push_back(inversion);
  }
  return ms;
}

// (R f)(ω) = f(Rᵀ ω): rotate the coefficients, evaluate at ω; evaluate the original at Rᵀ ω.
// Both sides are sums of ~(L+1)² O(1) terms through blocks built by ~L recurrence steps: the
// rounding is ~1e-14 at L = 9; the bound 1e-11 (order 8 must reach 1e-9) leaves room while any
// convention error (transpose, sign, band mix-up) gives O(1) differences.
void ExpectRotateThenEvaluateMatches(const std::vector<Mat3d>& matrices) {
  std::mt19937_64 rng(99);
  const std::vector<Vec3d> dirs = test::RandomDirections(60, 5);
  for (int order = 0; order <= kMaxShOrder; ++order) {
    for (const Mat3d& r : matrices) {
      const ShRotation rot = MustCreate(order, r);
      EXPECT_EQ(rot.improper(), Determinant(r) < 0);
      const std::vector<double> f = RandomCoefficients(order, rng);
      std::vector<double> g(f.size());
      rot.Apply(f, g);
      for (const Vec3d& w : dirs) {
        const double expected = Reconstruct(order, f, Transpose(r) * w);
        const double got = Reconstruct(order, g, w);
        ASSERT_NEAR(got, expected, 1e-11) << "order " << order << " R " << r << " at " << w;
      }
    }
  }
}

TEST(ShRotation, RotateThenEvaluateEqualsEvaluateAtRotatedDirection) {
  ExpectRotateThenEvaluateMatches(TestMatrices(false));
}

TEST(ShRotation, ImproperMatricesRotateAndInvert) {
  ExpectRotateThenEvaluateMatches(TestMatrices(true));
}

TEST(ShRotation, LobeFollowsTheMatrix) {
  // A lobe about d (c = Y(d)) rotated by R is the lobe about R d. Block entries carry ~1e-15
  // rounding from <= 8 recurrence steps, summed over <= 19 terms: ~1e-14; bound 1e-12.
  std::mt19937_64 rng(3);
  for (const Mat3d& r : TestMatrices(true)) {
    const Vec3d d = Normalize(Vec3d{0.2, -0.7, 0.4});
    std::vector<double> c(kMaxShCoeffCount), expected(kMaxShCoeffCount);
    EvalShBasis(kMaxShOrder, d, c.data());
    EvalShBasis(kMaxShOrder, r * d, expected.data());
    MustCreate(kMaxShOrder, r).Apply(c, c);  // in place
    for (int i = 0; i < kMaxShCoeffCount; ++i) ASSERT_NEAR(c[i], expected[i], 1e-12) << i;
  }
}

TEST(ShRotation, OrderEightMatchesProjectionOfRotatedFunction) {
  // Independent of evaluation identities: project ω -> f(Rᵀ ω) with a rule exact for degree 16
  // (f is a polynomial of degree 8, Y_i of degree 8) and compare with the rotated coefficients.
  // The quadrature only rounds (~1e-14); required accuracy at order 8: < 1e-9.
  const int order = 8;
  const auto nodes = SphereQuadratureForDegree(2 * order);
  std::mt19937_64 rng(2024);
  double worst = 0;
  for (int trial = 0; trial < 10; ++trial) {
    const Mat3d r = test::RandomRotation(rng);
    const std::vector<double> f = RandomCoefficients(order, rng);
    std::vector<double> rotated(f.size()), projected(f.size(), 0.0), y(f.size());
    MustCreate(order, r).Apply(f, rotated);
    for (const auto& node : nodes) {
      const double value = Reconstruct(order, f, Transpose(r) * node.direction);
      EvalShBasis(order, node.direction, y.data());
      for (size_t i = 0; i < f.size(); ++i) projected[i] += node.weight * value * y[i];
    }
    for (size_t i = 0; i < f.size(); ++i)
      worst = std::max(worst, std::abs(rotated[i] - projected[i]));
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_LT(worst, 1e-12) << "expected rounding-level agreement";
}

TEST(ShRotation, BlocksAreOrthogonal) {
  // Every band block of an orthogonal R is orthogonal: B Bᵀ = I to rounding (~1e-15 per entry).
  for (const Mat3d& r : TestMatrices(true)) {
    const ShRotation rot = MustCreate(kMaxShOrder, r);
    for (int l = 0; l <= kMaxShOrder; ++l) {
      for (int i = -l; i <= l; ++i)
        for (int j = -l; j <= l; ++j) {
          double dot = 0;
          for (int k = -l; k <= l; ++k) dot += rot.Element(l, i, k) * rot.Element(l, j, k);
          ASSERT_NEAR(dot, i == j ? 1.0 : 0.0, 1e-13) << "l " << l << " R " << r;
        }
    }
  }
}

TEST(ShRotation, IdentityCompositionAndInverse) {
  std::mt19937_64 rng(77);
  for (int order : {1, 2, 3, 5, 8, kMaxShOrder}) {
    const std::vector<double> f = RandomCoefficients(order, rng);
    std::vector<double> g(f.size()), h(f.size());
    // Identity: blocks are the identity up to the recurrence's sqrt roundings (~2 ulp per
    // step, compounded over <= 8 bands): 8 ulp of coefficients <= 1.
    MustCreate(order, Mat3d::Identity()).Apply(f, g);
    for (size_t i = 0; i < f.size(); ++i) EXPECT_NEAR(g[i], f[i], 8 * kDoubleEps) << i;
    for (int trial = 0; trial < 5; ++trial) {
      const Mat3d r1 = test::RandomRotation(rng), r2 = test::RandomRotation(rng);
      // Composition: rotating by r2 then r1 equals rotating by r1 r2. Each application rounds
      // ~1e-14 (see RotateThenEvaluate); three of them and the product r1 r2 stay below 1e-12.
      MustCreate(order, r2).Apply(f, g);
      MustCreate(order, r1).Apply(g, g);
      MustCreate(order, r1 * r2).Apply(f, h);
      for (size_t i = 0; i < f.size(); ++i) ASSERT_NEAR(g[i], h[i], 1e-12) << "order " << order;
      // Inverse: Rᵀ undoes R.
      MustCreate(order, r1).Apply(f, g);
      MustCreate(order, Transpose(r1)).Apply(g, g);
      for (size_t i = 0; i < f.size(); ++i) ASSERT_NEAR(g[i], f[i], 1e-12) << "order " << order;
    }
  }
}

TEST(ShRotation, BandOneIsThePermutedMatrix) {
  // The fast L1 case: the block is R on the basis order (y, z, x) with signs (-, +, -).
  std::mt19937_64 rng(5);
  const Mat3d r = test::RandomRotation(rng);
  const ShRotation rot = MustCreate(1, r);
  const int p[3] = {1, 2, 0};
  const double s[3] = {-1, 1, -1};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      EXPECT_EQ(rot.Element(1, i - 1, j - 1), s[i] * s[j] * r(p[i], p[j]));
  EXPECT_EQ(rot.Element(0, 0, 0), 1.0);
}

TEST(ShRotation, RgbMatchesPerChannel) {
  std::mt19937_64 rng(8);
  const int order = 4;
  const ShRotation rot = MustCreate(order, test::RandomRotation(rng));
  std::vector<Vec3d> rgb(ShCoeffCount(order)), out(ShCoeffCount(order));
  for (int c = 0; c < 3; ++c) {
    const std::vector<double> f = RandomCoefficients(order, rng);
    for (size_t i = 0; i < f.size(); ++i) rgb[i][c] = f[i];
  }
  rot.ApplyRgb(rgb, out);
  for (int c = 0; c < 3; ++c) {
    std::vector<double> f(rgb.size()), g(rgb.size());
    for (size_t i = 0; i < f.size(); ++i) f[i] = rgb[i][c];
    rot.Apply(f, g);
    for (size_t i = 0; i < f.size(); ++i) EXPECT_EQ(out[i][c], g[i]);
  }
}

TEST(ShRotation, RejectsBadInput) {
  EXPECT_FALSE(ShRotation::Create(-1, Mat3d::Identity()).ok());
  EXPECT_FALSE(ShRotation::Create(kMaxShOrder + 1, Mat3d::Identity()).ok());
  Mat3d scaled = Mat3d::Identity();
  scaled(0, 0) = 1.01;
  const absl::Status s = ShRotation::Create(2, scaled).status();
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(s.message()).find("rotation: matrix is not orthogonal"), std::string::npos)
      << s;
  Mat3d nan = Mat3d::Identity();
  nan(1, 2) = std::nan("");
  EXPECT_FALSE(ShRotation::Create(2, nan).ok());
  // A float-precision rotation is accepted.
  Mat3d rounded = Mat3d::Rotation(Normalize(Vec3d{1, 2, 3}), 0.3);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) rounded(i, j) = static_cast<float>(rounded(i, j));
  EXPECT_TRUE(ShRotation::Create(2, rounded).ok());
}

TEST(ShRotation, Prints) {
  std::ostringstream os;
  os << MustCreate(1, Mat3d::Identity());
  EXPECT_NE(os.str().find("ShRotation{order 1"), std::string::npos) << os.str();
}

}  // namespace
}  // namespace probebake
