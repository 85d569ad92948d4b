// Spawning rays off surfaces without self-intersection, at any scene scale.
//
// A hit point carries float error from two sources: Embree stores the triangle's vertices in
// float, so the surface itself is only known to a few ULPs of the vertex coordinates, and its
// intersection test (run on coordinates relative to the ray origin) errs by a few ULPs of them too.
// Both scale with the magnitude of the triangle's vertex coordinates, which can be far larger than
// the hit point's own: a large tilted floor passing near the local origin has vertices at 1e3 and
// hit points at 0.1 (Wächter and Binder, "A Fast and Robust Method for Avoiding Self-Intersection",
// Ray Tracing Gems (2019), ch. 6, scale their offset by the hit point's own coordinates, which
// leaves such floors covered in acne). So the origin is moved along the geometric normal by 2^-18
// of that magnitude, 32 to 64 float ULPs. The hit point must be interpolated from the vertices in
// double (TracerScene::Intersect), not o + t d and not in float, so that it lies on the triangle's
// plane to ~1e-16 of the vertex magnitudes; rounding the offset point to float then moves it by at
// most 2^-24 of its magnitude, far less than the offset.
//
// Margin, measured (white floor tilted to normal (0.3, 0.2, 1), half-size 1e3 and 2e4, centred at
// the local origin, uniform sky, probe 0.5 above;
// Extremes.LargeTiltedFloorAtTheLocalOriginHasNoAcne): offsets of 2^-22 of the vertex magnitude and
// more bake the exact radiance; 2^-26 loses 5% of it to self-intersection, no offset 11%. 2^-18 is
// 16 times the smallest clean offset.
#pragma once

#include <algorithm>
#include <cmath>

#include "probebake/math/vec3.h"

namespace probebake {

// Moves p off its surface to the side `n` points to (n: unit geometric normal, flipped by the
// caller toward the side the new ray leaves on). `vertexScale`: largest magnitude of the
// surface's float vertex coordinates (SurfaceHit::vertexScale).
// How far OffsetRayOrigin moves p, in scene units.
inline double RayOffsetDistance(const Vec3d& p, double vertexScale) {
  constexpr double kRelative = 0x1p-18;
  // Keeps the offset positive for geometry at the origin itself (a vertex scale of 0).
  constexpr double kAbsolute = 0x1p-100;
  const double scale = std::max(vertexScale, MaxComponent(Abs(p)));
  return kRelative * scale + kAbsolute;
}

inline Vec3f OffsetRayOrigin(const Vec3d& p, const Vec3d& n, double vertexScale) {
  return Vec3f(p + n * RayOffsetDistance(p, vertexScale));
}

// Below this distance, in scene units, a point cannot be told apart from the surface near q (a
// triangle whose float vertex coordinates reach `vertexScale`): 2^-22 of the coordinates'
// magnitude, 2 to 4 float ULPs, the size of the rounding of a ray origin to float plus that of
// Embree's intersection test. Rays leaving such a point start on either side of the surface. A
// ray offset (above) is 16 times as far.
inline double SurfaceResolution(const Vec3d& q, double vertexScale) {
  return 0x1p-22 * std::max(vertexScale, MaxComponent(Abs(q)));
}

// The largest float rounding error, in scene units, of a coordinate of magnitude `maxAbs` after a
// few operations: used to stop shadow rays short of the light surface they aim at.
inline double FloatSlack(double maxAbs) {
  return (maxAbs + 1e-3) * 0x1p-17;
}

}  // namespace probebake
