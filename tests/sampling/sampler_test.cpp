#include "probebake/sampling/sampler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "probebake/sampling/sobol_chunk.h"
#include "sampling/stats.h"

namespace probebake {
namespace {

using testing::ChiSquareTest;

constexpr double kAlpha = 1e-6;  // significance of every chi-square test in this file

// ---- Sobol building blocks against known answers.

// Direction numbers of the second Sobol dimension (primitive polynomial x + 1, m_1 = 1): the
// Bratley-Fox / Joe-Kuo tables give m_k = 1, 3, 5, 15, 17, 51, 85, 255 (Pascal's triangle mod 2);
// the k-th direction number is m_k 2^(32-k) and is the point of index 2^(k-1).
TEST(Sobol, SecondDimensionDirectionNumbers) {
  const uint32_t m[] = {1, 3, 5, 15, 17, 51, 85, 255};
  for (int k = 1; k <= 8; ++k)
    EXPECT_EQ(SobolSample32(uint32_t{1} << (k - 1), 1), m[k - 1] << (32 - k)) << "k = " << k;
  // First points in natural index order.
  const double expected[] = {0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875};
  for (uint32_t i = 0; i < 8; ++i) EXPECT_EQ(U32ToUnit(SobolSample32(i, 1)), expected[i]);
  EXPECT_EQ(SobolSample32(0x80000000u, 0), 1u);
}

// The table-free bit-reversed dimension 1 is the same linear map over GF(2) as the generator
// tables: equal on the 32 basis indices (which proves it), and on a few mixed ones.
TEST(Sobol, SecondDimensionReversedEqualsTheTables) {
  for (int k = 0; k < 32; ++k) {
    const uint32_t basis = uint32_t{1} << k;
    EXPECT_EQ(SobolSample32Dim1Reversed(basis), ReverseBits32(SobolSample32(basis, 1))) << k;
  }
  for (uint32_t i : {0u, 3u, 0x12345678u, 0xffffffffu})
    EXPECT_EQ(SobolSample32Dim1Reversed(i), ReverseBits32(SobolSample32(i, 1))) << i;
}

TEST(Sobol, ReverseBits) {
  EXPECT_EQ(ReverseBits32(1u), 0x80000000u);
  EXPECT_EQ(ReverseBits32(0x12345678u), 0x1e6a2c48u);
  for (uint32_t v : {0u, 7u, 0xdeadbeefu}) EXPECT_EQ(ReverseBits32(ReverseBits32(v)), v);
}

// OwenScramble32 must be a base-2 digit scramble: output digit j (from the most significant) is
// input digit j XOR a function of the digits above it. Equivalently, two inputs that share their
// first j digits map to outputs sharing their first j digits, and differing in digit j+1 maps to
// differing digit j+1.
TEST(Sobol, OwenScrambleIsANestedDigitScramble) {
  uint64_t state = 99;
  for (int t = 0; t < 20000; ++t) {
    state = MixBits(state + 0x9e3779b97f4a7c15ull);
    const uint32_t seed = static_cast<uint32_t>(state >> 32);
    const uint32_t a = static_cast<uint32_t>(state);
    const int j = t % 32;  // number of shared leading digits
    const uint32_t flip = 0x80000000u >> j;
    const uint32_t b = (a ^ flip) ^ (static_cast<uint32_t>(MixBits(state)) & (flip - 1));
    const uint32_t sa = OwenScramble32(a, seed), sb = OwenScramble32(b, seed);
    const uint32_t prefixMask = ~((flip << 1) - 1);  // digits above j+1 (empty for j = 0)
    ASSERT_EQ(sa & prefixMask, sb & prefixMask) << "j = " << j;
    ASSERT_NE(sa & flip, sb & flip) << "j = " << j;
  }
}

// ---- Sampler contract.

template <typename S>
std::vector<double> Sequence(S sampler, uint64_t firstIndex, int count) {
  std::vector<double> v;
  for (int i = 0; i < count; ++i) {
    sampler.StartSample(firstIndex + i);
    v.push_back(sampler.Get1D());
    const Vec2d p = sampler.Get2D();
    v.push_back(p.x);
    v.push_back(p.y);
    v.push_back(sampler.Get1D());
  }
  return v;
}

template <typename S>
void ExpectDeterministic() {
  // Same inputs, same bits.
  EXPECT_EQ(Sequence(S(3, 11), 0, 64), Sequence(S(3, 11), 0, 64));
  // The value at (index, dimension) does not depend on which indices were visited before, or on
  // work done on other streams in between (interleaved calls on two samplers).
  const std::vector<double> all = Sequence(S(3, 11), 0, 64);
  const std::vector<double> tail = Sequence(S(3, 11), 40, 24);
  EXPECT_EQ(std::vector<double>(all.begin() + 40 * 4, all.end()), tail);
  S a(3, 11), b(3, 12);
  std::vector<double> interleavedA, interleavedB;
  for (int i = 63; i >= 0; --i) {  // reverse order and interleaved
    b.StartSample(i);
    a.StartSample(i);
    interleavedB.push_back(b.Get1D());
    interleavedA.push_back(a.Get1D());
  }
  for (int i = 0; i < 64; ++i) EXPECT_EQ(interleavedA[63 - i], all[4 * i]);
  EXPECT_EQ(interleavedB.back(), Sequence(S(3, 12), 0, 1)[0]);
  // Copies are independent values.
  S c(3, 11);
  c.StartSample(5);
  c.Get1D();
  S d = c;
  EXPECT_EQ(c.Get2D(), d.Get2D());
  // Different seeds or streams give different values.
  EXPECT_NE(Sequence(S(3, 11), 0, 8), Sequence(S(4, 11), 0, 8));
  EXPECT_NE(Sequence(S(3, 11), 0, 8), Sequence(S(3, 12), 0, 8));
}

// StartSample(i, d) gives the values that StartSample(i) and d draws would have led to, for every
// d up to past the Sobol sampler's cached seeds (chunks then start at any set and straddle the
// cache's end), whatever was drawn before.
template <typename S>
void ExpectStartAtASet() {
  constexpr int kSets = 70;
  for (uint64_t index : {0u, 1u, 37u, 1000u}) {
    S all(9, 4);
    all.StartSample(index);
    std::vector<Vec2d> expected;
    for (int d = 0; d < kSets; ++d) expected.push_back(d % 3 ? all.Get2D() : Vec2d{all.Get1D(), 0});
    S s(9, 4);
    for (int d = 0; d < kSets; ++d) {
      s.StartSample(index + 1);
      s.Get2D();
      s.StartSample(index, uint64_t(d));
      for (int e = d; e < std::min(kSets, d + 11); ++e) {
        const Vec2d v = e % 3 ? s.Get2D() : Vec2d{s.Get1D(), 0};
        ASSERT_EQ(v, expected[e]) << "index " << index << ", start " << d << ", set " << e;
      }
    }
  }
}
TEST(Sampler, SobolStartsAtASet) {
  ExpectStartAtASet<SobolSampler>();
}
TEST(Sampler, IndependentStartsAtASet) {
  ExpectStartAtASet<IndependentSampler>();
}

// GetChunk after a restart at any set (inside the cached seeds and past them) gives what
// kSobolChunk Get2D calls give, and the calls after it go on from the next chunk.
TEST(Sampler, SobolChunkAtOnceEqualsTheCalls) {
  for (uint64_t index : {0u, 5u, 1000u}) {
    for (uint64_t first : {0u, 3u, 7u, 41u, 47u, 60u}) {
      SobolSampler calls(3, 8), chunk(3, 8);
      calls.StartSample(index, first);
      chunk.StartSample(index, first);
      const uint32_t *x, *y;
      chunk.GetChunk(&x, &y);
      for (int k = 0; k < kSobolChunk; ++k) {
        ASSERT_EQ(calls.Get2D(), (Vec2d{U32ToUnit(x[k]), U32ToUnit(y[k])}))
            << "index " << index << ", first set " << first << ", set " << first + k;
      }
      ASSERT_EQ(calls.Get2D(), chunk.Get2D()) << "index " << index << ", first set " << first;
    }
  }
}

TEST(Sampler, SobolIsDeterministic) {
  ExpectDeterministic<SobolSampler>();
}
TEST(Sampler, IndependentIsDeterministic) {
  ExpectDeterministic<IndependentSampler>();
}

template <typename S>
void ExpectValuesInUnitIntervalOn32BitGrid() {
  for (uint64_t stream = 0; stream < 16; ++stream) {
    for (double u : Sequence(S(stream, Hash(stream)), 0, 4096)) {
      ASSERT_GE(u, 0.0);
      ASSERT_LT(u, 1.0);
      const double scaled = u * 0x1p32;
      ASSERT_EQ(scaled, std::floor(scaled)) << u;
    }
  }
}

TEST(Sampler, SobolValuesInUnitInterval) {
  ExpectValuesInUnitIntervalOn32BitGrid<SobolSampler>();
}
TEST(Sampler, IndependentValuesInUnitInterval) {
  ExpectValuesInUnitIntervalOn32BitGrid<IndependentSampler>();
}

// The first 2^k samples of every stream, in every dimension set, hit each cell of every
// 2^a x 2^b elementary-interval grid (a + b = k) exactly once (Get2D), and each interval of
// length 2^-k exactly once (Get1D). This is exact, not statistical.
TEST(Sampler, SobolFirstPowerOfTwoSamplesAreStratified) {
  for (uint64_t stream : {uint64_t{0}, uint64_t{1}, uint64_t{77}, Hash(5, 6)}) {
    for (int k = 0; k <= 12; ++k) {
      const int n = 1 << k;
      // Dimension layout per sample: 1D, 2D, 1D, 2D, ... (dimension sets 0..5).
      std::vector<std::vector<double>> oneD(3, std::vector<double>(n));
      std::vector<std::vector<Vec2d>> twoD(3, std::vector<Vec2d>(n));
      SobolSampler s(2024, stream);
      for (int i = 0; i < n; ++i) {
        s.StartSample(i);
        for (int d = 0; d < 3; ++d) {
          oneD[d][i] = s.Get1D();
          twoD[d][i] = s.Get2D();
        }
      }
      for (int d = 0; d < 3; ++d) {
        std::vector<int> count(n, 0);
        for (double u : oneD[d]) ++count[static_cast<int>(u * n)];
        for (int c = 0; c < n; ++c)
          ASSERT_EQ(count[c], 1) << "1D set " << d << ", k = " << k << ", stream " << stream;
        for (int a = 0; a <= k; ++a) {
          const int b = k - a;
          std::vector<int> cells(n, 0);
          for (const Vec2d& p : twoD[d])
            ++cells[(static_cast<int>(p.x * (1 << a)) << b) + static_cast<int>(p.y * (1 << b))];
          for (int c = 0; c < n; ++c)
            ASSERT_EQ(cells[c], 1)
                << "2D set " << d << ", grid 2^" << a << " x 2^" << b << ", stream " << stream;
        }
      }
    }
  }
}

// Pearson correlation of two value sequences; for independent uniform sequences of length n it
// is approximately N(0, 1/n), so |r| <= 5/sqrt(n) fails with probability 6e-7 per check.
double Correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  double ma = 0, mb = 0;
  for (size_t i = 0; i < a.size(); ++i) ma += a[i], mb += b[i];
  ma /= n;
  mb /= n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

// Values of one coordinate: dimension set `set` (all 2D), coordinate `c`, samples 0..n-1.
template <typename S>
std::vector<double> Coordinate(uint64_t seed, uint64_t stream, int set, int c, int n) {
  std::vector<double> v(n);
  S s(seed, stream);
  for (int i = 0; i < n; ++i) {
    s.StartSample(i);
    for (int d = 0; d < set; ++d) s.Get2D();
    v[i] = s.Get2D()[c];
  }
  return v;
}

template <typename S>
void ExpectDecorrelated() {
  constexpr int n = 1 << 14;
  const double tolerance = 5 / std::sqrt(double(n));
  // Neighbouring streams (consecutive probes / batches), same dimension set.
  for (uint64_t p = 0; p < 4; ++p) {
    const double r = Correlation(Coordinate<S>(1, Hash(p, 0), 0, 0, n),
                                 Coordinate<S>(1, Hash(p + 1, 0), 0, 0, n));
    EXPECT_LE(std::abs(r), tolerance) << "streams " << p << ", " << p + 1;
  }
  // Different dimension sets of one stream ("padding"), and the two coordinates of one set.
  const std::vector<double> x0 = Coordinate<S>(1, 9, 0, 0, n);
  EXPECT_LE(std::abs(Correlation(x0, Coordinate<S>(1, 9, 0, 1, n))), tolerance);
  EXPECT_LE(std::abs(Correlation(x0, Coordinate<S>(1, 9, 1, 0, n))), tolerance);
  EXPECT_LE(std::abs(Correlation(x0, Coordinate<S>(1, 9, 1, 1, n))), tolerance);
  EXPECT_LE(std::abs(Correlation(x0, Coordinate<S>(1, 9, 7, 0, n))), tolerance);
  // The 2D projection across dimension sets is uniform: chi-square on a 16 x 16 grid (expected
  // 64 per cell). Decorrelated sets must not show the diagonal structure of unshuffled Sobol.
  const std::vector<double> y1 = Coordinate<S>(1, 9, 1, 0, n);
  std::vector<double> observed(256, 0), expected(256, n / 256.0);
  for (int i = 0; i < n; ++i) observed[int(x0[i] * 16) * 16 + int(y1[i] * 16)] += 1;
  const auto result = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(result.pass) << result.ToString();
}

TEST(Sampler, SobolStreamsAndDimensionsAreDecorrelated) {
  ExpectDecorrelated<SobolSampler>();
}
TEST(Sampler, IndependentStreamsAndDimensionsAreDecorrelated) {
  ExpectDecorrelated<IndependentSampler>();
}

// Independent sampler: uniform in 1D (1024 bins) and 2D (64 x 64), chi-square at alpha = 1e-6.
TEST(Sampler, IndependentIsUniform) {
  constexpr int n = 1 << 20;
  std::vector<double> o1(1024, 0), e1(1024, n / 1024.0), o2(4096, 0), e2(4096, n / 4096.0);
  IndependentSampler s(5, 6);
  for (int i = 0; i < n; ++i) {
    s.StartSample(i);
    o1[int(s.Get1D() * 1024)] += 1;
    const Vec2d p = s.Get2D();
    o2[int(p.x * 64) * 64 + int(p.y * 64)] += 1;
  }
  const auto r1 = ChiSquareTest(o1, e1, kAlpha), r2 = ChiSquareTest(o2, e2, kAlpha);
  EXPECT_TRUE(r1.pass) << r1.ToString();
  EXPECT_TRUE(r2.pass) << r2.ToString();
}

// ---- SobolSampler against its definition (sampler.h), value for value.

// Dimension set d of sample i of stream (seed, stream), both coordinates, from the building blocks:
// the index shuffled by OwenScramble32 under s0, then Sobol dimensions 0 and 1 at that index,
// scrambled under s1 and s2.
Vec2d DefinedPoint(uint64_t seed, uint64_t stream, uint32_t i, uint64_t d) {
  const uint64_t key = HashCombine(Hash(seed, stream), d);
  const uint32_t shuffled = OwenScramble32(i, uint32_t(key));
  return {U32ToUnit(OwenScramble32(SobolSample32(shuffled, 0), uint32_t(key >> 32))),
          U32ToUnit(OwenScramble32(SobolSample32(shuffled, 1), uint32_t(MixBits(key))))};
}

// Every value of 200 dimension sets (past the cached seeds' end at 48, chunks of 8 cut anywhere
// by the mix of calls) over mixed Get1D / Get2D schedules, samples revisited out of order.
TEST(Sampler, SobolSamplerFollowsItsDefinition) {
  for (uint64_t stream : {uint64_t{0}, uint64_t{77}, Hash(5, 6)}) {
    SobolSampler s(2024, stream);
    for (uint32_t i : {0u, 1u, 2u, 1000u, 3u, 0xffffffffu, 1u, 0x80000000u}) {
      s.StartSample(i);
      for (uint64_t d = 0; d < 200; ++d) {
        const Vec2d expected = DefinedPoint(2024, stream, i, d);
        if (Hash(stream, i, d) & 1) {
          ASSERT_EQ(s.Get2D(), expected) << "stream " << stream << " sample " << i << " set " << d;
        } else {
          ASSERT_EQ(s.Get1D(), expected.x)
              << "stream " << stream << " sample " << i << " set " << d;
        }
      }
    }
  }
}

// Both SIMD chunk implementations (the dispatcher picks one) against the scalar definition.
TEST(Sampler, SobolChunkImplementationsAgreeWithTheDefinition) {
  using Chunk =
      void (*)(uint32_t, const uint32_t*, const uint32_t*, const uint32_t*, uint32_t*, uint32_t*);
  std::vector<Chunk> chunks{detail::SobolChunkGeneric, SobolChunk};
  if (detail::CpuHasAvx2()) chunks.push_back(detail::SobolChunkAvx2);
  for (Chunk chunk : chunks) {
    for (uint64_t trial = 0; trial < 2000; ++trial) {
      uint32_t s0[kSobolChunk], s1[kSobolChunk], s2[kSobolChunk], x[kSobolChunk], y[kSobolChunk];
      for (int j = 0; j < kSobolChunk; ++j) {
        const uint64_t h = Hash(trial, uint64_t(j));
        s0[j] = uint32_t(h), s1[j] = uint32_t(h >> 32), s2[j] = uint32_t(MixBits(h));
      }
      const uint32_t i = uint32_t(Hash(trial) >> 7);
      chunk(ReverseBits32(i), s0, s1, s2, x, y);
      for (int j = 0; j < kSobolChunk; ++j) {
        const uint32_t shuffled = OwenScramble32(i, s0[j]);
        ASSERT_EQ(x[j], OwenScramble32(SobolSample32(shuffled, 0), s1[j])) << trial << " " << j;
        ASSERT_EQ(y[j], OwenScramble32(SobolSample32(shuffled, 1), s2[j])) << trial << " " << j;
      }
    }
  }
}

TEST(Sampler, SobolRejectsIndicesBeyond32Bits) {
  SobolSampler s(1, 2);
  s.StartSample((uint64_t{1} << 32) - 1);
  EXPECT_DEATH(s.StartSample(uint64_t{1} << 32), "index");
}

}  // namespace
}  // namespace probebake
