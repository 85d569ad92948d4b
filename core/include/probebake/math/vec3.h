// Small fixed-size vectors. Vec3<T> is a point, a direction or an RGB triple depending on context
// (names say which); Vec2<T> holds 2D sample points u in [0,1)^2. Plain aggregates, no SIMD.
#pragma once

#include <algorithm>
#include <cmath>
#include <ostream>

namespace probebake {

template <typename T>
struct Vec2 {
  T x = 0, y = 0;

  constexpr T operator[](int i) const { return i == 0 ? x : y; }
  constexpr T& operator[](int i) { return i == 0 ? x : y; }
  friend constexpr bool operator==(const Vec2&, const Vec2&) = default;
};

template <typename T>
struct Vec3 {
  T x = 0, y = 0, z = 0;

  constexpr Vec3() = default;
  constexpr Vec3(T x_, T y_, T z_) : x(x_), y(y_), z(z_) {}
  template <typename U>
  constexpr explicit Vec3(const Vec3<U>& v) : x(T(v.x)), y(T(v.y)), z(T(v.z)) {}

  constexpr T operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  constexpr T& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }

  constexpr Vec3 operator-() const { return {-x, -y, -z}; }
  constexpr Vec3& operator+=(const Vec3& b) {
    x += b.x;
    y += b.y;
    z += b.z;
    return *this;
  }
  constexpr Vec3& operator-=(const Vec3& b) {
    x -= b.x;
    y -= b.y;
    z -= b.z;
    return *this;
  }
  constexpr Vec3& operator*=(T s) {
    x *= s;
    y *= s;
    z *= s;
    return *this;
  }
  constexpr Vec3& operator*=(const Vec3& b) {
    x *= b.x;
    y *= b.y;
    z *= b.z;
    return *this;
  }
  constexpr Vec3& operator/=(T s) {
    x /= s;
    y /= s;
    z /= s;
    return *this;
  }

  friend constexpr bool operator==(const Vec3&, const Vec3&) = default;
};

using Vec2d = Vec2<double>;
using Vec2f = Vec2<float>;
using Vec3d = Vec3<double>;
using Vec3f = Vec3<float>;

template <typename T>
constexpr Vec3<T> operator+(Vec3<T> a, const Vec3<T>& b) {
  return a += b;
}
template <typename T>
constexpr Vec3<T> operator-(Vec3<T> a, const Vec3<T>& b) {
  return a -= b;
}
// Component-wise product (RGB modulation).
template <typename T>
constexpr Vec3<T> operator*(Vec3<T> a, const Vec3<T>& b) {
  return a *= b;
}
template <typename T>
constexpr Vec3<T> operator*(Vec3<T> a, T s) {
  return a *= s;
}
template <typename T>
constexpr Vec3<T> operator*(T s, Vec3<T> a) {
  return a *= s;
}
template <typename T>
constexpr Vec3<T> operator/(Vec3<T> a, T s) {
  return a /= s;
}

template <typename T>
constexpr T Dot(const Vec3<T>& a, const Vec3<T>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
// The angle between unit vectors a and b, in [0, pi] (their dot product clamped against rounding).
template <typename T>
T AngleBetween(const Vec3<T>& a, const Vec3<T>& b) {
  return std::acos(std::clamp(Dot(a, b), T(-1), T(1)));
}
template <typename T>
constexpr Vec3<T> Cross(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <typename T>
constexpr T LengthSquared(const Vec3<T>& a) {
  return Dot(a, a);
}
template <typename T>
T Length(const Vec3<T>& a) {
  return std::sqrt(Dot(a, a));
}
// Unit vector along a; a must be non-zero and finite. One division, then products (hot in the
// tracer): within 2 ulp of dividing each component.
template <typename T>
Vec3<T> Normalize(const Vec3<T>& a) {
  const T inv = T(1) / Length(a);
  return {a.x * inv, a.y * inv, a.z * inv};
}
template <typename T>
constexpr Vec3<T> Min(const Vec3<T>& a, const Vec3<T>& b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
template <typename T>
constexpr Vec3<T> Max(const Vec3<T>& a, const Vec3<T>& b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
template <typename T>
constexpr T MaxComponent(const Vec3<T>& a) {
  return std::max(a.x, std::max(a.y, a.z));
}
template <typename T>
constexpr Vec3<T> Abs(const Vec3<T>& a) {
  return {std::abs(a.x), std::abs(a.y), std::abs(a.z)};
}
template <typename T>
bool IsFinite(const Vec3<T>& a) {
  return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}
// Rec.709 luminance of a linear RGB triple.
template <typename T>
constexpr T Luminance(const Vec3<T>& rgb) {
  return T(0.2126) * rgb.x + T(0.7152) * rgb.y + T(0.0722) * rgb.z;
}

template <typename T>
std::ostream& operator<<(std::ostream& os, const Vec3<T>& v) {
  return os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
}
template <typename T>
std::ostream& operator<<(std::ostream& os, const Vec2<T>& v) {
  return os << "(" << v.x << ", " << v.y << ")";
}

}  // namespace probebake
