#include "probebake/sampling/sobol_chunk.h"

#include "probebake/sampling/sobol.h"

namespace probebake {
namespace {

// One body for both targets: for AVX2 the compiler vectorises the lane loop (32-bit multiplies,
// shifts and xors; 8 lanes fill one register); the generic build stays scalar, as SSE2 has no
// 32-bit multiply. Written out from OwenScramble32 to share bit
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

[[gnu::target("avx2")]] void SobolChunkAvx2(uint32_t reversedIndex, const uint32_t* s0,
                                            const uint32_t* s1, const uint32_t* s2, uint32_t* x,
                                            uint32_t* y) {
  ChunkBody(reversedIndex, s0, s1, s2, x, y);
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
