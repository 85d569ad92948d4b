#include "probebake/sampling/hash.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <unordered_set>

namespace probebake {
namespace {

// Known answers: splitmix64 seeded with 0 outputs MixBits(k * 0x9e3779b97f4a7c15) for k = 1, 2, 3;
// these are the published first outputs of Vigna's splitmix64.c (independent of this code).
TEST(Hash, MixBitsMatchesSplitmix64KnownOutputs) {
  constexpr uint64_t kGolden = 0x9e3779b97f4a7c15ull;
  EXPECT_EQ(MixBits(kGolden * 1), 0xe220a8397b1dcdafull);
  EXPECT_EQ(MixBits(kGolden * 2), 0x6e789e6aa1b965f4ull);
  EXPECT_EQ(MixBits(kGolden * 3), 0x06c45d188009454full);
}

// The fold identity the samplers rely on when caching Hash(seed, stream).
TEST(Hash, IsALeftFoldOfHashCombine) {
  static_assert(Hash(1, 2, 3) == HashCombine(Hash(1, 2), 3));
  static_assert(Hash(7) == HashCombine(kHashInit, 7));
  EXPECT_EQ(Hash(uint64_t{5}, -3, uint8_t{9}),
            HashCombine(HashCombine(HashCombine(kHashInit, 5), static_cast<uint64_t>(-3)), 9));
}

TEST(Hash, DependsOnValuesNotTypes) {
  EXPECT_EQ(Hash(int8_t{-1}), Hash(~uint64_t{0}));
  EXPECT_EQ(Hash(uint32_t{5}, int16_t{6}), Hash(uint64_t{5}, uint64_t{6}));
  EXPECT_NE(Hash(1, 2), Hash(2, 1));
  EXPECT_NE(Hash(0), Hash(0, 0));
}

// For a fixed prefix HashCombine is a bijection in its last argument, so distinct pairs collide
// only by chance: 2^20 pairs in 2^64 values collide with probability 2^39 / 2^64 ~ 3e-8.
TEST(Hash, NoCollisionsOnAGridOfPairs) {
  std::unordered_set<uint64_t> seen;
  for (int a = 0; a < 1024; ++a)
    for (int b = 0; b < 1024; ++b) seen.insert(Hash(a, b));
  EXPECT_EQ(seen.size(), size_t{1024 * 1024});
}

// Avalanche: flipping one input bit flips each output bit with probability 1/2. With T trials per
// (input bit, output bit) pair the flip frequency has standard deviation 0.5/sqrt(T); we allow 6
// sigma per pair (4096 pairs per function: family-wise false alarm ~ 4096 * 2e-9 ~ 1e-5).
// Inputs come from splitmix64 steps (a different use of the mixer: consecutive golden multiples).
void ExpectAvalanche(const char* name, uint64_t (*f)(uint64_t)) {
  constexpr int kTrials = 4000;
  const double tolerance = 6 * 0.5 / std::sqrt(double(kTrials));
  double worst = 0;
  int worstIn = -1, worstOut = -1;
  for (int inBit = 0; inBit < 64; ++inBit) {
    int flips[64] = {};
    uint64_t state = 0x1234567ull + inBit;
    for (int t = 0; t < kTrials; ++t) {
      state += 0x9e3779b97f4a7c15ull;
      const uint64_t x = MixBits(state);
      const uint64_t d = f(x) ^ f(x ^ (uint64_t{1} << inBit));
      for (int o = 0; o < 64; ++o) flips[o] += (d >> o) & 1;
    }
    for (int o = 0; o < 64; ++o) {
      const double bias = std::abs(flips[o] / double(kTrials) - 0.5);
      if (bias > worst) worst = bias, worstIn = inBit, worstOut = o;
    }
  }
  EXPECT_LE(worst, tolerance) << name << ": input bit " << worstIn << " -> output bit " << worstOut
                              << " flips with bias " << worst << " (expected 0 within " << tolerance
                              << ")";
}

TEST(Hash, AvalancheOfEveryArgument) {
  ExpectAvalanche("MixBits", [](uint64_t x) { return MixBits(x); });
  ExpectAvalanche("Hash(x, 3, 4)", [](uint64_t x) { return Hash(x, 3, 4); });
  ExpectAvalanche("Hash(3, x, 4)", [](uint64_t x) { return Hash(3, x, 4); });
  ExpectAvalanche("Hash(3, 4, x)", [](uint64_t x) { return Hash(3, 4, x); });
}

// Small consecutive keys (probe indices, dimensions) must give unbiased bits: over 2^16
// consecutive keys each output bit is set with frequency 1/2 +- 6 sigma (sigma = 0.5/256).
TEST(Hash, ConsecutiveKeysGiveBalancedBits) {
  constexpr int kKeys = 1 << 16;
  int ones[64] = {};
  for (int k = 0; k < kKeys; ++k) {
    const uint64_t h = Hash(42, k);
    for (int o = 0; o < 64; ++o) ones[o] += (h >> o) & 1;
  }
  const double tolerance = 6 * 0.5 / std::sqrt(double(kKeys));
  for (int o = 0; o < 64; ++o)
    EXPECT_NEAR(ones[o] / double(kKeys), 0.5, tolerance) << "output bit " << o;
}

}  // namespace
}  // namespace probebake
