#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "probebake/math/frame.h"
#include "probebake/math/mat3.h"
#include "probebake/math/vec3.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

// Rounding bound for a few double operations on unit-scale values.
constexpr double kEps = 8 * 2.220446049250313e-16;

TEST(Frame, OrthonormalAndRightHandedEverywhere) {
  // Directions over the sphere, including the poles and the branch switch at z = 0.
  const Vec3d dirs[] = {{0, 0, 1},     {0, 0, -1},      {1, 0, 0},     {0, 1, 0},
                        {0.6, 0, 0.8}, {0, -0.6, -0.8}, {1, 1e-30, 0}, {0.48, 0.6, 0.64}};
  for (Vec3d n : dirs) {
    n = Normalize(n);
    const Framed f = Framed::FromZ(n);
    EXPECT_NEAR(Length(f.s), 1.0, kEps) << n;
    EXPECT_NEAR(Length(f.t), 1.0, kEps) << n;
    EXPECT_NEAR(Dot(f.s, f.t), 0.0, kEps) << n;
    EXPECT_NEAR(Dot(f.s, f.n), 0.0, kEps) << n;
    const Vec3d c = Cross(f.s, f.t);
    EXPECT_NEAR(Length(c - n), 0.0, kEps) << n;
    const Vec3d v{0.3, -0.4, 0.5};
    EXPECT_NEAR(Length(f.FromLocal(f.ToLocal(v)) - v), 0.0, kEps) << n;
  }
}

// The tracer does not normalize a continuation direction again (ProbeIntegrator::ShadeSurface):
// a frame around a unit normal maps the unit local directions of SampleCosineHemisphere to unit
// directions, within the rounding of a few operations, for normals all over the sphere.
TEST(Frame, FromLocalKeepsUnitVectorsUnit) {
  double worst = 0;
  for (int i = 0; i < 64; ++i) {
    for (int j = 0; j < 64; ++j) {
      // Normals on a latitude-longitude grid, the poles and the seam at z = 0 included.
      const double z = -1 + 2 * i / 63.0, phi = 0.1 + 6.2 * j / 63.0;
      const double r = std::sqrt(std::max(0.0, 1 - z * z));
      const Vec3d n = Normalize(Vec3d{r * std::cos(phi), r * std::sin(phi), z});
      const Framed f = Framed::FromZ(n);
      for (int k = 0; k < 16; ++k) {
        const Vec3d local = SampleCosineHemisphere({(k + 0.5) / 16, std::fmod(0.37 * k, 1.0)});
        worst = std::max(worst, std::fabs(Length(f.FromLocal(local)) - 1));
      }
    }
  }
  EXPECT_LE(worst, kEps);
}

TEST(Mat3, RotationIsProperOrthogonalAndCounterClockwise) {
  const Mat3d r = Mat3d::Rotation({0, 0, 1}, std::acos(-1.0) / 2);
  // Counter-clockwise seen from +z: x goes to y.
  EXPECT_NEAR(Length(r * Vec3d{1, 0, 0} - Vec3d{0, 1, 0}), 0.0, kEps);
  EXPECT_NEAR(Determinant(r), 1.0, kEps);
  const Mat3d a = Mat3d::Rotation(Normalize(Vec3d{1, 2, 3}), 0.7);
  const Mat3d i = a * Inverse(a);
  for (int r0 = 0; r0 < 3; ++r0)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(i(r0, c), r0 == c ? 1.0 : 0.0, kEps);
  const Mat3d t = Transpose(a) * a;
  for (int r0 = 0; r0 < 3; ++r0)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(t(r0, c), r0 == c ? 1.0 : 0.0, kEps);
}

}  // namespace
}  // namespace probebake
