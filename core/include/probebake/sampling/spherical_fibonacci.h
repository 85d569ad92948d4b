// Spherical Fibonacci point sets and uniformly random rotations: the probe's directions are a
// spherical Fibonacci set turned by a random rotation per batch (core/src/bake/probe_integrator.h).
//
// SphericalFibonacci(j, n), j < n: the point with z = 1 - (2j + 1) / n and azimuth j / phi turns
// (phi the golden ratio; only the fraction counts). The n points have equal area each (n bands
// of equal height, one point per band), spread along a spiral by the golden angle, so every cap
// and band of the sphere holds close to its share of them. Integrating a smooth function with
// them converges far faster than with a 2D net mapped onto the sphere, whose map distorts cells
// near the poles and whose square has edges the sphere has not.
//
// UniformRotation(u) maps u in [0, 1)^3 to a rotation; for uniform u it is uniformly distributed
// (Haar measure on SO(3)): Shoemake's unit quaternion from three uniform numbers. A point set
// turned by such a rotation has every point uniformly distributed on the sphere, so the mean of
// f over the set is an unbiased estimate of f's mean over the sphere for any f, while the points
// keep their relative arrangement; independent rotations give independent estimates.
//
// Deterministic: integer arithmetic for the azimuth, SinCosTurns for angles (the same bits on
// every x86-64 build).
//
// References:
//   R. Marques, C. Bouville, M. Ribeiro, L. P. Santos, K. Bouatouch, "Spherical Fibonacci Point
//     Sets for Illumination Integrals", Computer Graphics Forum 32(8), 2013.
//   K. Shoemake, "Uniform Random Rotations", Graphics Gems III, 1992.
#pragma once

#include <cmath>
#include <cstdint>

#include "probebake/base/check.h"
#include "probebake/math/mat3.h"
#include "probebake/math/sincos_turns.h"
#include "probebake/math/vec3.h"
#include "probebake/sampling/hash.h"

namespace probebake {

// Point j of the n-point spherical Fibonacci set (unit vector). Precondition: j < n, n >= 1.
inline Vec3d SphericalFibonacci(uint64_t j, uint64_t n) {
  // j / phi mod 1 as a 64-bit fraction: 2^64 / phi rounded to odd, times j, wrapping.
  const uint64_t azimuthBits = j * 0x9e3779b97f4a7c15ull;
  const double azimuth = static_cast<double>(azimuthBits >> 11) * 0x1p-53;
  const double z = 1 - (2 * static_cast<double>(j) + 1) / static_cast<double>(n);
  const double sinTheta = std::sqrt(std::max(0.0, (1 - z) * (1 + z)));
  const SinCos phi = SinCosTurns(azimuth);
  return {sinTheta * phi.cos, sinTheta * phi.sin, z};
}

// The rotation of the unit quaternion (x, y, z, w) = (sqrt(1 - u0) sin 2pi u1, sqrt(1 - u0) cos
// 2pi u1, sqrt(u0) sin 2pi u2, sqrt(u0) cos 2pi u2): uniform over rotations for uniform u.
inline Mat3d UniformRotation(double u0, double u1, double u2) {
  const double a = std::sqrt(1 - u0), b = std::sqrt(u0);
  const SinCos s1 = SinCosTurns(u1), s2 = SinCosTurns(u2);
  const double x = a * s1.sin, y = a * s1.cos, z = b * s2.sin, w = b * s2.cos;
  return Mat3d::FromRows({1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                         {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                         {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)});
}

// The n-point spherical Fibonacci set (n may be 0: no point) turned by the rotation of the random
// stream (seed, stream): UniformRotation of three 53-bit numbers hashed from them (independent of
// every Sobol or independent sampler's numbers of the same stream, which hash small dimension
// indices).
class RotatedSphericalFibonacci {
 public:
  RotatedSphericalFibonacci(uint64_t n, uint64_t seed, uint64_t stream) : n_(n) {
    const uint64_t key = Hash(seed, stream, kRotationKey);
    const auto unit = [key](uint64_t k) {
      return static_cast<double>(HashCombine(key, k) >> 11) * 0x1p-53;
    };
    rotation_ = UniformRotation(unit(0), unit(1), unit(2));
  }

  uint64_t size() const { return n_; }
  // Point j (unit vector). Precondition: j < size().
  Vec3d Point(uint64_t j) const {
    PB_DCHECK(j < n_);
    return rotation_ * SphericalFibonacci(j, n_);
  }

 private:
  // Far above any dimension index a sampler hashes with (seed, stream).
  static constexpr uint64_t kRotationKey = 0x5350484552494346ull;  // "SPHERICF"
  uint64_t n_;
  Mat3d rotation_;
};

}  // namespace probebake
