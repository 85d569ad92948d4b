// Portable 64-bit hashing of integers, the root of every random stream in a bake.
//
// Contract: the results are pure functions of the integer values passed (no addresses, no
// std::hash, no platform-dependent widths), so the same inputs give the same bits on every
// platform, compiler and build type. Every argument is converted to uint64_t first (signed values
// by two's complement, C++20), so Hash(int32_t{-1}) == Hash(uint64_t{~0ull}) and
// Hash(uint8_t{7}) == Hash(uint64_t{7}): the value counts, not the type.
//
// Hash is a left fold of HashCombine from kHashInit, with no finaliser, so a prefix can be cached:
//   Hash(a, b, c) == HashCombine(Hash(a, b), c) == HashCombine(HashCombine(Hash(a), b), c).
// For a fixed prefix, distinct last arguments never collide (HashCombine is a bijection in v).
//
// References:
//   S. Vigna, splitmix64 (2015), whose output function is D. Stafford's "Mix13" variant of the
//   MurmurHash3 64-bit finaliser ("Better Bit Mixing", 2011): full avalanche, bijective.
#pragma once

#include <concepts>
#include <cstdint>

namespace probebake {

// Bijective 64-bit mixer with full avalanche (each input bit flips each output bit with
// probability ~1/2). MixBits(0) == 0, so never feed it raw small keys where that matters: use Hash.
constexpr uint64_t MixBits(uint64_t v) {
  v ^= v >> 30;
  v *= 0xbf58476d1ce4e5b9ull;
  v ^= v >> 27;
  v *= 0x94d049bb133111ebull;
  v ^= v >> 31;
  return v;
}

// Starting state of Hash (the 64-bit fractional part of sqrt(2)).
inline constexpr uint64_t kHashInit = 0x6a09e667f3bcc908ull;

// One fold step: mixes value v into running hash h. The additive constant (2^64 / golden ratio)
// keeps (h, v) = (0, 0) away from MixBits' fixed point at zero.
constexpr uint64_t HashCombine(uint64_t h, uint64_t v) {
  return MixBits(h + v + 0x9e3779b97f4a7c15ull);
}

// Hash of a sequence of integers, order-sensitive: Hash(a, b) != Hash(b, a) in general.
template <typename... Args>
requires(std::integral<Args>&&...) constexpr uint64_t Hash(Args... args) {
  uint64_t h = kHashInit;
  ((h = HashCombine(h, static_cast<uint64_t>(args))), ...);
  return h;
}

}  // namespace probebake
