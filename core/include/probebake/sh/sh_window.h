// Windows against ringing (docs/spherical-harmonics.md), applied per band as f_lm *= w_l:
//   none      w_l = 1
//   Hanning   w_l = (1 + cos(π l / W)) / 2 for l <= W, 0 beyond (width W > 0)
//   Lanczos   w_l = sinc(l / (L + 1)), sinc(x) = sin(πx)/(πx), L the expansion's order
//   heat      w_l = exp(-t l(l+1)), t >= 0 (the heat kernel on the sphere at time t; t = +inf
//             keeps band 0 only)
//
// Auto window: the heat family is the one-parameter family searched, because the heat kernel
// is a positive operator and obeys the minimum principle: the minimum over the sphere of the
// windowed irradiance is non-decreasing in t. So "the weakest window that makes the irradiance
// non-negative" is well defined: t* = min{t >= 0 : E_t(ω) >= 0 for all ω and all three RGB
// channels}, bracketed by a root search on t (Brent's method) to relative width 1e-10, and
// every t below the bracket leaves a negative value somewhere. Radiance whose irradiance is
// already non-negative gives t* = 0 (the input is unchanged).
//  - Orders <= 3 (irradiance bands 0, 1, 2 only, since Â_3 = 0): E(ω) = c + b·ω + ωᵀAω is a
//    quadratic form on the sphere, minimised exactly through the eigenvectors of A and the dual
//    max_{μ <= λmin} μ - Σ β_i² / (4(λ_i - μ)), which is a lower bound for every μ and tight at
//    its maximiser (trust-region duality). The returned t is therefore proven non-negative (up
//    to rounding, ~1e-16 of the irradiance).
//  - Orders >= 4: a deterministic grid (spacing π/(2 L_E + 2), L_E the highest irradiance band)
//    gives each point's per-band values once; the root search runs on the grid minimum; then the
//    grid's local minima below a Bernstein bound (the most a minimum between grid points can
//    undercut them) are refined by Newton's method on the sphere, and refined minima that are
//    still negative join the grid for another search above. This is a search, not a proof: a
//    negative basin narrower than the grid spacing whose nearest grid point is not a local grid
//    minimum could be missed. Tests check the result against an independent dense minimiser.
//  - Both: a first sufficient test (band amplitudes, addition theorem) clears most already
//    non-negative probes with no further work.
// Cost per probe: benchmark BM_AutoWindowRinging (probebake_sh_bench); probes that are already
// non-negative mostly stop at the amplitude test.
//
// References: P.-P. Sloan, "Stupid Spherical Harmonics (SH) Tricks", GDC 2008 (windowing);
// P.-P. Sloan, "Deringing Spherical Harmonics", SIGGRAPH Asia 2017 Technical Briefs;
// J. J. Moré, D. C. Sorensen, "Computing a Trust Region Step", SIAM J. Sci. Stat. Comput. 4(3),
// 1983 (the secular equation and the hard case).
#pragma once

#include <ostream>
#include <span>
#include <string>

#include "probebake/math/vec3.h"

namespace probebake {

double HanningWindowFactor(int l, double width);  // width > 0, l >= 0 (checked)
double LanczosWindowFactor(int l, int order);     // 0 <= l, order >= 0 (checked)
double HeatWindowFactor(int l, double t);         // t >= 0 or +inf, l >= 0 (checked)

// A window with its parameter. (scene/scene.h's ShWindow is the job setting that selects one;
// this is the window itself, as applied and recorded.)
enum class ShBandWindowKind { kNone, kHanning, kLanczos, kHeat };

struct ShBandWindow {
  ShBandWindowKind kind = ShBandWindowKind::kNone;
  double parameter = 0;  // Hanning: width W; heat: t; unused otherwise

  static ShBandWindow None() { return {}; }
  static ShBandWindow Hanning(double width) { return {ShBandWindowKind::kHanning, width}; }
  static ShBandWindow Lanczos() { return {ShBandWindowKind::kLanczos, 0}; }
  static ShBandWindow Heat(double t) { return {ShBandWindowKind::kHeat, t}; }

  // w_l for band l of an order-`order` expansion.
  double Factor(int l, int order) const;
  // "NONE", "HANNING(width=3)", "LANCZOS", "HEAT(t=0.0125)" (17 significant digits).
  std::string ToString() const;

  friend bool operator==(const ShBandWindow&, const ShBandWindow&) = default;
};

std::ostream& operator<<(std::ostream& os, const ShBandWindow& window);

// coeffs_lm *= w_l for the first ShCoeffCount(order) coefficients (checked).
void ApplyShWindow(const ShBandWindow& window, int order, std::span<double> coeffs);
void ApplyShWindowRgb(const ShBandWindow& window, int order, std::span<Vec3d> coeffs);

struct AutoWindowResult {
  // Heat(t*). t* = 0 when the irradiance is already non-negative; +inf (band 0 only) when no
  // window of the family suffices.
  ShBandWindow window;
  // False only when some channel's mean irradiance is negative (radiance L00 < 0), which no
  // window can fix (valid radiance never does this).
  bool nonNegative = true;
};

std::ostream& operator<<(std::ostream& os, const AutoWindowResult& result);

// The auto window of an order-`order` RGB radiance expansion (the irradiance is its Â_l
// convolution). Does not modify radiance; apply result.window with ApplyShWindowRgb.
AutoWindowResult FindAutoShWindow(int order, std::span<const Vec3d> radiance);

}  // namespace probebake
