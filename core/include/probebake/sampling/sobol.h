// The first two dimensions of the Sobol sequence as 32-bit integers, and the hash-based nested
// uniform (Owen) scramble of Burley 2020, the building blocks of SobolSampler.
//
// Conventions: a 32-bit value x stands for the point x * 2^-32 in [0, 1). Sobol dimension 0 is the
// van der Corput sequence (generator matrix = identity in bit-reversed order); dimension 1 is the
// Joe-Kuo dimension with primitive polynomial x + 1 (s = 1, m_1 = 1), whose direction numbers obey
// v_k = v_{k-1} ^ (v_{k-1} >> 1). Together they form a (0, 2)-sequence in base 2: every aligned
// block of 2^k consecutive indices is a (0, k, 2)-net, i.e. it has exactly one point in each cell
// of every 2^a x 2^b grid of elementary intervals with a + b = k.
//
// OwenScramble32 is a base-2 digit scramble: output bit j (counting from the most significant)
// is input bit j XOR a function of the more significant bits and the seed. Such scrambles map
// (t, m, s)-nets to (t, m, s)-nets, so scrambling preserves the stratification above, and for a
// fixed x a random seed makes the output (nearly) uniformly distributed (nested uniform scramble).
//
// References:
//   B. Burley, "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020.
//   S. Laine, T. Karras, "Stratified Sampling for Stochastic Transparency", EGSR 2011 (the
//     hash-based scramble idea).
//   N. Vegdahl, "Building a Better LK Hash", 2021 (the improved hash constants used below, also
//     used by pbrt-v4's FastOwenScrambler).
//   S. Joe, F. Y. Kuo, "Constructing Sobol sequences with better two-dimensional projections",
//     SIAM J. Sci. Comput. 30(5), 2008 (direction numbers).
#pragma once

#include <array>
#include <cstdint>

namespace probebake {

constexpr uint32_t ReverseBits32(uint32_t v) {
  v = (v << 16) | (v >> 16);
  v = ((v & 0x00ff00ffu) << 8) | ((v & 0xff00ff00u) >> 8);
  v = ((v & 0x0f0f0f0fu) << 4) | ((v & 0xf0f0f0f0u) >> 4);
  v = ((v & 0x33333333u) << 2) | ((v & 0xccccccccu) >> 2);
  v = ((v & 0x55555555u) << 1) | ((v & 0xaaaaaaaau) >> 1);
  return v;
}

// The hash-based permutation of Laine-Karras / Burley in the bit-reversed domain (the most
// significant digit of the fixed-point value is bit 0): every step (xor with an even multiple,
// add, multiply by an odd number) changes bit i only as a function of bits < i and the seed.
constexpr uint32_t LaineKarrasPermutation(uint32_t v, uint32_t seed) {
  v ^= v * 0x3d20adeau;
  v += seed;
  v *= (seed >> 16) | 1u;
  v ^= v * 0x05526c56u;
  v ^= v * 0x53a22864u;
  return v;
}

// Nested uniform scramble of the 32-bit fixed-point value v under a 32-bit seed. A bijection of
// the 2^32 values for every seed. The seed should be well mixed (e.g. bits of Hash(...)).
constexpr uint32_t OwenScramble32(uint32_t v, uint32_t seed) {
  return ReverseBits32(LaineKarrasPermutation(ReverseBits32(v), seed));
}

namespace detail {

// Dimension 1 generator matrix, applied one index byte at a time: kSobolDim1Bytes[b][x] is the
// XOR of the direction numbers v_{8b+i} over the set bits i of x.
constexpr std::array<std::array<uint32_t, 256>, 4> MakeSobolDim1Tables() {
  std::array<uint32_t, 32> v{};
  v[0] = 0x80000000u;
  for (int k = 1; k < 32; ++k) v[k] = v[k - 1] ^ (v[k - 1] >> 1);
  std::array<std::array<uint32_t, 256>, 4> t{};
  for (int b = 0; b < 4; ++b) {
    for (uint32_t x = 0; x < 256; ++x) {
      uint32_t r = 0;
      for (int i = 0; i < 8; ++i)
        if (x & (1u << i)) r ^= v[8 * b + i];
      t[b][x] = r;
    }
  }
  return t;
}

inline constexpr std::array<std::array<uint32_t, 256>, 4> kSobolDim1Bytes = MakeSobolDim1Tables();

}  // namespace detail

// ReverseBits32(SobolSample32(index, 1)), without tables or reversal. Bit-reversed, direction
// number k of dimension 1 has bit j set iff the binomial coefficient C(k, j) is odd, which by
// Lucas' theorem holds iff the binary digits of j are a subset of those of k. So bit j of the
// point is the XOR of the index bits k whose digits contain j's: a superset-XOR transform over
// the five binary digits of the bit position, done one digit per step (each step adds, to the
// positions whose digit is 0, the bit 2^digit positions above).
constexpr uint32_t SobolSample32Dim1Reversed(uint32_t index) {
  index ^= (index >> 1) & 0x55555555u;
  index ^= (index >> 2) & 0x33333333u;
  index ^= (index >> 4) & 0x0f0f0f0fu;
  index ^= (index >> 8) & 0x00ff00ffu;
  index ^= (index >> 16) & 0x0000ffffu;
  return index;
}

// Sobol point `index` in dimension 0 or 1 (precondition: dimension is 0 or 1), as 32-bit fixed
// point. Unscrambled: SobolSample32(0, d) == 0.
constexpr uint32_t SobolSample32(uint32_t index, int dimension) {
  if (dimension == 0) return ReverseBits32(index);
  const auto& t = detail::kSobolDim1Bytes;
  return t[0][index & 0xffu] ^ t[1][(index >> 8) & 0xffu] ^ t[2][(index >> 16) & 0xffu] ^
         t[3][index >> 24];
}

}  // namespace probebake
