// Projection onto the SH basis of sh_basis.h, reconstruction and product integrals.
//
//   projection      f_i = ∫ f(ω) Y_i(ω) dω
//   reconstruction  f(ω) ≈ Σ_i f_i Y_i(ω)
//   product         ∫ f(ω) g(ω) dω = Σ_i f_i g_i (orthonormality), exact for the truncations
//
// ShAccumulator / ShAccumulatorRgb sum sample contributions S_i = Σ_k x_k Y_i(ω_k) (x_k is a
// sample's weighted value, e.g. radiance / pdf) for Monte Carlo or quadrature projection. The sum
// is two-level: plain double sums over blocks of kBlockSize samples, each block then folded into
// a compensated (double-double) total with TwoSum. The rounding error of every coefficient is
// at most (kBlockSize + 2) u Σ_k |x_k Y_i(ω_k)| (u = 2^-53) whatever the number of samples (a
// float running sum of 1e8 samples loses everything; a plain double one drifts by up to 1e8 u):
// tested with 1e8 samples. The result depends only on the sequence of samples (and of merges),
// never on timing. Per sample the cost is that of a plain double sum.
//
// Coefficient arrays: layout of sh_basis.h, length at least ShCoeffCount(order) (checked).
//
// References: P.-P. Sloan, "Stupid Spherical Harmonics (SH) Tricks", GDC 2008; N. J. Higham,
// "Accuracy and Stability of Numerical Algorithms", 2nd ed., ch. 4 (summation error bounds).
#pragma once

#include <cstdint>
#include <span>
#include <type_traits>
#include <vector>

#include "probebake/base/check.h"
#include "probebake/math/vec3.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sphere_quadrature.h"

namespace probebake {

// Σ_i coeffs_i Y_i(dir) for unit dir (sh_basis.h's non-unit rule applies).
double ShReconstruct(int order, std::span<const double> coeffs, const Vec3d& dir);
Vec3d ShReconstructRgb(int order, std::span<const Vec3d> coeffs, const Vec3d& dir);

// ∫ f g dω = Σ_i f_i g_i over the first ShCoeffCount(order) coefficients.
double ShDot(int order, std::span<const double> f, std::span<const double> g);
// Per channel.
Vec3d ShDotRgb(int order, std::span<const Vec3d> f, std::span<const Vec3d> g);
// RGB function times a scalar one (e.g. lighting times a transfer function).
Vec3d ShDotRgb(int order, std::span<const Vec3d> f, std::span<const double> g);

// Accumulates S_i = Σ_k x_k Y_i(ω_k) per channel; Value is double (ShAccumulator) or Vec3d
// (ShAccumulatorRgb).
template <typename Value>
class ShAccumulatorT {
 public:
  static_assert(std::is_same_v<Value, double> || std::is_same_v<Value, Vec3d>);
  static constexpr int kChannels = std::is_same_v<Value, double> ? 1 : 3;
  static constexpr int kBlockSize = 256;

  // 0 <= order <= kMaxShOrder (checked).
  explicit ShAccumulatorT(int order);

  int order() const { return order_; }
  int64_t count() const { return count_; }

  // Adds x · Y(dir): evaluates the basis at unit dir.
  void Add(const Vec3d& dir, const Value& x);

  // Adds x · basis, where basis holds Y_i(ω) for i < ShCoeffCount(order()) (e.g. from one
  // EvalShBasis shared by several accumulators).
  void AddBasis(std::span<const double> basis, const Value& x) {
    PB_DCHECK_GE(basis.size(), static_cast<size_t>(coeffs_));
    double* block = block_.data();
    if constexpr (kChannels == 1) {
      for (int i = 0; i < coeffs_; ++i) block[i] += basis[i] * x;
    } else {
      // Channel-major, so each channel's update is one contiguous (vectorisable) loop.
      for (int i = 0; i < coeffs_; ++i) block[i] += basis[i] * x.x;
      for (int i = 0; i < coeffs_; ++i) block[coeffs_ + i] += basis[i] * x.y;
      for (int i = 0; i < coeffs_; ++i) block[2 * coeffs_ + i] += basis[i] * x.z;
    }
    if (++count_ % kBlockSize == 0) FoldBlock();
  }

  // Adds other's samples (same order, checked) as if they followed this one's.
  void Merge(const ShAccumulatorT& other);

  // out_i = scale · S_i (e.g. scale = 1/N, or 4π/N for uniform sphere samples of f).
  void Sum(std::span<Value> out, double scale = 1) const;

  void Reset();

 private:
  void FoldBlock();
  static void TwoSumInto(double x, double& hi, double& lo);

  int order_;
  int coeffs_;
  int64_t count_ = 0;
  // Per channel and coefficient (index c · coeffs_ + i): the open block's plain sum, and the
  // compensated total hi + lo of the folded blocks.
  std::vector<double> block_, hi_, lo_;
};

using ShAccumulator = ShAccumulatorT<double>;
using ShAccumulatorRgb = ShAccumulatorT<Vec3d>;

// f_i = ∫ f Y_i by a sphere quadrature (sphere_quadrature.h): exact when f Y_i is a polynomial
// of degree the rule integrates exactly. f: const Vec3d& -> double (or Vec3d, with out Vec3d).
template <typename F, typename Value>
void ShProjectQuadrature(int order, std::span<const SphereQuadratureNode> nodes, F&& f,
                         std::span<Value> out) {
  ShAccumulatorT<Value> acc(order);
  for (const SphereQuadratureNode& node : nodes) {
    acc.Add(node.direction, static_cast<Value>(f(node.direction)) * node.weight);
  }
  acc.Sum(out);
}

}  // namespace probebake
