#include "probebake/sh/sh_projection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sphere_quadrature.h"
#include "sh/sh_test_util.h"

namespace probebake {
namespace {

using test::kDoubleEps;
using test::kPi;

std::vector<double> RandomCoefficients(int order, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> f(ShCoeffCount(order));
  for (double& c : f) c = u(rng);
  return f;
}

TEST(ShProjection, QuadratureProjectionRecoversAnExpansion) {
  // f = Σ c_i Y_i of order L projected with a rule exact for degree 2L returns c to rounding
  // (~(nodes) eps max|f Y| ≈ 200 · 2.2e-16 · 10 < 1e-12).
  for (int order : {0, 1, 2, 4, 8, kMaxShOrder}) {
    const std::vector<double> c = RandomCoefficients(order, 40 + order);
    const auto nodes = SphereQuadratureForDegree(2 * order);
    std::vector<double> p(c.size());
    ShProjectQuadrature(
        order, std::span<const SphereQuadratureNode>(nodes),
        [&](const Vec3d& w) { return ShReconstruct(order, c, w); }, std::span<double>(p));
    for (size_t i = 0; i < c.size(); ++i) ASSERT_NEAR(p[i], c[i], 1e-12) << "order " << order;
    // RGB: three different functions at once (the -2x channel doubles the rounding: 2e-12).
    std::vector<Vec3d> rgb(c.size()), prgb(c.size());
    for (size_t i = 0; i < c.size(); ++i) rgb[i] = {c[i], -2 * c[i], c[c.size() - 1 - i]};
    ShProjectQuadrature(
        order, std::span<const SphereQuadratureNode>(nodes),
        [&](const Vec3d& w) { return ShReconstructRgb(order, rgb, w); }, std::span<Vec3d>(prgb));
    for (size_t i = 0; i < c.size(); ++i)
      for (int k = 0; k < 3; ++k) ASSERT_NEAR(prgb[i][k], rgb[i][k], 2e-12) << "order " << order;
  }
}

TEST(ShProjection, WhiteFurnace) {
  // Constant 1: f_00 = ∫ Y00 = 4π / (2 sqrt(π)) = 2 sqrt(π); all others vanish. The rule is
  // exact for degree 4; rounding over 15 nodes of weights summing to 4π: ~1e-15; bound 1e-14.
  const int order = 4;
  const auto nodes = SphereQuadratureForDegree(order);
  std::vector<double> p(ShCoeffCount(order));
  ShProjectQuadrature(
      order, std::span<const SphereQuadratureNode>(nodes), [](const Vec3d&) { return 1.0; },
      std::span<double>(p));
  EXPECT_NEAR(p[0], 2 * std::sqrt(kPi), 1e-14);
  for (size_t i = 1; i < p.size(); ++i) EXPECT_NEAR(p[i], 0.0, 1e-14) << i;
}

TEST(ShProjection, ReconstructionAndProductIntegral) {
  const int order = 5;
  const std::vector<double> f = RandomCoefficients(order, 1), g = RandomCoefficients(order, 2);
  // ∫ f g by a rule exact for degree 2L equals the coefficient dot product, up to rounding over
  // 66 nodes of a sum of ~36² O(1) products: ~1e-14; bound 1e-12. The RGB variants run the same
  // arithmetic per channel, so they must agree exactly.
  double integral = 0;
  for (const auto& node : SphereQuadratureForDegree(2 * order)) {
    integral += node.weight * ShReconstruct(order, f, node.direction) *
                ShReconstruct(order, g, node.direction);
  }
  EXPECT_NEAR(ShDot(order, f, g), integral, 1e-12);
  // RGB variants agree with the scalar ones channel by channel.
  std::vector<Vec3d> frgb(f.size()), grgb(f.size());
  for (size_t i = 0; i < f.size(); ++i) frgb[i] = {f[i], g[i], -f[i]}, grgb[i] = {g[i], g[i], f[i]};
  const Vec3d d = ShDotRgb(order, frgb, grgb);
  EXPECT_EQ(d.x, ShDot(order, f, g));
  EXPECT_EQ(d.y, ShDot(order, g, g));
  const Vec3d dm = ShDotRgb(order, frgb, g);
  EXPECT_EQ(dm.x, ShDot(order, f, g));
  EXPECT_EQ(dm.y, ShDot(order, g, g));
  const Vec3d w = Normalize(Vec3d{-0.3, 0.1, 0.9});
  const Vec3d r = ShReconstructRgb(order, frgb, w);
  EXPECT_EQ(r.x, ShReconstruct(order, f, w));
  EXPECT_EQ(r.y, ShReconstruct(order, g, w));
}

// Samples for the drift test: a cycle of K (direction, value) pairs with values spread over six
// decades (fireflies among dim samples), so magnitudes differ as in a real bake.
struct Sample {
  std::vector<double> basis;
  double value;
};

std::vector<Sample> CycleOfSamples(int order, int k) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0, 1);
  const std::vector<Vec3d> dirs = test::RandomDirections(k, 18);
  std::vector<Sample> samples;
  for (int j = 0; j < k; ++j) {
    Sample s{std::vector<double>(ShCoeffCount(order)), std::pow(10.0, 6 * u(rng) - 3)};
    EvalShBasis(order, dirs[j], s.basis.data());
    samples.push_back(std::move(s));
  }
  return samples;
}

// Exact product a·b as an unevaluated sum hi + lo (Dekker/Veltkamp, no FMA needed).
void TwoProduct(double a, double b, double& hi, double& lo) {
  hi = a * b;
  auto split = [](double x, double& xh, double& xl) {
    const double c = 134217729.0 * x;  // 2^27 + 1
    xh = c - (c - x);
    xl = x - xh;
  };
  double ah, al, bh, bl;
  split(a, ah, al);
  split(b, bh, bl);
  lo = ((ah * bh - hi) + ah * bl + al * bh) + al * bl;
}

TEST(ShAccumulator, HundredMillionSamplesStayWithinTheBlockedBound) {
  // 1e8 samples cycling through K = 1009 (prime) sample contributions x_k,i = fl(value · Y_i).
  // The exact sum is Σ_j n_j x_j with n_j the number of times sample j occurs; n_j · x_j is
  // formed exactly as a double-double and the K terms summed in long double with Kahan's
  // compensation: that reference is accurate to ~1e-19 relative, far below what is tested.
  // Bound (header): |error_i| <= (kBlockSize + 2) u Σ_k |x_k,i|, u = 2^-53 — independent of the
  // number of samples. A float running sum is also run to show the test detects drift: it must
  // be off by more than 1e-4 relative where ours is within ~3e-14.
  const int order = 2;
  const int64_t kSamples = 100'000'000;
  const int kCycle = 1009;
  const std::vector<Sample> samples = CycleOfSamples(order, kCycle);
  const int n = ShCoeffCount(order);

  ShAccumulator acc(order);
  std::vector<float> floatSum(n, 0.0f);
  for (int64_t k = 0; k < kSamples; ++k) {
    const Sample& s = samples[k % kCycle];
    acc.AddBasis(s.basis, s.value);
    for (int i = 0; i < n; ++i) floatSum[i] += static_cast<float>(s.basis[i] * s.value);
  }
  EXPECT_EQ(acc.count(), kSamples);
  std::vector<double> sum(n);
  acc.Sum(sum);

  const double u = kDoubleEps / 2;
  for (int i = 0; i < n; ++i) {
    long double ref = 0, comp = 0, absSum = 0;
    auto kahan = [&](long double x) {
      const long double y = x - comp;
      const long double t = ref + y;
      comp = (t - ref) - y;
      ref = t;
    };
    for (int j = 0; j < kCycle; ++j) {
      const double x = samples[j].basis[i] * samples[j].value;  // what the accumulator adds
      const int64_t count = kSamples / kCycle + (j < kSamples % kCycle ? 1 : 0);
      double hi, lo;
      TwoProduct(static_cast<double>(count), x, hi, lo);
      kahan(hi);
      kahan(lo);
      absSum += std::abs(static_cast<long double>(x)) * count;
    }
    const double bound = (ShAccumulator::kBlockSize + 2) * u * static_cast<double>(absSum);
    const double error = std::abs(sum[i] - static_cast<double>(ref));
    EXPECT_LE(error, bound) << "coefficient " << i << ": expected " << static_cast<double>(ref)
                            << ", got " << sum[i];
    const double floatError = std::abs(floatSum[i] - static_cast<double>(ref));
    EXPECT_GT(floatError, 1e-4 * std::abs(static_cast<double>(ref)))
        << "a float sum should drift; coefficient " << i;
    RecordProperty("coefficient_" + std::to_string(i) + "_error_over_abs_sum",
                   test::Sci(error / static_cast<double>(absSum)));
    RecordProperty("coefficient_" + std::to_string(i) + "_float_relative_error",
                   test::Sci(floatError / std::abs(static_cast<double>(ref))));
  }
}

TEST(ShAccumulator, DeterministicAndMergeable) {
  const int order = 3;
  const std::vector<Sample> samples = CycleOfSamples(order, 5000);
  ShAccumulator a(order), b(order), whole(order), first(order), second(order);
  for (const Sample& s : samples) {
    a.AddBasis(s.basis, s.value);
    b.AddBasis(s.basis, s.value);
  }
  std::vector<double> sa(ShCoeffCount(order)), sb(sa.size());
  a.Sum(sa);
  b.Sum(sb);
  for (size_t i = 0; i < sa.size(); ++i) EXPECT_EQ(sa[i], sb[i]) << "not reproducible";
  // Merging two halves (split off a block boundary) stays within the same error bound of the
  // whole: both are within (B + 2) u Σ|x| of the exact sum.
  double absSum[16] = {};
  for (size_t k = 0; k < samples.size(); ++k) {
    (k < 1234 ? first : second).AddBasis(samples[k].basis, samples[k].value);
    for (int i = 0; i < 16; ++i) absSum[i] += std::abs(samples[k].basis[i] * samples[k].value);
  }
  first.Merge(second);
  EXPECT_EQ(first.count(), static_cast<int64_t>(samples.size()));
  std::vector<double> merged(sa.size());
  first.Sum(merged);
  for (size_t i = 0; i < sa.size(); ++i) {
    const double bound = 2 * (ShAccumulator::kBlockSize + 2) * (kDoubleEps / 2) * absSum[i];
    EXPECT_NEAR(merged[i], sa[i], bound) << i;
  }
  // Reset empties; Sum scales (one sample: Y_10(+Z) · 2 · 0.5, two roundings of sqrt(3/(4π))).
  a.Reset();
  EXPECT_EQ(a.count(), 0);
  a.Add(Vec3d{0, 0, 1}, 2.0);
  std::vector<double> one(sa.size());
  a.Sum(one, 0.5);
  EXPECT_NEAR(one[ShIndex(1, 0)], std::sqrt(3 / (4 * kPi)), 1e-16);
}

TEST(ShAccumulator, RgbMatchesThreeScalarAccumulators) {
  const int order = 2;
  const std::vector<Sample> samples = CycleOfSamples(order, 3000);
  ShAccumulatorRgb rgb(order);
  ShAccumulator r(order), g(order), b(order);
  for (const Sample& s : samples) {
    const Vec3d x{s.value, 2 * s.value, -s.value};
    rgb.AddBasis(s.basis, x);
    r.AddBasis(s.basis, x.x);
    g.AddBasis(s.basis, x.y);
    b.AddBasis(s.basis, x.z);
  }
  std::vector<Vec3d> out(ShCoeffCount(order));
  std::vector<double> rr(out.size()), gg(out.size()), bb(out.size());
  rgb.Sum(out);
  r.Sum(rr);
  g.Sum(gg);
  b.Sum(bb);
  for (size_t i = 0; i < out.size(); ++i) {
    EXPECT_EQ(out[i].x, rr[i]);
    EXPECT_EQ(out[i].y, gg[i]);
    EXPECT_EQ(out[i].z, bb[i]);
  }
}

}  // namespace
}  // namespace probebake
