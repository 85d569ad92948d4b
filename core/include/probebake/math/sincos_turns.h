// sin and cos of an angle given in turns (2 pi radians), for the sampling warps' azimuths.
//
// Why not std::sin / std::cos: the warps call them once or twice per path vertex, and glibc's
// general-argument sincos costs ~130 instructions a call (docs/performance-history.md). Here the
// argument is reduced exactly in turns (no multiple of pi to subtract: t - q/4 is exact for
// |t| < 2^50 by Sterbenz's lemma), leaving x = 2 pi r with |x| <= pi/4, where truncated Taylor
// series in x^2 (evaluated by Estrin's scheme) are accurate to rounding: the first omitted terms,
// x^19/19! and x^20/20!, are below 1e-19 at pi/4. Deterministic: plain double arithmetic (the
// project builds with -ffp-contract=off), the same bits on every x86-64 build.
//
// Accuracy: |error| <= 4 * 2^-53 absolute against the exact sin(2 pi t), cos(2 pi t) (tested
// against long double over a million sampler values and |t| up to 1e6; the measured maximum is
// 1.35e-16, 0.61 ulp of 1: tests/base/sincos_turns_test.cpp).
#pragma once

#include <cstdint>

namespace probebake {

struct SinCos {
  double sin, cos;
};

// sin(2 pi turns) and cos(2 pi turns). Precondition: |turns| < 2^50 (the warps pass [0, 1)).
inline SinCos SinCosTurns(double turns) {
  // Nearest quarter turn q and the remainder r in [-1/8, 1/8] turns (exact).
  const double t4 = 4 * turns;
  const int64_t q = static_cast<int64_t>(t4 >= 0 ? t4 + 0.5 : t4 - 0.5);
  const double r = turns - static_cast<double>(q) * 0.25;
  const double x = r * 6.283185307179586476925286766559;  // 2 pi
  const double z = x * x;
  // sin x = x - x z S(z), S = 1/3! - z/5! + ... - z^7/17!; cos x = 1 - z/2 + z^2 C(z),
  // C = 1/4! - z/6! + ... - z^7/18!. x z S is at most 0.11 |x|, so its rounding errors reach the
  // result scaled down by that much. S and C by Estrin's scheme, pairs of terms combined by z^2
  // and z^4, rather than Horner's rule: a dependency chain of 3 multiply-adds instead of 8, and
  // the warps wait for the result (docs/performance-history.md).
  const double z2 = z * z, z4 = z2 * z2;
  const double s01 = 1.0 / 6.0 - z * (1.0 / 120.0);
  const double s23 = 1.0 / 5040.0 - z * (1.0 / 362880.0);
  const double s45 = 1.0 / 39916800.0 - z * (1.0 / 6227020800.0);
  const double s67 = 1.0 / 1307674368000.0 - z * (1.0 / 355687428096000.0);
  const double s = (s01 + z2 * s23) + z4 * (s45 + z2 * s67);
  const double sinX = x - x * z * s;
  const double c01 = 1.0 / 24.0 - z * (1.0 / 720.0);
  const double c23 = 1.0 / 40320.0 - z * (1.0 / 3628800.0);
  const double c45 = 1.0 / 479001600.0 - z * (1.0 / 87178291200.0);
  const double c67 = 1.0 / 20922789888000.0 - z * (1.0 / 6402373705728000.0);
  const double c = (c01 + z2 * c23) + z4 * (c45 + z2 * c67);
  // 1 - z/2 + z^2 c, with 1 - z/2 split as in fdlibm's __kernel_cos so that its rounding error
  // is recovered: w = 1 - z/2 rounded, (1 - w) - z/2 exactly what the rounding lost.
  const double hz = 0.5 * z;
  const double w = 1.0 - hz;
  const double cosX = w + (((1.0 - w) - hz) + z2 * c);
  switch (q & 3) {
    case 0:
      return {sinX, cosX};
    case 1:
      return {cosX, -sinX};
    case 2:
      return {-sinX, -cosX};
    default:
      return {-cosX, sinX};
  }
}

}  // namespace probebake
