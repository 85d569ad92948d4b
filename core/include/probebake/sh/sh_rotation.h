// Rotation of SH expansions (basis of sh_basis.h) by a 3x3 orthogonal matrix.
//
// Convention: rotating f by R gives (R f)(ω) = f(Rᵀ ω), so a lobe pointing along d ends up
// pointing along R d: rotate-then-evaluate at ω equals evaluate-at-Rᵀω (tested). R acts on
// column vectors (math/mat3.h). Each band l transforms on its own by a (2l+1)x(2l+1) block:
//   out_lm = Σ_n B_l[m][n] in_ln,
// built once per matrix (Ivanic–Ruedenberg recurrence from the band-1 block, which is R itself
// with rows and columns permuted to (y, z, x) and the Condon–Shortley signs) and applied to as
// many vectors as needed.
//
// Improper matrices (det -1, e.g. client axis conversions that swap handedness) are accepted:
// R = (-R)(-I), the inversion -I maps Y_lm(-ω) = (-1)^l Y_lm(ω), so the blocks of the proper
// rotation -R are used with band l multiplied by (-1)^l.
//
// References:
//  - J. Ivanic, K. Ruedenberg, "Rotation Matrices for Real Spherical Harmonics. Direct
//    Determination by Recursion", J. Phys. Chem. 100(15), 1996, and the erratum, J. Phys.
//    Chem. A 102(45), 1998 (the corrected P, U, V, W terms used here).
//  - C. H. Choi et al., "Rapid and stable determination of rotation matrices between spherical
//    harmonics by direct recursion", J. Chem. Phys. 111(19), 1999.
//  - P.-P. Sloan, "Stupid Spherical Harmonics (SH) Tricks", GDC 2008.
#pragma once

#include <ostream>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/math/mat3.h"
#include "probebake/math/vec3.h"

namespace probebake {

class ShRotation {
 public:
  // Largest max |RᵀR - I| accepted by Create (float-precision matrices pass; the SH blocks are
  // then orthogonal to about the same accuracy).
  static constexpr double kOrthogonalityTolerance = 1e-6;

  // Builds the blocks of bands 0..order for r. INVALID_ARGUMENT "rotation: ..." when order is
  // outside [0, kMaxShOrder], r has a non-finite entry, or r is not orthogonal within
  // kOrthogonalityTolerance.
  static absl::StatusOr<ShRotation> Create(int order, const Mat3d& r);

  int order() const { return order_; }
  const Mat3d& matrix() const { return r_; }
  bool improper() const { return improper_; }

  // B_l[m][n], the block entry of band l (0 <= l <= order, |m|, |n| <= l; checked).
  double Element(int l, int m, int n) const;

  // out = R in for the first ShCoeffCount(order()) coefficients (both spans at least that long,
  // checked). in and out may be the same array.
  void Apply(std::span<const double> in, std::span<double> out) const;
  void ApplyRgb(std::span<const Vec3d> in, std::span<Vec3d> out) const;

 private:
  ShRotation() = default;

  int order_ = 0;
  Mat3d r_;
  bool improper_ = false;
  // Band l, column-major ((n + l)(2l + 1) + (m + l)), starts at l(2l-1)(2l+1)/3.
  std::vector<double> blocks_;
};

std::ostream& operator<<(std::ostream& os, const ShRotation& rotation);

}  // namespace probebake
