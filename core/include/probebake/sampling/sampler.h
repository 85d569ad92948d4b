// Deterministic sample generators for the path tracer: SobolSampler (randomised quasi-Monte
// Carlo) and IndependentSampler (plain Monte Carlo), value types with the same interface so the
// tracer can be templated on them (see the Sampler concept).
//
// Contract (both samplers):
//   - A sampler is built from (seed, stream); the caller derives stream by hashing, e.g.
//     Hash(probeKey, batchIndex) with the probe's position key (core/src/bake/probe_site.h).
//     StartSample(index) selects the sample within the stream and resets the dimension counter;
//     each Get1D() or Get2D() call then consumes one dimension (set). The value returned depends
//     only on (seed, stream, index, dimension, kind of call): never on call history, other streams,
//     threads or time. Copies are independent.
//   - Values are k * 2^-32 for an integer k in [0, 2^32), so they lie in [0, 1) exactly
//     (1 - 2^-32 is the largest). float(u) rounds to 1.0f for u > 1 - 2^-25, so clamp when
//     converting: std::min(float(u), 0x1.fffffep-1f).
//   - Before the first StartSample call a sampler behaves as after StartSample(0).
//   - Precondition for SobolSampler: index < 2^32 (checked).
//
// SobolSampler: dimension set d of sample i is the point with index OwenScramble(i, s0) of the
// first one (Get1D) or two (Get2D) Sobol dimensions, each coordinate Owen-scrambled with its own
// seed, where s0, s1, s2 are 32-bit pieces of Hash(seed, stream, d). Hence:
//   - for each dimension set, the first 2^k samples of a stream are a (0, k, 2)-net (Get2D) or
//     one point per interval [j 2^-k, (j+1) 2^-k) (Get1D): index shuffling by a nested scramble
//     maps the indices 0..2^k-1 onto an aligned block of 2^k Sobol indices;
//   - dimension sets are decorrelated from each other ("padding" by index shuffling), and
//   - every stream is an independent randomisation, so estimates from different streams are
//     independent and unbiased, and their spread gives honest standard errors.
// IndependentSampler: Get1D = high 32 bits of Hash(seed, stream, index, d); Get2D = both halves.
//
// References: see sobol.h (Burley 2020; Laine-Karras 2011; Joe-Kuo 2008) and hash.h.
#pragma once

#include <concepts>
#include <cstdint>

#include "probebake/base/check.h"
#include "probebake/math/vec3.h"
#include "probebake/sampling/hash.h"
#include "probebake/sampling/sobol.h"

namespace probebake {

// The fixed-point value bits * 2^-32 in [0, 1) (exact in double).
constexpr double U32ToUnit(uint32_t bits) {
  return static_cast<double>(bits) * 0x1p-32;
}

template <typename S>
concept Sampler = std::copy_constructible<S> && requires(S s, uint64_t index) {
  S(uint64_t{0}, uint64_t{0});
  s.StartSample(index);
  { s.Get1D() } -> std::same_as<double>;
  { s.Get2D() } -> std::same_as<Vec2d>;
};

class SobolSampler {
 public:
  SobolSampler(uint64_t seed, uint64_t stream) : streamHash_(Hash(seed, stream)) {}

  void StartSample(uint64_t index) {
    PB_CHECK_LT(index, uint64_t{1} << 32);
    reversedIndex_ = ReverseBits32(static_cast<uint32_t>(index));
    dimension_ = 0;
  }

  // Written out from OwenScramble32 to share bit reversals: with r = ReverseBits32(index), the
  // shuffled index is i' = Rev(LK(r, s0)), dimension 0 of the Sobol point is Rev(i') and its
  // scramble is Rev(LK(Rev(Rev(i')), s1)) = Rev(LK(i', s1)); dimension 1's scramble
  // Rev(LK(Rev(Sobol1(i')), s2)) takes Rev(Sobol1(i')) from bit-reversed tables.
  double Get1D() {
    const uint64_t key = NextDimensionKeys().key;
    const uint32_t i = ReverseBits32(LaineKarrasPermutation(reversedIndex_, uint32_t(key)));
    return U32ToUnit(ReverseBits32(LaineKarrasPermutation(i, uint32_t(key >> 32))));
  }

  Vec2d Get2D() {
    const DimensionKeys& k = NextDimensionKeys();
    const uint32_t i = ReverseBits32(LaineKarrasPermutation(reversedIndex_, uint32_t(k.key)));
    return {U32ToUnit(ReverseBits32(LaineKarrasPermutation(i, uint32_t(k.key >> 32)))),
            U32ToUnit(ReverseBits32(
                LaineKarrasPermutation(SobolSample32Dim1Reversed(i), uint32_t(k.key2))))};
  }

 private:
  struct DimensionKeys {
    uint64_t key;   // Hash(seed, stream, d)
    uint64_t key2;  // MixBits(key): a third independent 32-bit seed for Get2D
  };
  // The keys of the current dimension set d, then advance d. They depend on the stream and d
  // only, not on the sample, so the first kCachedSets are computed once per stream: samples
  // consume dimension sets in order from 0, so the cache fills contiguously.
  const DimensionKeys& NextDimensionKeys() {
    const uint64_t d = dimension_++;
    if (d < cached_) return cache_[d];
    DimensionKeys k{HashCombine(streamHash_, d), 0};
    k.key2 = MixBits(k.key);
    if (d == cached_ && d < kCachedSets) {
      cache_[d] = k;
      ++cached_;
      return cache_[d];
    }
    overflow_ = k;
    return overflow_;
  }

  static constexpr uint64_t kCachedSets = 48;
  uint64_t streamHash_;         // Hash(seed, stream)
  uint32_t reversedIndex_ = 0;  // ReverseBits32(index)
  uint64_t dimension_ = 0;
  uint64_t cached_ = 0;
  DimensionKeys cache_[kCachedSets];
  DimensionKeys overflow_{};
};

class IndependentSampler {
 public:
  IndependentSampler(uint64_t seed, uint64_t stream)
      : streamHash_(Hash(seed, stream)), sampleHash_(HashCombine(streamHash_, 0)) {}

  void StartSample(uint64_t index) {
    sampleHash_ = HashCombine(streamHash_, index);
    dimension_ = 0;
  }

  double Get1D() { return U32ToUnit(static_cast<uint32_t>(NextDimensionHash() >> 32)); }

  Vec2d Get2D() {
    const uint64_t h = NextDimensionHash();
    return {U32ToUnit(static_cast<uint32_t>(h >> 32)), U32ToUnit(static_cast<uint32_t>(h))};
  }

 private:
  // Hash(seed, stream, index, d) for the current dimension d, then advance d.
  uint64_t NextDimensionHash() { return HashCombine(sampleHash_, dimension_++); }

  uint64_t streamHash_;  // Hash(seed, stream)
  uint64_t sampleHash_;  // Hash(seed, stream, index)
  uint64_t dimension_ = 0;
};

static_assert(Sampler<SobolSampler>);
static_assert(Sampler<IndependentSampler>);

}  // namespace probebake
