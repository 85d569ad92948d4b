// Real spherical-harmonic basis (docs/spherical-harmonics.md): orthonormal on the unit sphere,
// Condon–Shortley phase, polar axis +Z, evaluated on world-space unit directions (x, y, z) with no
// axis swap.
//
//   Y_l0        = sqrt((2l+1)/(4π)) P_l(z)
//   Y_lm (m>0)  = sqrt(2) K_lm P_l^m(z) cos(mφ)         P_l^m with the (-1)^m Condon–Shortley
//   phase, Y_l-m (m>0) = sqrt(2) K_lm P_l^m(z) sin(mφ)         K_lm = sqrt((2l+1)/(4π)
//   (l-m)!/(l+m)!),
//
// so Y_1-1 = -0.4886 y, Y_10 = 0.4886 z, Y_11 = -0.4886 x (the signs of Unity's and most shader SH
// code). Coefficient i = ShIndex(l, m) = l(l+1) + m; order L has ShCoeffCount(L) = (L+1)^2 of them.
//
// Two evaluation paths, agreeing to 1e-12 in double (tested):
//  - orders 0..3: hand-expanded polynomials in (x, y, z) (the fast path);
//  - EvalShBasisRecurrence, any order <= kMaxShOrder, used by EvalShBasis for orders >= 4: the
//    fully normalised associated-Legendre recurrence in z for Q_l^m = Y_lm / sin^m θ, times
//    (x + iy)^m built by complex multiplication. No trigonometry, no division by sin θ: exact at
//    the poles, and components as small as 1e-30 give correspondingly small, accurate values.
//
// Non-unit input: if |d|² differs from 1 by more than 64 ulp of T the direction is normalised
// first (one sqrt, on a branch unit callers never take), so EvalShBasis(d) = EvalShBasis(d/|d|).
// A zero, infinite or NaN direction is a caller bug and fails a PB_CHECK.
//
// References:
//  - P.-P. Sloan, "Stupid Spherical Harmonics (SH) Tricks", GDC 2008 (basis, conventions).
//  - P.-P. Sloan, "Efficient Spherical Harmonic Evaluation", JCGT 2(2), 2013 (the (x+iy)^m form).
//  - R. Green, "Spherical Harmonic Lighting: The Gritty Details", GDC 2003.
#pragma once

#include "probebake/math/vec3.h"

namespace probebake {

// Highest supported order. 9 is the largest order whose coefficient indices (0..99) fit the
// two-digit grid names radiance_sh_NN of the probe-volume file (docs/volume-format.md).
inline constexpr int kMaxShOrder = 9;

// Number of coefficients of an order-`order` expansion, (order+1)^2.
constexpr int ShCoeffCount(int order) {
  return (order + 1) * (order + 1);
}

// Linear index of (l, m), -l <= m <= l.
constexpr int ShIndex(int l, int m) {
  return l * (l + 1) + m;
}

inline constexpr int kMaxShCoeffCount = ShCoeffCount(kMaxShOrder);

// Y_0^0 = 1 / (2 sqrt(pi)), the constant basis function: a function's mean over the sphere is
// its coefficient c_0 times it.
inline constexpr double kShY00 = 0.28209479177387814347;

// Writes Y_i(d), i = 0 .. ShCoeffCount(order)-1, to out. 0 <= order <= kMaxShOrder (checked).
// d: a unit direction (see the non-unit rule above). T: float or double; float evaluates in float.
template <typename T>
void EvalShBasis(int order, const Vec3<T>& d, T* out);

// The general recurrence path for every order (EvalShBasis uses it for orders >= 4). Same
// contract as EvalShBasis; exposed so the two paths can be compared.
template <typename T>
void EvalShBasisRecurrence(int order, const Vec3<T>& d, T* out);

}  // namespace probebake
