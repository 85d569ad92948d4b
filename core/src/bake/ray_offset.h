// Spawning rays off surfaces without self-intersection, at any scene scale.
//
// Wächter and Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems
// (2019), ch. 6: the origin is moved along the geometric normal by a fixed number of float ULPs
// (so the offset scales with the coordinate's magnitude, which is where float hit points carry
// their error), with a small absolute offset near the origin where ULPs vanish. The hit point must
// come from barycentric interpolation of the float vertices (not o + t d), whose error is a few
// ULPs of the vertex coordinates.
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

#include "probebake/math/vec3.h"

namespace probebake {

// Moves p off its surface to the side `n` points to (n: unit geometric normal, flipped by the
// caller toward the side the new ray leaves on).
inline Vec3f OffsetRayOrigin(const Vec3f& p, const Vec3f& n) {
  constexpr float kOrigin = 1.0f / 32.0f;
  constexpr float kFloatScale = 1.0f / 65536.0f;
  constexpr float kIntScale = 256.0f;
  Vec3f out;
  for (int i = 0; i < 3; ++i) {
    const int32_t offset = int32_t(kIntScale * n[i]);
    const int32_t bits = std::bit_cast<int32_t>(p[i]);
    const float pi = std::bit_cast<float>(bits + (p[i] < 0 ? -offset : offset));
    out[i] = std::fabs(p[i]) < kOrigin ? p[i] + kFloatScale * n[i] : pi;
  }
  return out;
}

// The largest float rounding error, in scene units, of a coordinate of magnitude `maxAbs` after a
// few operations: used to stop shadow rays short of the light surface they aim at.
inline double FloatSlack(double maxAbs) {
  return (maxAbs + 1e-3) * 0x1p-17;
}

}  // namespace probebake
