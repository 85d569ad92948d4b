// Solid-angle sampling of a rectangle seen from a point (Urena, Fajardo, King 2013): directions
// uniform over the rectangle's solid angle, for next-event estimation toward rectangular area
// lights; variance does not blow up near the light as with area sampling (pdf r^2 / (A cos)).
//
// Rectangle: corner s and edge vectors ex, ey (orthogonal, non-zero lengths): the points
// s + a ex + b ey, a, b in [0, 1]. Reference point o, not in the rectangle's plane.
// Threes, as in warps.h:
//   SampleSphericalRectangle(u, o, s, ex, ey) -> point on the rectangle and pdf per steradian
//     (= 1 / solid angle) of the direction Normalize(p - o);
//   SphericalRectanglePdf(o, s, ex, ey) -> 1 / solid angle (per steradian) for any direction that
//     hits the rectangle (the caller tests that);
//   InvertSphericalRectangleSample(p, o, s, ex, ey) -> u in [0,1)^2.
// u.x sweeps the solid angle along ex, u.y the direction along ey within it.
// Degenerate input (o in the plane, solid angle not positive): pdf 0 and the corner s returned.
// Precision: the solid angle is Van Oosterom and Strackee's for the rectangle's two triangles,
// one atan2 of sums that are positive wherever the rectangle looks small, so its relative error
// is a few eps at any size (Urena et al.'s sum of four angles minus 2 pi has an absolute error of
// ~1e-15 sr: 5e-11 relative at 1e-6 sr, 2% at 1e-14 sr; pbrt-v4 switches to area sampling below
// 3e-4 sr in single precision). That atan2 replaces the four acos of Urena et al.'s form; the
// sampling map itself needs no inverse trigonometry.
//
// References:
//   C. Urena, M. Fajardo, A. King, "An Area-Preserving Parametrization for Spherical Rectangles",
//     Computer Graphics Forum 32(4) (EGSR), 2013.
//   A. van Oosterom, J. Strackee, "The Solid Angle of a Plane Triangle", IEEE Transactions on
//     Biomedical Engineering 30(2), 1983.
//   M. Pharr, W. Jakob, G. Humphreys, "Physically Based Rendering", 4th ed. (pbrt-v4), 2023.
#pragma once

#include "probebake/math/vec3.h"

namespace probebake {

struct SphericalRectangleSample {
  Vec3d p;         // point on the rectangle
  double pdf = 0;  // per steradian, 1 / solid angle; 0 for degenerate input
};

SphericalRectangleSample SampleSphericalRectangle(Vec2d u, const Vec3d& o, const Vec3d& s,
                                                  const Vec3d& ex, const Vec3d& ey);
// Solid angle (sr) of the rectangle seen from o; 0 for degenerate input.
double SphericalRectangleSolidAngle(const Vec3d& o, const Vec3d& s, const Vec3d& ex,
                                    const Vec3d& ey);
double SphericalRectanglePdf(const Vec3d& o, const Vec3d& s, const Vec3d& ex, const Vec3d& ey);
// p must lie on the rectangle (its offset from the plane is ignored).
Vec2d InvertSphericalRectangleSample(const Vec3d& p, const Vec3d& o, const Vec3d& s,
                                     const Vec3d& ex, const Vec3d& ey);

}  // namespace probebake
