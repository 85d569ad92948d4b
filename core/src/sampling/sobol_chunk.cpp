#include "probebake/sampling/sobol_chunk.h"

#include <immintrin.h>

#include "probebake/sampling/sobol.h"

namespace probebake {
namespace {

// The generic body (SobolChunkAvx2 below is the same in AVX2 intrinsics); it stays scalar, as
// SSE2 has no 32-bit multiply. Written out from OwenScramble32 to share bit
// reversals: with r = ReverseBits32(index) the shuffled index is i = Rev(LK(r, s0)), dimension 0
// of the Sobol point is Rev(i) and its scramble is Rev(LK(Rev(Rev(i)), s1)) = Rev(LK(i, s1));
// dimension 1's scramble Rev(LK(Rev(Sobol1(i)), s2)) gets Rev(Sobol1(i)) from the table-free
// SobolSample32Dim1Reversed.
[[gnu::always_inline]] inline void ChunkBody(uint32_t reversedIndex, const uint32_t* __restrict s0,
                                             const uint32_t* __restrict s1,
                                             const uint32_t* __restrict s2, uint32_t* __restrict x,
                                             uint32_t* __restrict y) {
  for (int j = 0; j < kSobolChunk; ++j) {
    const uint32_t i = ReverseBits32(LaineKarrasPermutation(reversedIndex, s0[j]));
    x[j] = ReverseBits32(LaineKarrasPermutation(i, s1[j]));
    y[j] = ReverseBits32(LaineKarrasPermutation(SobolSample32Dim1Reversed(i), s2[j]));
  }
}

using ChunkFn = void (*)(uint32_t, const uint32_t*, const uint32_t*, const uint32_t*, uint32_t*,
                         uint32_t*);

ChunkFn PickChunk() {
  return detail::CpuHasAvx2() ? detail::SobolChunkAvx2 : detail::SobolChunkGeneric;
}

}  // namespace

namespace detail {

void SobolChunkGeneric(uint32_t reversedIndex, const uint32_t* s0, const uint32_t* s1,
                       const uint32_t* s2, uint32_t* x, uint32_t* y) {
  ChunkBody(reversedIndex, s0, s1, s2, x, y);
}

namespace {

// ChunkBody in AVX2 intrinsics. The compiler vectorised the scalar body's bit reversals as five
// shift-and-mask stages each (about 23 instructions, three reversals per lane); a byte shuffle
// and two nibble lookups (vpshufb) do one in 7.
[[gnu::target("avx2")]] [[gnu::always_inline]] inline __m256i ReverseBits8x32(__m256i v) {
  // Bytes reversed within each 32-bit lane, then the bits of each byte by its two nibbles.
  const __m256i byteSwap = _mm256_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12, 3,
                                            2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12);
  const __m256i nibbleReversed = _mm256_setr_epi8(
      0x0, 0x8, 0x4, 0xC, 0x2, 0xA, 0x6, 0xE, 0x1, 0x9, 0x5, 0xD, 0x3, 0xB, 0x7, 0xF, 0x0, 0x8, 0x4,
      0xC, 0x2, 0xA, 0x6, 0xE, 0x1, 0x9, 0x5, 0xD, 0x3, 0xB, 0x7, 0xF);
  const __m256i low = _mm256_set1_epi8(0x0F);
  v = _mm256_shuffle_epi8(v, byteSwap);
  const __m256i lo = _mm256_and_si256(v, low);
  const __m256i hi = _mm256_and_si256(_mm256_srli_epi16(v, 4), low);
  // A reversed low nibble becomes the high one: values below 16 shifted by 4 stay in their byte.
  return _mm256_or_si256(_mm256_slli_epi16(_mm256_shuffle_epi8(nibbleReversed, lo), 4),
                         _mm256_shuffle_epi8(nibbleReversed, hi));
}

// LaineKarrasPermutation (sobol.h), lane by lane: the same constants and steps, so that the two
// cannot drift apart unnoticed (SobolChunkImplementationsAgreeWithTheDefinition).
[[gnu::target("avx2")]] [[gnu::always_inline]] inline __m256i LaineKarras8(__m256i v,
                                                                           __m256i seed) {
  v = _mm256_xor_si256(v, _mm256_mullo_epi32(v, _mm256_set1_epi32(int(0x3d20adeau))));
  v = _mm256_add_epi32(v, seed);
  v = _mm256_mullo_epi32(v, _mm256_or_si256(_mm256_srli_epi32(seed, 16), _mm256_set1_epi32(1)));
  v = _mm256_xor_si256(v, _mm256_mullo_epi32(v, _mm256_set1_epi32(int(0x05526c56u))));
  v = _mm256_xor_si256(v, _mm256_mullo_epi32(v, _mm256_set1_epi32(int(0x53a22864u))));
  return v;
}

[[gnu::target("avx2")]] [[gnu::always_inline]] inline __m256i XorShiftMasked(__m256i v, int shift,
                                                                             uint32_t mask) {
  return _mm256_xor_si256(
      v, _mm256_and_si256(_mm256_srli_epi32(v, shift), _mm256_set1_epi32(int(mask))));
}

}  // namespace

[[gnu::target("avx2")]] void SobolChunkAvx2(uint32_t reversedIndex, const uint32_t* s0,
                                            const uint32_t* s1, const uint32_t* s2, uint32_t* x,
                                            uint32_t* y) {
  static_assert(kSobolChunk == 8, "one AVX2 register of 32-bit lanes");
  const __m256i seed0 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(s0));
  const __m256i seed1 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(s1));
  const __m256i seed2 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(s2));
  const __m256i i = ReverseBits8x32(LaineKarras8(_mm256_set1_epi32(int(reversedIndex)), seed0));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(x), ReverseBits8x32(LaineKarras8(i, seed1)));
  // SobolSample32Dim1Reversed(i), lane by lane.
  __m256i d1 = XorShiftMasked(i, 1, 0x55555555u);
  d1 = XorShiftMasked(d1, 2, 0x33333333u);
  d1 = XorShiftMasked(d1, 4, 0x0f0f0f0fu);
  d1 = XorShiftMasked(d1, 8, 0x00ff00ffu);
  d1 = XorShiftMasked(d1, 16, 0x0000ffffu);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(y), ReverseBits8x32(LaineKarras8(d1, seed2)));
}

bool CpuHasAvx2() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
}

}  // namespace detail

void SobolChunk(uint32_t reversedIndex, const uint32_t* s0, const uint32_t* s1, const uint32_t* s2,
                uint32_t* x, uint32_t* y) {
  static const ChunkFn chunk = PickChunk();
  chunk(reversedIndex, s0, s1, s2, x, y);
}

}  // namespace probebake
