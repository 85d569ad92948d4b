// The baker's identity, recorded in every volume and part of every job digest: a change to
// kBakerVersion invalidates the result cache.
#pragma once

namespace probebake {

inline constexpr const char* kGeneratorName = "probebake";
inline constexpr const char* kVersion = "0.1.0";
// Bumped whenever the same job would bake different bits; tests/bake/golden_test.cpp fails when
// the bits change without a bump, and when a bump changes no bits.
inline constexpr int kBakerVersion = 23;

}  // namespace probebake
