#include "probebake/sh/sh_unity.h"

#include <cmath>
#include <numbers>

#include "probebake/base/check.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_rotation.h"

namespace probebake {

Mat3d UnityFromProbebakeAxes() {
  return Mat3d::FromRows({1, 0, 0}, {0, 0, 1}, {0, 1, 0});
}

UnitySh9Constants PackUnitySh9(std::span<const Vec3d> radiance, UnityAxes axes) {
  PB_CHECK_GE(radiance.size(), static_cast<size_t>(ShCoeffCount(2)));
  Vec3d sh[9];
  for (int i = 0; i < 9; ++i) sh[i] = radiance[i];
  if (axes == UnityAxes::kUnityYUp) {
    // The fixed axis map is a valid orthogonal matrix: Create cannot fail.
    const absl::StatusOr<ShRotation> rot = ShRotation::Create(2, UnityFromProbebakeAxes());
    PB_CHECK(rot.ok());
    rot->ApplyRgb(sh, sh);
  }
  const double sqrtPi = std::sqrt(std::numbers::pi);
  const double fC0 = 1 / (2 * sqrtPi);
  const double fC1 = std::sqrt(3.0) / (3 * sqrtPi);
  const double fC2 = std::sqrt(15.0) / (8 * sqrtPi);
  const double fC3 = std::sqrt(5.0) / (16 * sqrtPi);
  const double fC4 = 0.5 * fC2;
  UnitySh9Constants c;
  for (int ch = 0; ch < 3; ++ch) {
    c.v[ch] = {static_cast<float>(-fC1 * sh[3][ch]), static_cast<float>(-fC1 * sh[1][ch]),
               static_cast<float>(fC1 * sh[2][ch]),
               static_cast<float>(fC0 * sh[0][ch] - fC3 * sh[6][ch])};
    c.v[3 + ch] = {static_cast<float>(fC2 * sh[4][ch]), static_cast<float>(-fC2 * sh[5][ch]),
                   static_cast<float>(3 * fC3 * sh[6][ch]), static_cast<float>(-fC2 * sh[7][ch])};
  }
  c.v[6] = {static_cast<float>(fC4 * sh[8].x), static_cast<float>(fC4 * sh[8].y),
            static_cast<float>(fC4 * sh[8].z), 1.0f};
  return c;
}

Vec3d EvalUnityShadeSh9(const UnitySh9Constants& c, const Vec3d& n) {
  const double n4[4] = {n.x, n.y, n.z, 1};
  const double vB[4] = {n.x * n.y, n.y * n.z, n.z * n.z, n.z * n.x};  // n.xyzz * n.yzzx
  const double vC = n.x * n.x - n.y * n.y;
  Vec3d out;
  for (int ch = 0; ch < 3; ++ch) {
    double a = 0, b = 0;
    for (int k = 0; k < 4; ++k) {
      a += c.v[ch][k] * n4[k];
      b += c.v[3 + ch][k] * vB[k];
    }
    out[ch] = a + b + c.v[6][ch] * vC;
  }
  return out;
}

std::ostream& operator<<(std::ostream& os, const UnitySh9Constants& c) {
  static const char* const kNames[7] = {"SHAr", "SHAg", "SHAb", "SHBr", "SHBg", "SHBb", "SHC"};
  os << "UnitySh9Constants{";
  for (int i = 0; i < 7; ++i) {
    os << (i ? ", " : "") << kNames[i] << " (" << c.v[i][0] << ", " << c.v[i][1] << ", "
       << c.v[i][2] << ", " << c.v[i][3] << ")";
  }
  return os << "}";
}

}  // namespace probebake
