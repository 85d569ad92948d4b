// 3x3 matrices, row-major: m[r][c]. Applied to column vectors (v' = M v), like the job file's
// transforms. Used for rotations of directions and SH, and for normal transforms.
#pragma once

#include <array>
#include <cmath>
#include <ostream>

#include "probebake/math/vec3.h"

namespace probebake {

template <typename T>
struct Mat3 {
  std::array<std::array<T, 3>, 3> m{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};

  static constexpr Mat3 Identity() { return {}; }
  static constexpr Mat3 FromRows(const Vec3<T>& r0, const Vec3<T>& r1, const Vec3<T>& r2) {
    Mat3 a;
    a.m = {{{r0.x, r0.y, r0.z}, {r1.x, r1.y, r1.z}, {r2.x, r2.y, r2.z}}};
    return a;
  }
  // Rotation by `angle` radians about unit `axis`, counter-clockwise looking down the axis
  // (right-hand rule).
  static Mat3 Rotation(const Vec3<T>& axis, T angle) {
    const T c = std::cos(angle), s = std::sin(angle), t = 1 - c;
    const T x = axis.x, y = axis.y, z = axis.z;
    return FromRows({t * x * x + c, t * x * y - s * z, t * x * z + s * y},
                    {t * x * y + s * z, t * y * y + c, t * y * z - s * x},
                    {t * x * z - s * y, t * y * z + s * x, t * z * z + c});
  }

  constexpr T operator()(int r, int c) const { return m[r][c]; }
  constexpr T& operator()(int r, int c) { return m[r][c]; }
  constexpr Vec3<T> Row(int r) const { return {m[r][0], m[r][1], m[r][2]}; }
  constexpr Vec3<T> Col(int c) const { return {m[0][c], m[1][c], m[2][c]}; }

  friend constexpr bool operator==(const Mat3&, const Mat3&) = default;
};

using Mat3d = Mat3<double>;
using Mat3f = Mat3<float>;

template <typename T>
constexpr Vec3<T> operator*(const Mat3<T>& a, const Vec3<T>& v) {
  return {Dot(a.Row(0), v), Dot(a.Row(1), v), Dot(a.Row(2), v)};
}

template <typename T>
constexpr Mat3<T> operator*(const Mat3<T>& a, const Mat3<T>& b) {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
  return r;
}

template <typename T>
constexpr Mat3<T> Transpose(const Mat3<T>& a) {
  return Mat3<T>::FromRows(a.Col(0), a.Col(1), a.Col(2));
}

template <typename T>
constexpr T Determinant(const Mat3<T>& a) {
  return Dot(a.Row(0), Cross(a.Row(1), a.Row(2)));
}

// Inverse of a; the caller ensures Determinant(a) is not zero.
template <typename T>
constexpr Mat3<T> Inverse(const Mat3<T>& a) {
  const Vec3<T> c0 = Cross(a.Row(1), a.Row(2));
  const Vec3<T> c1 = Cross(a.Row(2), a.Row(0));
  const Vec3<T> c2 = Cross(a.Row(0), a.Row(1));
  const T inv = T(1) / Dot(a.Row(0), c0);
  return Transpose(Mat3<T>::FromRows(c0 * inv, c1 * inv, c2 * inv));
}

template <typename T>
std::ostream& operator<<(std::ostream& os, const Mat3<T>& a) {
  return os << "[" << a.Row(0) << ", " << a.Row(1) << ", " << a.Row(2) << "]";
}

}  // namespace probebake
