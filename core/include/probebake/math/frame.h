// An orthonormal frame around a unit vector, for turning local sample directions (z up) into
// world directions. Built with the branchless construction of Duff et al. 2017, "Building an
// Orthonormal Basis, Revisited" (JCGT 6(1)), continuous except at n.z = -1 exactly.
#pragma once

#include <cmath>

#include "probebake/math/vec3.h"

namespace probebake {

template <typename T>
struct Frame {
  Vec3<T> s, t, n;  // right-handed: s x t = n

  // n must be unit length.
  static Frame FromZ(const Vec3<T>& n) {
    const T sign = std::copysign(T(1), n.z);
    const T a = T(-1) / (sign + n.z);
    const T b = n.x * n.y * a;
    return {{T(1) + sign * n.x * n.x * a, sign * b, -sign * n.x}, {b, sign + n.y * n.y * a, -n.y}, n};
  }
  Vec3<T> ToLocal(const Vec3<T>& v) const { return {Dot(v, s), Dot(v, t), Dot(v, n)}; }
  Vec3<T> FromLocal(const Vec3<T>& v) const { return s * v.x + t * v.y + n * v.z; }
};

using Framed = Frame<double>;

}  // namespace probebake
