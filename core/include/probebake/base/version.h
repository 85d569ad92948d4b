// The baker's identity, recorded in every volume and part of every job digest: a change to
// kBakerVersion invalidates the result cache (bump it whenever the same job would bake different
// bits).
#pragma once

namespace probebake {

inline constexpr const char* kGeneratorName = "probebake";
inline constexpr const char* kVersion = "0.1.0";
// Bumped whenever a change alters the numbers a bake produces.
inline constexpr int kBakerVersion = 14;

}  // namespace probebake
