#include "probebake/sh/sh_rotation.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "absl/strings/str_cat.h"
#include "constexpr_sqrt.h"
#include "probebake/base/check.h"
#include "probebake/base/status.h"
#include "probebake/sh/sh_basis.h"

namespace probebake {
namespace {

using sh_internal::ConstexprSqrt;

constexpr int BandOffset(int l) {
  return l * (2 * l - 1) * (2 * l + 1) / 3;
}
constexpr int kBlockStorage = BandOffset(kMaxShOrder + 1);

// The R-independent coefficients u, v, w of Ivanic–Ruedenberg (1998 erratum, table 2), stored
// per (l, m, n) at BandOffset(l) + (m + l)(2l + 1) + (n + l).
struct UvwTables {
  double u[kBlockStorage] = {};
  double v[kBlockStorage] = {};
  double w[kBlockStorage] = {};
};

constexpr UvwTables MakeUvw() {
  UvwTables t;
  for (int l = 2; l <= kMaxShOrder; ++l) {
    const int size = 2 * l + 1;
    for (int m = -l; m <= l; ++m) {
      for (int n = -l; n <= l; ++n) {
        const int k = BandOffset(l) + (m + l) * size + (n + l);
        const double d = m == 0 ? 1 : 0;
        const int am = m < 0 ? -m : m;
        const double denom =
            (n == l || n == -l) ? (2.0 * l) * (2.0 * l - 1) : double(l + n) * (l - n);
        t.u[k] = ConstexprSqrt(double(l + m) * (l - m) / denom);
        t.v[k] = 0.5 * ConstexprSqrt((1 + d) * (l + am - 1) * (l + am) / denom) * (1 - 2 * d);
        t.w[k] = -0.5 * ConstexprSqrt(double(l - am - 1) * (l - am) / denom) * (1 - d);
      }
    }
  }
  return t;
}

constexpr UvwTables kUvw = MakeUvw();

constexpr double kSqrt2 = 1.41421356237309504880;

// Band-l block from the band-1 block r1 and the band-(l-1) block prev (Ivanic–Ruedenberg).
class BandRecurrence {
 public:
  BandRecurrence(int l, const double* r1, const double* prev) : l_(l), r1_(r1), prev_(prev) {}

  void Build(double* out) const {
    const int size = 2 * l_ + 1;
    for (int m = -l_; m <= l_; ++m) {
      for (int n = -l_; n <= l_; ++n) {
        const int k = BandOffset(l_) + (m + l_) * size + (n + l_);
        double value = 0;
        if (kUvw.u[k] != 0) value += kUvw.u[k] * U(m, n);
        if (kUvw.v[k] != 0) value += kUvw.v[k] * V(m, n);
        if (kUvw.w[k] != 0) value += kUvw.w[k] * W(m, n);
        out[(m + l_) * size + (n + l_)] = value;
      }
    }
  }

 private:
  double R1(int i, int j) const { return r1_[(i + 1) * 3 + (j + 1)]; }
  double Prev(int a, int b) const { return prev_[(a + l_ - 1) * (2 * l_ - 1) + (b + l_ - 1)]; }

  double P(int i, int a, int b) const {
    if (b == l_) return R1(i, 1) * Prev(a, l_ - 1) - R1(i, -1) * Prev(a, -l_ + 1);
    if (b == -l_) return R1(i, 1) * Prev(a, -l_ + 1) + R1(i, -1) * Prev(a, l_ - 1);
    return R1(i, 0) * Prev(a, b);
  }
  double U(int m, int n) const { return P(0, m, n); }
  double V(int m, int n) const {
    if (m == 0) return P(1, 1, n) + P(-1, -1, n);
    if (m == 1) return kSqrt2 * P(1, 0, n);
    if (m == -1) return kSqrt2 * P(-1, 0, n);
    if (m > 0) return P(1, m - 1, n) - P(-1, -m + 1, n);
    return P(1, m + 1, n) + P(-1, -m - 1, n);
  }
  double W(int m, int n) const {
    if (m > 0) return P(1, m + 1, n) + P(-1, -m - 1, n);
    return P(1, m - 1, n) - P(-1, -m + 1, n);
  }

  int l_;
  const double* r1_;
  const double* prev_;
};

// out_m = Σ_n block[m][n] in_n for a band of compile-time size N (fully unrolled).
template <int N, typename V>
void ApplyBlock(const double* block, const V* in, V* out) {
  V tmp[N];
  for (int n = 0; n < N; ++n) tmp[n] = in[n];
  for (int m = 0; m < N; ++m) {
    V sum = block[m * N] * tmp[0];
    for (int n = 1; n < N; ++n) sum += block[m * N + n] * tmp[n];
    out[m] = sum;
  }
}

template <typename V>
void ApplyBands(int order, const double* blocks, const V* in, V* out) {
  out[0] = blocks[0] * in[0];
  if (order >= 1) ApplyBlock<3>(blocks + BandOffset(1), in + 1, out + 1);
  if (order >= 2) ApplyBlock<5>(blocks + BandOffset(2), in + 4, out + 4);
  if (order >= 3) ApplyBlock<7>(blocks + BandOffset(3), in + 9, out + 9);
  if (order >= 4) ApplyBlock<9>(blocks + BandOffset(4), in + 16, out + 16);
  if (order >= 5) ApplyBlock<11>(blocks + BandOffset(5), in + 25, out + 25);
  if (order >= 6) ApplyBlock<13>(blocks + BandOffset(6), in + 36, out + 36);
  if (order >= 7) ApplyBlock<15>(blocks + BandOffset(7), in + 49, out + 49);
  if (order >= 8) ApplyBlock<17>(blocks + BandOffset(8), in + 64, out + 64);
  if (order >= 9) ApplyBlock<19>(blocks + BandOffset(9), in + 81, out + 81);
  static_assert(kMaxShOrder == 9, "extend ApplyBands to the new kMaxShOrder");
}

}  // namespace

absl::StatusOr<ShRotation> ShRotation::Create(int order, const Mat3d& r) {
  if (order < 0 || order > kMaxShOrder) {
    return FieldError("rotation",
                      absl::StrCat("SH order ", order, " outside [0, ", kMaxShOrder, "]"));
  }
  double worst = 0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (!std::isfinite(r(i, j))) return FieldError("rotation", "non-finite matrix entry");
      const double dot = Dot(r.Col(i), r.Col(j));
      worst = std::max(worst, std::abs(dot - (i == j ? 1.0 : 0.0)));
    }
  }
  if (!(worst <= kOrthogonalityTolerance)) {
    return FieldError("rotation", absl::StrCat("matrix is not orthogonal (max |R^T R - I| = ",
                                               worst, " > ", kOrthogonalityTolerance, ")"));
  }
  ShRotation rot;
  rot.order_ = order;
  rot.r_ = r;
  rot.improper_ = Determinant(r) < 0;
  rot.blocks_.resize(BandOffset(order + 1));
  double* b = rot.blocks_.data();
  b[0] = 1;
  if (order == 0) return rot;
  // Band 1: the basis is -y, z, -x (times sqrt(3/(4π))), i.e. P ω with P the signed permutation
  // p = (y, z, x), s = (-1, 1, -1); the block is P R' Pᵀ with R' the proper part of r.
  const double sign = rot.improper_ ? -1 : 1;
  constexpr int p[3] = {1, 2, 0};
  constexpr double s[3] = {-1, 1, -1};
  double* r1 = b + BandOffset(1);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r1[i * 3 + j] = sign * s[i] * s[j] * r(p[i], p[j]);
  for (int l = 2; l <= order; ++l) {
    BandRecurrence(l, r1, b + BandOffset(l - 1)).Build(b + BandOffset(l));
  }
  if (rot.improper_) {
    // The inversion: band l times (-1)^l, applied once every band of -r exists.
    for (int l = 1; l <= order; l += 2) {
      for (int k = BandOffset(l); k < BandOffset(l + 1); ++k) b[k] = -b[k];
    }
  }
  return rot;
}

std::span<const double> ShRotation::Band(int l) const {
  PB_CHECK(l >= 0 && l <= order_);
  return std::span<const double>(blocks_).subspan(BandOffset(l), (2 * l + 1) * (2 * l + 1));
}

void ShRotation::Apply(std::span<const double> in, std::span<double> out) const {
  const size_t count = ShCoeffCount(order_);
  PB_CHECK_GE(in.size(), count);
  PB_CHECK_GE(out.size(), count);
  ApplyBands(order_, blocks_.data(), in.data(), out.data());
}

void ShRotation::ApplyRgb(std::span<const Vec3d> in, std::span<Vec3d> out) const {
  const size_t count = ShCoeffCount(order_);
  PB_CHECK_GE(in.size(), count);
  PB_CHECK_GE(out.size(), count);
  ApplyBands(order_, blocks_.data(), in.data(), out.data());
}

std::ostream& operator<<(std::ostream& os, const ShRotation& rotation) {
  os << "ShRotation{order " << rotation.order() << ", R " << rotation.matrix()
     << (rotation.improper() ? ", improper" : "") << ", bands [";
  for (int l = 0; l <= rotation.order(); ++l) {
    const std::span<const double> band = rotation.Band(l);
    os << (l ? "; " : "") << "l" << l << ":";
    for (size_t k = 0; k < band.size(); ++k) os << " " << band[k];
  }
  return os << "]}";
}

}  // namespace probebake
