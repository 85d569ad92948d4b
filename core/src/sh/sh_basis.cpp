#include "probebake/sh/sh_basis.h"

#include <cmath>
#include <limits>
#include <type_traits>

#include "constexpr_sqrt.h"
#include "probebake/base/check.h"

namespace probebake {
namespace {

using sh_internal::ConstexprSqrt;

// Coefficients of the fully normalised recurrence for Q_l^m = Y_l±m / sin^m θ with the azimuthal
// factor (cos mφ, sin mφ) removed (m >= 0; for m > 0 it includes the sqrt(2) of real SH):
//   Q_m^m     = qmm[m]                      (a constant: the sin^m θ is carried by (x+iy)^m)
//   Q_l^m     = a[l][m] z Q_{l-1}^m + b[l][m] Q_{l-2}^m      (l > m; Q_{m-1}^m = 0)
// with a = sqrt((4l²-1)/(l²-m²)), b = -sqrt((2l+1)(l+m-1)(l-m-1) / ((2l-3)(l-m)(l+m))). These
// are the three-term Legendre recurrence divided through by the normalisation, so every
// intermediate is O(1): no factorial growth, no overflow at high order.
template <typename T>
struct RecurrenceTables {
  T qmm[kMaxShOrder + 1] = {};
  T a[kMaxShOrder + 1][kMaxShOrder + 1] = {};
  T b[kMaxShOrder + 1][kMaxShOrder + 1] = {};
};

constexpr RecurrenceTables<double> MakeTables() {
  RecurrenceTables<double> t;
  t.qmm[0] = 0.28209479177387814347;  // 1/(2 sqrt(π))
  for (int m = 1; m <= kMaxShOrder; ++m) {
    // Q_m^m / Q_{m-1}^{m-1} = -sqrt((2m+1)/(2m)), times sqrt(2) once for the real-SH factor.
    const double ratio = -ConstexprSqrt((2.0 * m + 1) / (2.0 * m) * (m == 1 ? 2.0 : 1.0));
    t.qmm[m] = t.qmm[m - 1] * ratio;
  }
  for (int m = 0; m <= kMaxShOrder; ++m) {
    for (int l = m + 1; l <= kMaxShOrder; ++l) {
      const double ll = l, mm = m;
      t.a[l][m] = ConstexprSqrt((4 * ll * ll - 1) / (ll * ll - mm * mm));
      if (l >= m + 2) {
        t.b[l][m] = -ConstexprSqrt((2 * ll + 1) * (ll + mm - 1) * (ll - mm - 1) /
                                   ((2 * ll - 3) * (ll - mm) * (ll + mm)));
      }
    }
  }
  return t;
}

constexpr RecurrenceTables<double> kTablesDouble = MakeTables();

constexpr RecurrenceTables<float> MakeFloatTables() {
  RecurrenceTables<float> f;
  for (int i = 0; i <= kMaxShOrder; ++i) {
    f.qmm[i] = static_cast<float>(kTablesDouble.qmm[i]);
    for (int j = 0; j <= kMaxShOrder; ++j) {
      f.a[i][j] = static_cast<float>(kTablesDouble.a[i][j]);
      f.b[i][j] = static_cast<float>(kTablesDouble.b[i][j]);
    }
  }
  return f;
}

constexpr RecurrenceTables<float> kTablesFloat = MakeFloatTables();

template <typename T>
constexpr const RecurrenceTables<T>& Tables() {
  if constexpr (std::is_same_v<T, float>) {
    return kTablesFloat;
  } else {
    return kTablesDouble;
  }
}

// The documented non-unit rule: d is used as given when |d|² is within 64 ulp of 1, else
// normalised (out of line: unit callers only pay for |d|² and one compare). Scalars, not a
// Vec3 copy, so the fast path keeps x, y, z in registers.
template <typename T>
[[gnu::noinline]] Vec3<T> NormalizeSlow(const Vec3<T>& d, T r2) {
  // Also reached for NaN (every comparison with it is false).
  PB_CHECK(r2 > 0 && std::isfinite(r2));
  return d / std::sqrt(r2);
}

template <typename T>
struct Xyz {
  T x, y, z;
};

template <typename T>
inline Xyz<T> UnitDirection(const Vec3<T>& d) {
  constexpr T kTolerance = 64 * std::numeric_limits<T>::epsilon();
  const T r2 = d.x * d.x + d.y * d.y + d.z * d.z;
  if (std::abs(r2 - T(1)) <= kTolerance) [[likely]]
    return {d.x, d.y, d.z};
  const Vec3<T> u = NormalizeSlow(d, r2);
  return {u.x, u.y, u.z};
}

template <typename T>
inline void Recurrence(int order, const Xyz<T>& d, T* out) {
  const RecurrenceTables<T>& t = Tables<T>();
  const T x = d.x, y = d.y, z = d.z;
  // c[m] + i s[m] = (x + iy)^m = sin^m θ (cos mφ + i sin mφ).
  T c[kMaxShOrder + 1], s[kMaxShOrder + 1];
  c[0] = 1;
  s[0] = 0;
  for (int m = 1; m <= order; ++m) {
    c[m] = x * c[m - 1] - y * s[m - 1];
    s[m] = x * s[m - 1] + y * c[m - 1];
  }
  // m = 0: zonal terms.
  {
    T q2 = t.qmm[0];
    out[0] = q2;
    if (order >= 1) {
      T q1 = t.a[1][0] * z * q2;
      out[ShIndex(1, 0)] = q1;
      for (int l = 2; l <= order; ++l) {
        const T q = t.a[l][0] * z * q1 + t.b[l][0] * q2;
        out[ShIndex(l, 0)] = q;
        q2 = q1;
        q1 = q;
      }
    }
  }
  for (int m = 1; m <= order; ++m) {
    T q2 = t.qmm[m];
    out[ShIndex(m, m)] = q2 * c[m];
    out[ShIndex(m, -m)] = q2 * s[m];
    if (m + 1 > order) break;
    T q1 = t.a[m + 1][m] * z * q2;
    out[ShIndex(m + 1, m)] = q1 * c[m];
    out[ShIndex(m + 1, -m)] = q1 * s[m];
    for (int l = m + 2; l <= order; ++l) {
      const T q = t.a[l][m] * z * q1 + t.b[l][m] * q2;
      out[ShIndex(l, m)] = q * c[m];
      out[ShIndex(l, -m)] = q * s[m];
      q2 = q1;
      q1 = q;
    }
  }
}

// Hand-expanded polynomials for orders 0..3 (valid on the unit sphere: z² - 1/3 and friends are
// written with x² + y² + z² = 1 folded in). Constants are the normalisations K, to 20 digits.
template <typename T>
inline void ClosedForm(int order, const Xyz<T>& d, T* out) {
  const T x = d.x, y = d.y, z = d.z;
  out[0] = T(0.28209479177387814347);
  if (order == 0) return;
  constexpr T k1 = T(0.48860251190291992159);  // sqrt(3/(4π))
  out[1] = -k1 * y;
  out[2] = k1 * z;
  out[3] = -k1 * x;
  if (order == 1) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  const T xy = x * y, yz = y * z, xz = x * z;
  constexpr T k2a = T(1.0925484305920790705);   // sqrt(15/(4π))
  constexpr T k20 = T(0.31539156525252000603);  // sqrt(5/(16π))
  constexpr T k22 = T(0.54627421529603953527);  // sqrt(15/(16π))
  out[4] = k2a * xy;
  out[5] = -k2a * yz;
  out[6] = k20 * (T(3) * zz - T(1));
  out[7] = -k2a * xz;
  out[8] = k22 * (xx - yy);
  if (order == 2) return;
  constexpr T k33 = T(0.59004358992664351035);  // sqrt(35/(32π))
  constexpr T k32 = T(2.8906114426405540554);   // sqrt(105/(4π))
  constexpr T k31 = T(0.45704579946446573616);  // sqrt(21/(32π))
  constexpr T k30 = T(0.37317633259011539141);  // sqrt(7/(16π))
  constexpr T k32b = T(1.4453057213202770277);  // sqrt(105/(16π))
  const T five_zz_1 = T(5) * zz - T(1);
  out[9] = -k33 * y * (T(3) * xx - yy);
  out[10] = k32 * xy * z;
  out[11] = -k31 * y * five_zz_1;
  out[12] = k30 * z * (T(5) * zz - T(3));
  out[13] = -k31 * x * five_zz_1;
  out[14] = k32b * z * (xx - yy);
  out[15] = -k33 * x * (xx - T(3) * yy);
}

}  // namespace

template <typename T>
void EvalShBasis(int order, const Vec3<T>& d, T* out) {
  PB_CHECK(order >= 0 && order <= kMaxShOrder);
  const Xyz<T> u = UnitDirection(d);
  if (order <= 3) {
    ClosedForm(order, u, out);
  } else {
    Recurrence(order, u, out);
  }
}

template <typename T>
void EvalShBasisRecurrence(int order, const Vec3<T>& d, T* out) {
  PB_CHECK(order >= 0 && order <= kMaxShOrder);
  Recurrence(order, UnitDirection(d), out);
}

template void EvalShBasis<float>(int, const Vec3<float>&, float*);
template void EvalShBasis<double>(int, const Vec3<double>&, double*);
template void EvalShBasisRecurrence<float>(int, const Vec3<float>&, float*);
template void EvalShBasisRecurrence<double>(int, const Vec3<double>&, double*);

}  // namespace probebake
