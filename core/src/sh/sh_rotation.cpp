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

// Ivanic–Ruedenberg (1998 erratum, table 2) writes the band-l block as
//   B_l[m][n] = u U + v V + w W,
// where U, V, W are sums of P_i(a, n) terms (i in {-1, 0, 1}, a a row of band l-1) and u, v, w
// depend on n only through 1/sqrt(denom(n)), denom = (l+n)(l-n) for |n| < l and 2l(2l-1) at
// |n| = l. So each row m is a short list of terms c · P_i(a, ·), scaled per column by
// 1/sqrt(denom(n)); the terms and scales are R-independent and tabulated here.
//   P_i(a, n) = B1[i][0] B_{l-1}[a][n]                                    (|n| < l)
//   P_i(a, l) = B1[i][1] B_{l-1}[a][l-1] - B1[i][-1] B_{l-1}[a][1-l]
//   P_i(a,-l) = B1[i][1] B_{l-1}[a][1-l] + B1[i][-1] B_{l-1}[a][l-1]
struct RowTerm {
  int i = 0;     // band-1 row, -1..1
  int a = 0;     // band-(l-1) row
  double c = 0;  // u, v or w without the 1/sqrt(denom), with V's and W's signs and sqrt(2)
};

struct RowRecipe {
  int count = 0;
  RowTerm terms[5];
};

struct RecurrenceTables {
  // recipe[l][m + l]; inv_denom[l][n + l] = 1/sqrt(denom(n)).
  RowRecipe recipe[kMaxShOrder + 1][2 * kMaxShOrder + 1];
  double inv_denom[kMaxShOrder + 1][2 * kMaxShOrder + 1] = {};
};

constexpr RecurrenceTables MakeRecurrenceTables() {
  RecurrenceTables t;
  constexpr double kSqrt2 = 1.41421356237309504880;
  for (int l = 2; l <= kMaxShOrder; ++l) {
    for (int n = -l; n <= l; ++n) {
      const double denom =
          (n == l || n == -l) ? (2.0 * l) * (2.0 * l - 1) : double(l + n) * (l - n);
      t.inv_denom[l][n + l] = 1 / ConstexprSqrt(denom);
    }
    for (int m = -l; m <= l; ++m) {
      RowRecipe& r = t.recipe[l][m + l];
      auto add = [&r](int i, int a, double c) { r.terms[r.count++] = RowTerm{i, a, c}; };
      const double d = m == 0 ? 1 : 0;
      const int am = m < 0 ? -m : m;
      const double u = ConstexprSqrt(double(l + m) * (l - m));
      const double v = 0.5 * ConstexprSqrt((1 + d) * (l + am - 1) * (l + am)) * (1 - 2 * d);
      const double w = -0.5 * ConstexprSqrt(double(l - am - 1) * (l - am)) * (1 - d);
      if (u != 0) add(0, m, u);
      if (v != 0) {
        if (m == 0) {
          add(1, 1, v);
          add(-1, -1, v);
        } else if (m == 1) {
          add(1, 0, v * kSqrt2);
        } else if (m == -1) {
          add(-1, 0, v * kSqrt2);
        } else if (m > 1) {
          add(1, m - 1, v);
          add(-1, -m + 1, -v);
        } else {
          add(1, m + 1, v);
          add(-1, -m - 1, v);
        }
      }
      if (w != 0) {
        if (m > 0) {
          add(1, m + 1, w);
          add(-1, -m - 1, w);
        } else {
          add(1, m - 1, w);
          add(-1, -m + 1, -w);
        }
      }
    }
  }
  return t;
}

constexpr RecurrenceTables kRecurrence = MakeRecurrenceTables();

// Band L, row-major into `cur` ((2L+1)²), from band 1 (b1, row-major 3x3) and band L-1 (`prev`,
// row-major). Rows are combinations of whole rows of `prev`, so the inner loops are contiguous;
// L is a template argument so the loops and the tabulated recipes unroll into straight code.
template <int L>
void BuildBand(const double* b1, const double* prev, double* cur) {
  constexpr int kSize = 2 * L + 1, kPrev = 2 * L - 1;
  const double* inv_denom = kRecurrence.inv_denom[L];
#pragma GCC unroll 19
  for (int m = -L; m <= L; ++m) {
    const RowRecipe& recipe = kRecurrence.recipe[L][m + L];
    double row[kSize] = {};
#pragma GCC unroll 5
    for (int t = 0; t < recipe.count; ++t) {
      const RowTerm& term = recipe.terms[t];
      const double* p = prev + (term.a + L - 1) * kPrev;  // row a of band L-1, index b + L - 1
      const double* r1 = b1 + (term.i + 1) * 3;           // r1[0..2] = B1[i][-1, 0, 1]
      const double center = term.c * r1[1];
      for (int n = 1; n < kSize - 1; ++n) row[n] += center * p[n - 1];
      row[kSize - 1] += term.c * (r1[2] * p[kPrev - 1] - r1[0] * p[0]);
      row[0] += term.c * (r1[2] * p[0] + r1[0] * p[kPrev - 1]);
    }
    for (int n = 0; n < kSize; ++n) cur[(m + L) * kSize + n] = row[n] * inv_denom[n];
  }
}

void BuildBand(int l, const double* b1, const double* prev, double* cur) {
  switch (l) {
    case 2:
      return BuildBand<2>(b1, prev, cur);
    case 3:
      return BuildBand<3>(b1, prev, cur);
    case 4:
      return BuildBand<4>(b1, prev, cur);
    case 5:
      return BuildBand<5>(b1, prev, cur);
    case 6:
      return BuildBand<6>(b1, prev, cur);
    case 7:
      return BuildBand<7>(b1, prev, cur);
    case 8:
      return BuildBand<8>(b1, prev, cur);
    case 9:
      return BuildBand<9>(b1, prev, cur);
  }
  static_assert(kMaxShOrder == 9, "extend BuildBand to the new kMaxShOrder");
  PB_CHECK(false);
}

// out_m = Σ_n B[m][n] in_n for one band of compile-time size N, B column-major. Accumulating
// column by column keeps each out_m's sum in the order n = 0, 1, ... (the same bits as a row
// dot product) while the loop over m vectorises.
template <int N>
void ApplyBlock(const double* block, const double* in, double* out) {
  double x[N], acc[N];
  for (int n = 0; n < N; ++n) x[n] = in[n];
  for (int m = 0; m < N; ++m) acc[m] = block[m] * x[0];
  for (int n = 1; n < N; ++n)
    for (int m = 0; m < N; ++m) acc[m] += block[n * N + m] * x[n];
  for (int m = 0; m < N; ++m) out[m] = acc[m];
}

// RGB: the three channels as separate contiguous vectors, each through the scalar kernel.
template <int N>
void ApplyBlock(const double* block, const Vec3d* in, Vec3d* out) {
  double c[3][N], o[3][N];
  for (int n = 0; n < N; ++n) c[0][n] = in[n].x, c[1][n] = in[n].y, c[2][n] = in[n].z;
  for (int k = 0; k < 3; ++k) ApplyBlock<N>(block, c[k], o[k]);
  for (int m = 0; m < N; ++m) out[m] = {o[0][m], o[1][m], o[2][m]};
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
  // Bands are built row-major in two ping-pong scratch buffers (the recurrence reads whole rows
  // of the previous band) and stored column-major (what Apply wants).
  double b1[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) b1[i * 3 + j] = sign * s[i] * s[j] * r(p[i], p[j]);
  double scratch[2][(2 * kMaxShOrder + 1) * (2 * kMaxShOrder + 1)];
  std::copy(b1, b1 + 9, scratch[1]);
  const double flip = rot.improper_ ? -1 : 1;  // the inversion: band l times (-1)^l
  for (int l = 1; l <= order; ++l) {
    double* cur = scratch[l % 2];
    if (l >= 2) BuildBand(l, b1, scratch[(l - 1) % 2], cur);
    const int size = 2 * l + 1;
    const double bandSign = (l % 2 == 1) ? flip : 1.0;
    double* out = b + BandOffset(l);
    for (int m = 0; m < size; ++m)
      for (int n = 0; n < size; ++n) out[n * size + m] = bandSign * cur[m * size + n];
  }
  return rot;
}

double ShRotation::Element(int l, int m, int n) const {
  PB_CHECK(l >= 0 && l <= order_);
  PB_CHECK(m >= -l && m <= l && n >= -l && n <= l);
  return blocks_[BandOffset(l) + (n + l) * (2 * l + 1) + (m + l)];
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
    os << (l ? "; " : "") << "l" << l << ":";
    for (int m = -l; m <= l; ++m)
      for (int n = -l; n <= l; ++n) os << " " << rotation.Element(l, m, n);
  }
  return os << "]}";
}

}  // namespace probebake
