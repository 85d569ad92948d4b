// Eight consecutive dimension sets of one scrambled Sobol sample at once: SobolSampler's inner
// loop, written so the eight lanes run in SIMD.
//
// Contract: for each lane j < kSobolChunk, with i = ReverseBits32(LaineKarrasPermutation(
// reversedIndex, s0[j])) the shuffled index,
//   x[j] = ReverseBits32(LaineKarrasPermutation(i, s1[j]))                              and
//   y[j] = ReverseBits32(LaineKarrasPermutation(SobolSample32Dim1Reversed(i), s2[j])),
// i.e. the 32-bit fixed-point values SobolSampler::Get2D returns for the dimension set with
// seeds (s0, s1, s2) (Get1D returns x). Integer arithmetic only, so every implementation returns
// the same bits: the AVX2 one is picked at run time where the CPU has it, the generic one
// elsewhere.
#pragma once

#include <cstdint>

namespace probebake {

inline constexpr int kSobolChunk = 8;

void SobolChunk(uint32_t reversedIndex, const uint32_t* s0, const uint32_t* s1, const uint32_t* s2,
                uint32_t* x, uint32_t* y);

namespace detail {
// The two implementations, for tests that check both against the definition.
void SobolChunkGeneric(uint32_t reversedIndex, const uint32_t* s0, const uint32_t* s1,
                       const uint32_t* s2, uint32_t* x, uint32_t* y);
void SobolChunkAvx2(uint32_t reversedIndex, const uint32_t* s0, const uint32_t* s1,
                    const uint32_t* s2, uint32_t* x, uint32_t* y);
// Whether this CPU runs SobolChunkAvx2.
bool CpuHasAvx2();
}  // namespace detail

}  // namespace probebake
