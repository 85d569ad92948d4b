// Deterministic sample generators for the path tracer: SobolSampler (randomised quasi-Monte
// Carlo) and IndependentSampler (plain Monte Carlo), value types with the same interface so the
// tracer can be templated on them (see the Sampler concept).
//
// Contract (both samplers):
//   - A sampler is built from (seed, stream); the caller derives stream by hashing, e.g.
//     Hash(probeKey, batchIndex) with the probe's position key (core/src/bake/probe_site.h).
//     StartSample(index) selects the sample within the stream and resets the dimension counter;
//     each Get1D() or Get2D() call then consumes one dimension (set). StartSample(index, d) starts
//     at dimension set d instead, as if d sets had been drawn. The value returned depends
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
// seed, where s0 and s1 are the halves of Hash(seed, stream, d) and s2 32 bits of a remix of it.
// Hence:
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
#include "probebake/sampling/sobol_chunk.h"

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

  void StartSample(uint64_t index, uint64_t firstSet = 0) {
    PB_CHECK_LT(index, uint64_t{1} << 32);
    reversedIndex_ = ReverseBits32(static_cast<uint32_t>(index));
    dimension_ = firstSet;
    chunkEnd_ = firstSet;
  }

  double Get1D() { return U32ToUnit(x_[NextInChunk()]); }

  Vec2d Get2D() {
    const uint64_t j = NextInChunk();
    return {U32ToUnit(x_[j]), U32ToUnit(y_[j])};
  }

  // Right after StartSample: the next kSobolChunk sets at once, as 32-bit fixed point (*x and *y
  // point at kSobolChunk values each; set k is what the k-th Get2D call would return, its x alone
  // what Get1D would). Consumes them, without the per-call bookkeeping.
  void GetChunk(const uint32_t** x, const uint32_t** y) {
    PB_DCHECK(dimension_ == chunkEnd_);
    FillChunk();
    dimension_ = chunkEnd_;
    *x = x_;
    *y = y_;
  }

 private:
  // The current dimension set's lane in the chunk of precomputed sets, then advance d. Sets are
  // computed kSobolChunk at a time (sobol_chunk.h, in SIMD); a path that ends mid-chunk wastes
  // the rest, which costs less than computing each set alone.
  uint64_t NextInChunk() {
    if (dimension_ == chunkEnd_) FillChunk();
    return dimension_++ - (chunkEnd_ - kSobolChunk);
  }

  // Points of dimension sets [dimension_, dimension_ + kSobolChunk) of the current sample. Their
  // seeds depend on the stream and d only, not on the sample, so those of the first kCachedSets
  // are computed once per stream.
  void FillChunk() {
    const uint64_t begin = dimension_;
    chunkEnd_ = begin + kSobolChunk;
    if (chunkEnd_ <= kCachedSets) {
      for (; cached_ < chunkEnd_; ++cached_)
        Seeds(cached_, &s0_[cached_], &s1_[cached_], &s2_[cached_]);
      SobolChunk(reversedIndex_, &s0_[begin], &s1_[begin], &s2_[begin], x_, y_);
      return;
    }
    uint32_t s0[kSobolChunk], s1[kSobolChunk], s2[kSobolChunk];
    for (int j = 0; j < kSobolChunk; ++j) Seeds(begin + j, &s0[j], &s1[j], &s2[j]);
    SobolChunk(reversedIndex_, s0, s1, s2, x_, y_);
  }

  // Dimension set d's seeds: the halves of key = Hash(seed, stream, d) and the low half of
  // MixBits(key) (a third independent 32-bit seed for Get2D's second coordinate).
  void Seeds(uint64_t d, uint32_t* s0, uint32_t* s1, uint32_t* s2) const {
    const uint64_t key = HashCombine(streamHash_, d);
    *s0 = uint32_t(key);
    *s1 = uint32_t(key >> 32);
    *s2 = uint32_t(MixBits(key));
  }

  // A chunk that straddles the cached sets' end (after a StartSample past set 0) computes its
  // seeds as the chunks past it do.
  static constexpr uint64_t kCachedSets = 48;
  uint64_t streamHash_;         // Hash(seed, stream)
  uint32_t reversedIndex_ = 0;  // ReverseBits32(index)
  uint64_t dimension_ = 0;
  uint64_t chunkEnd_ = 0;  // the chunk holds sets [chunkEnd_ - kSobolChunk, chunkEnd_)
  uint64_t cached_ = 0;    // seeds of sets [0, cached_) are in s0_, s1_, s2_
  uint32_t s0_[kCachedSets], s1_[kCachedSets], s2_[kCachedSets];
  uint32_t x_[kSobolChunk], y_[kSobolChunk];  // the chunk's points, 32-bit fixed point
};

class IndependentSampler {
 public:
  IndependentSampler(uint64_t seed, uint64_t stream)
      : streamHash_(Hash(seed, stream)), sampleHash_(HashCombine(streamHash_, 0)) {}

  void StartSample(uint64_t index, uint64_t firstSet = 0) {
    sampleHash_ = HashCombine(streamHash_, index);
    dimension_ = firstSet;
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
