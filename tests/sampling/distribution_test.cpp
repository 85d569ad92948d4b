#include "probebake/sampling/distribution.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "sampling/stats.h"

namespace probebake {
namespace {

using testing::ChiSquareTest;

constexpr double kEps = std::numeric_limits<double>::epsilon();  // 2^-52
constexpr double kAlpha = 1e-6;  // significance of every chi-square test in this file

// Exact-enough reference probabilities: long double (64-bit mantissa) sums of the weights, whose
// error (n * 2^-64 relative) is far below the double tolerances checked against them.
std::vector<double> ReferencePmf(const std::vector<double>& w) {
  long double total = 0;
  for (double x : w) total += x;
  std::vector<double> p(w.size());
  for (size_t i = 0; i < w.size(); ++i) p[i] = static_cast<double>(w[i] / total);
  return p;
}

std::vector<double> RandomWeights(int n, uint64_t stream, double zeroFraction) {
  IndependentSampler s(21, stream);
  std::vector<double> w(n);
  for (int i = 0; i < n; ++i) {
    s.StartSample(i);
    w[i] = s.Get1D() < zeroFraction ? 0.0 : 0.1 + s.Get1D();
  }
  return w;
}

// Pmf is w_i / sum(w) to a few ulp(1): each CDF entry is the compensated prefix sum (relative
// error ~2 eps) divided by the total (eps/2), so |cdf_i - exact| <= 3 eps * cdf_i <= 3 eps and the
// width of an interval is off by <= 6 eps absolute (plus its own subtraction, <= eps/2 * pmf).
constexpr double kPmfTolerance = 8 * kEps;

TEST(DiscreteDistribution, PmfIsNormalisedWeight) {
  const std::vector<double> w = RandomWeights(1000, 1, 0.2);
  const DiscreteDistribution d(w);
  ASSERT_EQ(d.Size(), 1000);
  const std::vector<double> ref = ReferencePmf(w);
  double sum = 0;
  for (int i = 0; i < 1000; ++i) {
    EXPECT_NEAR(d.Pmf(i), ref[i], kPmfTolerance) << "index " << i;
    if (w[i] == 0) {
      EXPECT_EQ(d.Pmf(i), 0.0) << "index " << i;
    }
    sum += d.Pmf(i);
  }
  EXPECT_NEAR(sum, 1, 1000 * kEps);  // telescoping sum of 1000 differences
}

TEST(DiscreteDistribution, SamplingFrequenciesMatchPmf) {
  const std::vector<double> w = RandomWeights(500, 2, 0.2);
  const DiscreteDistribution d(w);
  constexpr int kSamples = 1 << 20;
  std::vector<double> observed(500, 0), expected(500);
  for (int i = 0; i < 500; ++i) expected[i] = d.Pmf(i) * kSamples;
  IndependentSampler s(22, 0);
  for (int n = 0; n < kSamples; ++n) {
    s.StartSample(n);
    const double u = s.Get1D();
    const DiscreteSample x = d.Sample(u);
    ASSERT_GT(x.pmf, 0);
    ASSERT_EQ(x.pmf, d.Pmf(x.index));  // same double, not merely close
    observed[x.index] += 1;
  }
  const auto r = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r.pass) << r.ToString();
}

// The remapped u is uniform given the index and overall: chi-square of u' over 256 bins, with
// all samples pooled (each index contributes a uniform u', so the mixture is uniform).
TEST(DiscreteDistribution, RemappedUIsUniform) {
  const std::vector<double> w = RandomWeights(37, 3, 0.1);
  const DiscreteDistribution d(w);
  constexpr int kSamples = 1 << 20;
  std::vector<double> observed(256, 0), expected(256, kSamples / 256.0);
  IndependentSampler s(23, 0);
  for (int n = 0; n < kSamples; ++n) {
    s.StartSample(n);
    const DiscreteSample x = d.Sample(s.Get1D());
    ASSERT_GE(x.uRemapped, 0);
    ASSERT_LT(x.uRemapped, 1);
    observed[static_cast<int>(x.uRemapped * 256)] += 1;
  }
  const auto r = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r.pass) << r.ToString();
}

TEST(DiscreteDistribution, InvertsSample) {
  const std::vector<double> w = RandomWeights(1000, 4, 0.3);
  const DiscreteDistribution d(w);
  IndependentSampler s(24, 0);
  for (int n = 0; n < 100000; ++n) {
    s.StartSample(n);
    const double u = s.Get1D();
    const DiscreteSample x = d.Sample(u);
    const double back = d.Invert(x.index, x.uRemapped);
    // u' = (u - c) / p and back = c + u' p: two roundings of size eps * (c + p) <= 2 eps.
    ASSERT_NEAR(back, u, 2 * kEps) << "index " << x.index;
    ASSERT_EQ(d.Sample(back).index, x.index);
  }
  // Invert always lands inside the index's interval, even for u' at its top.
  for (int i = 0; i < 1000; ++i) {
    if (w[i] == 0) continue;
    ASSERT_EQ(d.Sample(d.Invert(i, kOneMinusEpsilon)).index, i);
    ASSERT_EQ(d.Sample(d.Invert(i, 0)).index, i);
  }
}

// Sample's search against the definition: the index is the last one of positive weight whose
// interval starts at or below u (Invert(i, 0) is that start exactly). The tables mix sizes from 1
// up and runs of tiny and zero weights beside large ones, so the guide's ranges take every length
// from 0 to past the counted window, and windows run past the last entry.
TEST(DiscreteDistribution, SampleFindsTheIntervalOfU) {
  std::vector<std::vector<double>> tables;
  for (int n = 1; n <= 12; ++n) tables.push_back(RandomWeights(n, 100 + n, 0.3));
  for (int run = 1; run <= 20; ++run) {
    std::vector<double> w;
    for (int k = 0; k < 6; ++k) {
      w.push_back(1.0);
      for (int t = 0; t < run; ++t) w.push_back(t % 3 == 2 ? 0.0 : 1e-3 * (t + 1));
    }
    tables.push_back(w);
  }
  IndependentSampler s(25, 0);
  for (size_t t = 0; t < tables.size(); ++t) {
    const std::vector<double>& w = tables[t];
    const DiscreteDistribution d(w);
    for (int k = 0; k < 4096; ++k) {
      s.StartSample(k);
      const double u = k < 2048 ? k / 2048.0 : s.Get1D();
      int64_t expected = -1;
      for (int64_t i = 0; i < d.Size(); ++i) {
        if (d.Pmf(i) > 0 && d.Invert(i, 0) <= u) expected = i;
      }
      ASSERT_EQ(d.Sample(u).index, expected) << "table " << t << ", u = " << u;
    }
  }
}

TEST(DiscreteDistribution, ZeroWeightsAreNeverSampled) {
  // Sweep u over a fine deterministic grid; zero-weight indices, including leading, trailing and
  // consecutive ones, must never come out.
  const std::vector<double> w = {0, 0, 1, 0, 2, 0, 0, 3, 0};
  const DiscreteDistribution d(w);
  for (int k = 0; k < (1 << 16); ++k) {
    const int64_t i = d.Sample(k / 65536.0).index;
    ASSERT_GT(w[i], 0) << "u = " << k / 65536.0;
  }
  EXPECT_EQ(d.Sample(0).index, 2);
  EXPECT_EQ(d.Sample(kOneMinusEpsilon).index, 7);
  EXPECT_EQ(d.Pmf(2), 1.0 / 6);
}

TEST(DiscreteDistribution, AllZeroWeightsAreUniform) {
  const std::vector<double> w(10, 0.0);
  const DiscreteDistribution d(w);
  EXPECT_EQ(d.Total(), 0);
  for (int i = 0; i < 10; ++i) EXPECT_NEAR(d.Pmf(i), 0.1, kEps);
  for (int k = 0; k < 10; ++k) EXPECT_EQ(d.Sample((k + 0.5) / 10).index, k);
}

TEST(DiscreteDistribution, SingleWeight) {
  const std::vector<double> w = {3.5};
  const DiscreteDistribution d(w);
  EXPECT_EQ(d.Total(), 3.5);
  EXPECT_EQ(d.Pmf(0), 1.0);
  const DiscreteSample x = d.Sample(0.25);
  EXPECT_EQ(x.index, 0);
  EXPECT_EQ(x.uRemapped, 0.25);
}

// HDR dynamic range: one 1e9 "sun" followed by 10^6 texels of 1e-6. The small weights' total is
// exactly 1 (probability 1/(1e9 + 1) ~ 1e-9). Plain double summation would add each 1e-6 to
// ~1e9, where ulp = 1.2e-7, losing ~5% of every small weight; compensated sums keep the mass.
TEST(DiscreteDistribution, SmallWeightsAfterAHugeOneKeepTheirMass) {
  constexpr int kSmall = 1000000;
  std::vector<double> w(kSmall + 1, 1e-6);
  w[0] = 1e9;
  const DiscreteDistribution d(w);
  // Total: exact value 1e9 + 1 (up to the representation of 1e-6: relative 1e-16).
  EXPECT_NEAR(d.Total(), 1e9 + 1, 1e9 * 4 * kEps);
  // Mass of the small block = 1 - cdf_1 = 1 - Pmf(0); exact 1/(1e9 + 1). The CDF entry near 1 is
  // good to ~3 eps (see kPmfTolerance), i.e. 3.3e-7 relative to the 1e-9 block mass.
  const double smallMass = 1 - d.Pmf(0);
  const double exact = 1 / (1e9 + 1);
  EXPECT_NEAR(smallMass / exact, 1, 4 * kEps / exact);
  // Every small texel keeps a positive pmf, each close to 1e-15 within the absolute bound.
  const std::vector<double> ref = ReferencePmf(w);
  for (int i = 1; i <= kSmall; ++i) {
    ASSERT_GT(d.Pmf(i), 0) << i;
    ASSERT_NEAR(d.Pmf(i), ref[i], kPmfTolerance) << i;
  }
}

// Weights spanning 1e-6 .. 1e9 log-uniformly, shuffled: pmf within the absolute bound, relative
// accuracy for every index whose probability is large enough for the bound to be relative, all
// positive, and the sampling frequencies match (chi-square, pooling the tiny ones).
TEST(DiscreteDistribution, ExtremeDynamicRange) {
  constexpr int n = 100000;
  std::vector<double> w(n);
  IndependentSampler s(25, 0);
  for (int i = 0; i < n; ++i) {
    s.StartSample(i);
    w[i] = std::pow(10.0, -6 + 15 * s.Get1D());
  }
  const DiscreteDistribution d(w);
  const std::vector<double> ref = ReferencePmf(w);
  for (int i = 0; i < n; ++i) {
    ASSERT_GT(d.Pmf(i), 0) << i;
    ASSERT_NEAR(d.Pmf(i), ref[i], kPmfTolerance) << i;
    if (ref[i] > 1e-6) {
      ASSERT_NEAR(d.Pmf(i) / ref[i], 1, kPmfTolerance / 1e-6) << i;
    }
  }
  constexpr int kSamples = 1 << 20;
  std::vector<double> observed(n, 0), expected(n);
  for (int i = 0; i < n; ++i) expected[i] = d.Pmf(i) * kSamples;
  for (int k = 0; k < kSamples; ++k) {
    s.StartSample(n + k);
    observed[d.Sample(s.Get1D()).index] += 1;
  }
  const auto r = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r.pass) << r.ToString();
}

// ---- PiecewiseConstant2D.

TEST(PiecewiseConstant2D, PmfSamplingAndRemapping) {
  constexpr int rows = 16, cols = 24;
  std::vector<double> w = RandomWeights(rows * cols, 5, 0.15);
  for (int c = 0; c < cols; ++c) w[3 * cols + c] = 0;  // a black row
  w[7 * cols + 5] = 1e7;                               // a sun
  const PiecewiseConstant2D d(w, rows, cols);
  EXPECT_EQ(d.Rows(), rows);
  EXPECT_EQ(d.Cols(), cols);
  const std::vector<double> ref = ReferencePmf(w);
  double sum = 0;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      // Product of a marginal and a conditional pmf, each within 8 eps absolute of exact, and
      // each <= 1: |error| <= 16 eps + rounding.
      EXPECT_NEAR(d.Pmf(r, c), ref[r * cols + c], 20 * kEps) << r << ", " << c;
      if (w[r * cols + c] == 0) {
        EXPECT_EQ(d.Pmf(r, c), 0.0);
      }
      sum += d.Pmf(r, c);
    }
  }
  EXPECT_NEAR(sum, 1, rows * cols * 4 * kEps);

  constexpr int kSamples = 1 << 20;
  std::vector<double> observed(rows * cols, 0), expected(rows * cols);
  for (int i = 0; i < rows * cols; ++i) expected[i] = d.Pmf(i / cols, i % cols) * kSamples;
  std::vector<double> remapObserved(16 * 16, 0), remapExpected(16 * 16, kSamples / 256.0);
  IndependentSampler s(26, 0);
  for (int n = 0; n < kSamples; ++n) {
    s.StartSample(n);
    const Vec2d u = s.Get2D();
    const PiecewiseConstant2DSample x = d.Sample(u);
    ASSERT_GT(x.pmf, 0);
    ASSERT_EQ(x.pmf, d.Pmf(x.row, x.col));
    observed[x.row * cols + x.col] += 1;
    ASSERT_TRUE(x.uRemapped.x >= 0 && x.uRemapped.x < 1 && x.uRemapped.y >= 0 && x.uRemapped.y < 1);
    remapObserved[int(x.uRemapped.x * 16) * 16 + int(x.uRemapped.y * 16)] += 1;
    if (n < 100000) {
      const Vec2d back = d.Invert(x.row, x.col, x.uRemapped);
      ASSERT_NEAR(back.x, u.x, 2 * kEps);
      ASSERT_NEAR(back.y, u.y, 2 * kEps);
    }
  }
  const auto r1 = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r1.pass) << "cells: " << r1.ToString();
  const auto r2 = ChiSquareTest(remapObserved, remapExpected, kAlpha);
  EXPECT_TRUE(r2.pass) << "remapped u: " << r2.ToString();
}

// Prefetch loads the row Sample will read (the same row, always) and guesses a column of it from
// the guide bucket, exact where the row is uniform.
TEST(PiecewiseConstant2D, PrefetchPicksTheSampledRowAndGuessesItsColumn) {
  constexpr int rows = 24, cols = 40;
  std::vector<double> w = RandomWeights(rows * cols, 12, 0.1);
  for (int c = 0; c < cols; ++c) w[2 * cols + c] = 3;  // a uniform row
  const PiecewiseConstant2D d(w, rows, cols);
  IndependentSampler s(28, 0);
  int uniformRowSamples = 0;
  for (int n = 0; n < 100000; ++n) {
    s.StartSample(n);
    const Vec2d u = s.Get2D();
    int64_t row, col;
    d.Prefetch(u, &row, &col);
    const PiecewiseConstant2DSample x = d.Sample(u);
    ASSERT_EQ(row, x.row);
    ASSERT_TRUE(col >= 0 && col < cols);
    if (x.row == 2) {
      ++uniformRowSamples;
      ASSERT_EQ(col, x.col) << u.x;
    }
  }
  EXPECT_GT(uniformRowSamples, 100);
}

TEST(PiecewiseConstant2D, RowThenColumnIsSample) {
  constexpr int rows = 24, cols = 40;
  const PiecewiseConstant2D d(RandomWeights(rows * cols, 13, 0.1), rows, cols);
  IndependentSampler s(29, 0);
  for (int n = 0; n < 10000; ++n) {
    s.StartSample(n);
    const Vec2d u = s.Get2D();
    const PiecewiseConstant2DSample x = d.Sample(u);
    const DiscreteSample r = d.SampleRow(u.y);
    const DiscreteSample c = d.SampleColumn(r.index, u.x);
    ASSERT_EQ(r.index, x.row);
    ASSERT_EQ(c.index, x.col);
    ASSERT_EQ(r.pmf * c.pmf, x.pmf);
    ASSERT_EQ(c.uRemapped, x.uRemapped.x);
    ASSERT_EQ(r.uRemapped, x.uRemapped.y);
  }
}

TEST(PiecewiseConstant2D, AllZeroIsUniform) {
  const std::vector<double> w(6 * 4, 0.0);
  const PiecewiseConstant2D d(w, 6, 4);
  EXPECT_EQ(d.Total(), 0);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(d.Pmf(r, c), 1.0 / 24, 2 * kEps);
  const PiecewiseConstant2DSample x = d.Sample({0.6, 0.9});
  EXPECT_EQ(x.row, 5);
  EXPECT_EQ(x.col, 2);
}

// An HDR environment: 512 x 256 sky of 1e-3..1 with a 1e9 sun texel; every texel keeps a
// positive pmf within the absolute bound, and the sun is chosen with its probability.
TEST(PiecewiseConstant2D, HdrSunBesideDimSky) {
  constexpr int rows = 256, cols = 512;
  std::vector<double> w = RandomWeights(rows * cols, 6, 0.0);
  for (double& x : w) x *= 1e-3;
  w[40 * cols + 300] = 1e9;
  const PiecewiseConstant2D d(w, rows, cols);
  const std::vector<double> ref = ReferencePmf(w);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      ASSERT_GT(d.Pmf(r, c), 0);
      ASSERT_NEAR(d.Pmf(r, c), ref[r * cols + c], 20 * kEps);
    }
  EXPECT_NEAR(d.Pmf(40, 300) / ref[40 * cols + 300], 1, 20 * kEps);
}

}  // namespace
}  // namespace probebake
