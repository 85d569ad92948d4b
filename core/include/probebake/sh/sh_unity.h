// Export of order-2 RGB radiance SH to Unity's ambient / light-probe shader constants
// unity_SHAr, unity_SHAg, unity_SHAb, unity_SHBr, unity_SHBg, unity_SHBb, unity_SHC (7 float4).
//
// Packing (Unity's ConvertSHConstants): with radiance coefficients L_i of one channel
// in the basis of sh_basis.h and fC0 = 1/(2 sqrt(π)), fC1 = sqrt(3)/(3 sqrt(π)),
// fC2 = sqrt(15)/(8 sqrt(π)), fC3 = sqrt(5)/(16 sqrt(π)), fC4 = fC2/2,
//   SHA = (-fC1 L3, -fC1 L1, fC1 L2, fC0 L0 - fC3 L6)
//   SHB = (fC2 L4, -fC2 L5, 3 fC3 L6, -fC2 L7)
//   SHC = (fC4 L8 red, fC4 L8 green, fC4 L8 blue, 1)
// These fold in the irradiance band factors divided by π (fC_l = Y-constant · Â_l / π), so
// Unity's ShadeSH9(n) = dot(SHA, (n, 1)) + dot(SHB, n.xyzz * n.yzzx) + SHC.rgb (x² - y²)
// equals E(n) / π, the irradiance over π (the radiance leaving a white Lambertian surface).
//
// Axes. probebake is Z-up and right-handed (docs/spherical-harmonics.md); Unity is Y-up and
// left-handed. With UnityAxes::kUnityYUp the mapping is Unity (x, y, z) = probebake (x, z, y): up
// stays up, x stays x, and probebake's +Y (forward in a Z-up right-handed world) becomes Unity's
// forward +Z. It is a reflection (det -1), applied as an improper SH rotation (sh_rotation.h), so
// ShadeSH9 of the result at n_unity = (n.x, n.z, n.y) equals E(n)/π of the input at n.
// UnityAxes::kProbebake packs the coefficients as they are.
#pragma once

#include <array>
#include <ostream>
#include <span>

#include "probebake/math/mat3.h"
#include "probebake/math/vec3.h"

namespace probebake {

enum class UnityAxes { kProbebake, kUnityYUp };

struct UnitySh9Constants {
  // SHAr, SHAg, SHAb, SHBr, SHBg, SHBb, SHC; each (x, y, z, w).
  std::array<std::array<float, 4>, 7> v{};
};

std::ostream& operator<<(std::ostream& os, const UnitySh9Constants& c);

// The direction map of kUnityYUp: n_unity = UnityFromProbebakeAxes() n.
Mat3d UnityFromProbebakeAxes();

// Packs order-2 RGB radiance coefficients (at least 9, checked; probebake's Z-up frame).
UnitySh9Constants PackUnitySh9(std::span<const Vec3d> radiance, UnityAxes axes);

// Unity's ShadeSH9 (SHEvalLinearL0L1 + SHEvalLinearL2) at unit normal n given in the packed
// constants' frame, evaluated in double without Unity's final clamp or colour-space conversion.
Vec3d EvalUnityShadeSh9(const UnitySh9Constants& c, const Vec3d& n);

}  // namespace probebake
