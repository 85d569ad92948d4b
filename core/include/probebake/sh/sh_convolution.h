// Convolution of SH functions with circularly symmetric (zonal) kernels
// (docs/spherical-harmonics.md).
//
// A kernel h(ω·d) that depends only on the angle to its axis d has zonal coefficients h_l (its
// projection onto Y_l0 when d = +Z). Convolving a function f with it multiplies each band:
//   (h * f)_lm = sqrt(4π/(2l+1)) h_l f_lm =: factor_l f_lm,
// and the kernel itself, turned to axis d, has coefficients c_lm = factor_l Y_lm(d) (addition
// theorem). All functions here work in "band factor" form, factor_l = sqrt(4π/(2l+1)) h_l.
//
//  - Irradiance from radiance, E(n) = ∫ L(ω) max(0, n·ω) dω: factor_l = Â_l = π, 2π/3, π/4, 0,
//    -π/24, 0, π/64, 0, -π/128, ... (Ramamoorthi–Hanrahan 2001). Closed form for even l:
//    Â_l = 2π (-1)^(l/2-1) / ((l+2)(l-1)) · l! / (2^l ((l/2)!)²); odd l > 1 are exactly 0.
//  - The lobe family max(0, cos θ)^n, real n >= 0: factor_l = 2π ∫_0^1 P_l(u) u^n du
//    (n = 1 gives Â_l; l <= 3 match UE4's CalcDiffuseTransferSH3 closed forms).
//  - The Henyey–Greenstein phase function with mean cosine g, normalised to integrate to 1:
//    factor_l = g^l, so its lobe about d is c_lm = g^l Y_lm(d).
//
// Coefficient arrays are in the layout of sh_basis.h (index l(l+1)+m), of length at least
// ShCoeffCount(order) (checked); input and output may be the same array.
//
// References:
//  - R. Ramamoorthi, P. Hanrahan, "An Efficient Representation for Irradiance Environment Maps",
//    SIGGRAPH 2001, and "On the relationship between radiance and irradiance", JOSA A 18(10), 2001.
//  - P.-P. Sloan, "Stupid Spherical Harmonics (SH) Tricks", GDC 2008 (zonal harmonics, windows).
//  - UE4's CalcDiffuseTransferSH3 (cos^n factors); SebH's HLSL spherical-harmonics helpers (HG
//    lobe, cosine lobe).
#pragma once

#include <span>

#include "probebake/math/vec3.h"

namespace probebake {

// Â_l, the irradiance (clamped-cosine) band factor, for any l >= 0. O(l) time; exact up to
// rounding (a few ulp), exactly 0 for odd l > 1.
double IrradianceBandFactor(int l);

// 2π ∫_0^1 P_l(u) u^n du, the band factor of the lobe max(0, cos θ)^n, for l >= 0 and real n >= 0
// (checked). Built with I_{l+2} = I_l (n - l) / (n + l + 3) from I_0 = 1/(n+1), I_1 = 1/(n+2),
// so l <= 3 reproduce UE4's closed forms and the factors vanish exactly where they should
// (integer n, l > n, l - n even).
double CosinePowerBandFactor(int l, double n);

// g^l, the band factor of the Henyey–Greenstein phase function; -1 <= g <= 1 (checked; |g| = 1 is
// the limit, a delta lobe).
double HenyeyGreensteinBandFactor(int l, double g);

// out_lm = factors[l] · in_lm for l = 0..order; factors has order+1 entries.
void ScaleBands(int order, std::span<const double> factors, std::span<const double> in,
                std::span<double> out);
void ScaleBandsRgb(int order, std::span<const double> factors, std::span<const Vec3d> in,
                   std::span<Vec3d> out);

// Convolution with a zonal kernel given by its zonal coefficients h_l (l = 0..order):
// out_lm = sqrt(4π/(2l+1)) h_l in_lm.
void ConvolveZonal(int order, std::span<const double> zonal, std::span<const double> in,
                   std::span<double> out);

// Irradiance SH from radiance SH (per channel): irradiance_lm = Â_l radiance_lm. Units: radiance
// W/(m² sr) (or any radiance unit) gives irradiance in W/m² (the same unit times sr).
void RadianceToIrradiance(int order, std::span<const double> radiance,
                          std::span<double> irradiance);
void RadianceToIrradianceRgb(int order, std::span<const Vec3d> radiance,
                             std::span<Vec3d> irradiance);

// E(n) = Σ Â_l L_lm Y_lm(n): the irradiance of the order-`order` radiance expansion at unit
// normal n (non-unit n follows sh_basis.h's rule).
double IrradianceAt(int order, std::span<const double> radiance, const Vec3d& normal);
Vec3d IrradianceAtRgb(int order, std::span<const Vec3d> radiance, const Vec3d& normal);

// SH of the lobe max(0, d·ω)^n about unit axis d (n = 1: the clamped cosine, integral π).
void CosinePowerLobe(int order, double n, const Vec3d& d, std::span<double> out);

// SH of the Henyey–Greenstein phase function about unit axis d with mean cosine g (integral 1):
// c_lm = g^l Y_lm(d).
void HenyeyGreensteinLobe(int order, double g, const Vec3d& d, std::span<double> out);

}  // namespace probebake
