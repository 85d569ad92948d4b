// Warps from the unit square to directions and shapes, in threes (pbrt-v4 util/sampling.h names):
// SampleX(u, ...) maps u in [0,1)^n to a sample, XPdf(...) is its density, InvertXSample(...)
// maps a sample back to u (InvertX(SampleX(u)) == u up to rounding, where the map is one-to-one).
// No RNG state; u is always explicit and must lie in [0, 1).
//
// Units of the pdfs:
//   directions (sphere, hemisphere, cosine hemisphere, cone, Henyey-Greenstein): per steradian;
//   unit disk: per unit area of the unit disk (1/pi);
//   triangle, parallelogram: per unit area in the units of the given vertices.
// Local frames: hemispheres are around +z, cones around +z; rotate with Frame (math/frame.h).
//
// Henyey-Greenstein convention: theta is the angle between the propagation direction of the
// incoming light and the propagation direction of the scattered light, so cos theta =
// Dot(dIn, dOut) and g > 0 scatters forward (cos theta near 1), g < 0 backward, g = 0 is isotropic.
// In a tracer that stores wo (toward the previous vertex, = dOut) and wi (toward the light, =
// -dIn), cos theta = -Dot(wi, wo); in the local frame of SampleHenyeyGreenstein, +z is dIn.
//
// References:
//   P. Shirley, K. Chiu, "A Low Distortion Map Between Disk and Square", JGT 2(3), 1997.
//   E. Heitz, "A Low-Distortion Map Between Triangle and Square", 2019.
//   L. G. Henyey, J. L. Greenstein, "Diffuse radiation in the Galaxy", ApJ 93, 1941.
//   M. Pharr, W. Jakob, G. Humphreys, "Physically Based Rendering", 4th ed. (pbrt-v4), 2023.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "probebake/math/sincos_turns.h"
#include "probebake/math/vec3.h"

namespace probebake {

// Largest double below 1: the upper clamp for remapped or inverted u.
inline constexpr double kOneMinusEpsilon = 0x1.fffffffffffffp-1;

namespace detail {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kInv2Pi = 1 / (2 * std::numbers::pi);
inline constexpr double kInv4Pi = 1 / (4 * std::numbers::pi);

// Unit vector with z = cosTheta and azimuth phi = 2 pi phiTurns. sin theta comes from
// (1 - cos)(1 + cos), each factor free of cancellation near its pole, so tiny polar angles keep
// their relative precision.
inline Vec3d DirectionFromCosTheta(double cosTheta, double phiTurns) {
  const double sinTheta = std::sqrt(std::max(0.0, (1 - cosTheta) * (1 + cosTheta)));
  const SinCos phi = SinCosTurns(phiTurns);
  return {sinTheta * phi.cos, sinTheta * phi.sin, cosTheta};
}

// Azimuth of w as a fraction of a turn, in [0, 1). Undefined (returns 0) on the z axis.
inline double AzimuthFraction(const Vec3d& w) {
  double f = std::atan2(w.y, w.x) * kInv2Pi;  // (-1/2, 1/2]
  if (f < 0) f += 1;                          // may round to 1 for tiny negative f
  return std::min(f, kOneMinusEpsilon);
}

inline double ClampUnit(double u) {
  return std::clamp(u, 0.0, kOneMinusEpsilon);
}

}  // namespace detail

// ---- Uniform sphere: z = 1 - 2 u.x (u.x = 0 is the +z pole), phi = 2 pi u.y.
inline Vec3d SampleUniformSphere(Vec2d u) {
  return detail::DirectionFromCosTheta(1 - 2 * u.x, u.y);
}
inline constexpr double UniformSpherePdf() {
  return detail::kInv4Pi;
}
// w must be unit length.
inline Vec2d InvertUniformSphereSample(const Vec3d& w) {
  return {detail::ClampUnit((1 - w.z) / 2), detail::AzimuthFraction(w)};
}

// ---- Uniform hemisphere around +z: z = u.x, phi = 2 pi u.y.
inline Vec3d SampleUniformHemisphere(Vec2d u) {
  return detail::DirectionFromCosTheta(u.x, u.y);
}
inline constexpr double UniformHemispherePdf() {
  return detail::kInv2Pi;
}
// w must be unit length with w.z >= 0.
inline Vec2d InvertUniformHemisphereSample(const Vec3d& w) {
  return {detail::ClampUnit(w.z), detail::AzimuthFraction(w)};
}

// ---- Concentric map of the square onto the unit disk (Shirley-Chiu): area-preserving up to a
// constant, continuous, maps the square's concentric squares to concentric circles.
inline Vec2d SampleUniformDiskConcentric(Vec2d u) {
  const double ox = 2 * u.x - 1, oy = 2 * u.y - 1;
  if (ox == 0 && oy == 0) return {0, 0};
  // Angle theta in turns: (pi/4) (oy/ox) = (oy/ox)/8 turns, pi/2 - (pi/4)(ox/oy) = 1/4 - (ox/oy)/8.
  double r, thetaTurns;
  if (std::abs(ox) > std::abs(oy)) {
    r = ox;
    thetaTurns = (oy / ox) * 0.125;
  } else {
    r = oy;
    thetaTurns = 0.25 - (ox / oy) * 0.125;
  }
  const SinCos theta = SinCosTurns(thetaTurns);
  return {r * theta.cos, r * theta.sin};
}
inline constexpr double UniformDiskPdf() {
  return 1 / detail::kPi;
}
// p must lie in the closed unit disk.
inline Vec2d InvertUniformDiskConcentricSample(Vec2d p) {
  if (p.x == 0 && p.y == 0) return {0.5, 0.5};
  const double len = std::sqrt(p.x * p.x + p.y * p.y);
  double ox, oy;
  if (std::abs(p.x) >= std::abs(p.y)) {
    // Forward branch |ox| > |oy|: p = ox (cos t, sin t), t = (pi/4) oy/ox in [-pi/4, pi/4].
    ox = std::copysign(len, p.x);
    oy = ox * std::atan(p.y / p.x) * (4 / detail::kPi);
  } else {
    // Forward branch |oy| >= |ox|: p = oy (cos t, sin t), pi/2 - t = (pi/4) ox/oy.
    oy = std::copysign(len, p.y);
    ox = oy * std::atan(p.x / p.y) * (4 / detail::kPi);
  }
  return {detail::ClampUnit((ox + 1) / 2), detail::ClampUnit((oy + 1) / 2)};
}

// ---- Cosine-weighted hemisphere around +z (Malley: lift the concentric disk), pdf cos(theta)/pi.
inline Vec3d SampleCosineHemisphere(Vec2d u) {
  const Vec2d d = SampleUniformDiskConcentric(u);
  return {d.x, d.y, std::sqrt(std::max(0.0, 1 - d.x * d.x - d.y * d.y))};
}
// Zero below the horizon (cosTheta < 0).
inline double CosineHemispherePdf(double cosTheta) {
  return std::max(cosTheta, 0.0) * (1 / detail::kPi);
}
// w must be unit length with w.z >= 0.
inline Vec2d InvertCosineHemisphereSample(const Vec3d& w) {
  return InvertUniformDiskConcentricSample({w.x, w.y});
}

// ---- Uniform cone (spherical cap) around +z with half-angle thetaMax, given cosThetaMax in
// [-1, 1). 1 - cos(theta) = u.x (1 - cosThetaMax) and sin^2 = t (2 - t) with t = 1 - cos(theta),
// so no step cancels: for a cap as small as the sun's (0.27 deg, 1 - cosThetaMax ~ 1e-5) the
// subtraction 1 - cosThetaMax is exact (Sterbenz) and the only error left is the caller's
// rounding of cosThetaMax (relative 1e-16 / 1e-5 = 1e-11 on the cap's solid angle in double).
// The same cap given by oneMinusCosThetaMax = 1 - cosThetaMax in (0, 2], for caps so small that
// cosThetaMax rounds to 1 (a sphere light of radius r at distance d: 1 - cos ~ r^2 / 2d^2, below
// ulp(1) from r / d ~ 1e-8).
inline Vec3d SampleUniformConeFromOneMinusCos(Vec2d u, double oneMinusCosThetaMax) {
  const double t = u.x * oneMinusCosThetaMax;
  const double sinTheta = std::sqrt(std::max(0.0, t * (2 - t)));
  const SinCos phi = SinCosTurns(u.y);
  return {sinTheta * phi.cos, sinTheta * phi.sin, 1 - t};
}
inline double UniformConePdfFromOneMinusCos(double oneMinusCosThetaMax) {
  return detail::kInv2Pi / oneMinusCosThetaMax;
}
inline Vec3d SampleUniformCone(Vec2d u, double cosThetaMax) {
  return SampleUniformConeFromOneMinusCos(u, 1 - cosThetaMax);
}
// Density inside the cap (the caller tests membership: cos(theta) >= cosThetaMax).
inline double UniformConePdf(double cosThetaMax) {
  return UniformConePdfFromOneMinusCos(1 - cosThetaMax);
}
// w must be unit length and inside the cap.
inline Vec2d InvertUniformConeSample(const Vec3d& w, double cosThetaMax) {
  // 1 - z without cancellation near the pole: (x^2 + y^2) / (1 + z) for z > 0.
  const double t = w.z > 0 ? (w.x * w.x + w.y * w.y) / (1 + w.z) : 1 - w.z;
  return {detail::ClampUnit(t / (1 - cosThetaMax)), detail::AzimuthFraction(w)};
}

// ---- Uniform triangle: area-uniform barycentrics (b0, b1, b2), b0 + b1 + b2 = 1, by Heitz's
// low-distortion map (the square's two halves are mapped linearly onto the triangle's halves).
// The point is b0 p0 + b1 p1 + b2 p2.
inline std::array<double, 3> SampleUniformTriangle(Vec2d u) {
  double b0, b1;
  if (u.x < u.y) {
    b0 = u.x / 2;
    b1 = u.y - b0;
  } else {
    b1 = u.y / 2;
    b0 = u.x - b1;
  }
  return {b0, b1, 1 - b0 - b1};
}
// 1 / area; per unit area in the vertices' units. Precondition: non-degenerate triangle.
inline double UniformTrianglePdf(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2) {
  return 2 / Length(Cross(p1 - p0, p2 - p0));
}
// b: barycentrics of a point inside the triangle.
inline Vec2d InvertUniformTriangleSample(const std::array<double, 3>& b) {
  if (b[0] > b[1]) return {detail::ClampUnit(b[0] + b[1]), detail::ClampUnit(2 * b[1])};
  return {detail::ClampUnit(2 * b[0]), detail::ClampUnit(b[1] + b[0])};
}

// ---- Uniform parallelogram p0 + s e1 + t e2, (s, t) = u (a rectangle when e1 is orthogonal to
// e2).
inline Vec3d SampleUniformParallelogram(Vec2d u, const Vec3d& p0, const Vec3d& e1,
                                        const Vec3d& e2) {
  return p0 + e1 * u.x + e2 * u.y;
}
// 1 / area; per unit area. Precondition: e1, e2 not parallel.
inline double UniformParallelogramPdf(const Vec3d& e1, const Vec3d& e2) {
  return 1 / Length(Cross(e1, e2));
}
// p must lie on the parallelogram (its component off the plane is ignored: least squares).
inline Vec2d InvertUniformParallelogramSample(const Vec3d& p, const Vec3d& p0, const Vec3d& e1,
                                              const Vec3d& e2) {
  const Vec3d d = p - p0;
  const double a11 = Dot(e1, e1), a12 = Dot(e1, e2), a22 = Dot(e2, e2);
  const double r1 = Dot(e1, d), r2 = Dot(e2, d);
  const double det = a11 * a22 - a12 * a12;
  return {detail::ClampUnit((r1 * a22 - r2 * a12) / det),
          detail::ClampUnit((r2 * a11 - r1 * a12) / det)};
}

// ---- Henyey-Greenstein phase function, g in [-0.999, 0.999] (stable there; |g| < 1 required).
// p(cos theta) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos theta)^{3/2}) per steradian; see the
// direction convention above. At g = 0 every function below reduces exactly (bit for bit) to the
// uniform sphere: pdf 1/(4 pi), cos theta = 1 - 2u.
inline double HenyeyGreensteinPdf(double cosTheta, double g) {
  // 1 + g^2 - 2 g cos as a sum of non-negative terms: no cancellation at the lobe's peak.
  const double denom = g >= 0 ? (1 - g) * (1 - g) + 2 * g * (1 - cosTheta)
                              : (1 + g) * (1 + g) - 2 * g * (1 + cosTheta);
  return detail::kInv4Pi * (1 - g) * (1 + g) / (denom * std::sqrt(denom));
}

// cos theta for u in [0, 1): the inverse of P(cos > c) = u, so u = 0 gives cos = 1 (as the uniform
// sphere's z = 1 - 2u does) and u -> 1 gives cos -> -1.
inline double SampleHenyeyGreensteinCos(double u, double g) {
  const double a = 1 - 2 * u;  // the isotropic answer
  double cosTheta;
  if (std::abs(g) < 0.25) {
    // (1 + g^2 - s^2) / (2g) with s = (1 - g^2)/(1 + g a), expanded so the 1/g cancels
    // analytically: cos = [a + g (a^2+3)/2 + g^2 a + g^3 (a^2-1)/2] / (1 + g a)^2. Exact at g = 0;
    // absolute error a few ulps for |g| < 1/4 (terms O(1), denominator >= 9/16).
    const double d = 1 + g * a;
    cosTheta = (a + g * ((a * a + 3) / 2 + g * (a + g * (a * a - 1) / 2))) / (d * d);
  } else {
    // Textbook inversion of the CDF; absolute error ~3 eps/|g| <= 12 eps here.
    const double s = (1 - g) * (1 + g) / (1 + g * a);
    cosTheta = (1 + g * g - s * s) / (2 * g);
  }
  return std::clamp(cosTheta, -1.0, 1.0);
}

// u with SampleHenyeyGreensteinCos(u, g) == cosTheta: u = P(cos > cosTheta)
//   = (1 + g)(1 - cos) / (q (1 - g + q)),  q = sqrt(1 + g^2 - 2 g cos),  free of 1/g.
inline double InvertHenyeyGreensteinCosSample(double cosTheta, double g) {
  const double denom = g >= 0 ? (1 - g) * (1 - g) + 2 * g * (1 - cosTheta)
                              : (1 + g) * (1 + g) - 2 * g * (1 + cosTheta);
  const double q = std::sqrt(denom);
  return detail::ClampUnit((1 + g) * (1 - cosTheta) / (q * (1 - g + q)));
}

// Scattered propagation direction in the frame whose +z is the incoming propagation direction.
inline Vec3d SampleHenyeyGreenstein(Vec2d u, double g) {
  return detail::DirectionFromCosTheta(SampleHenyeyGreensteinCos(u.x, g), u.y);
}
// w: unit direction in the same local frame.
inline Vec2d InvertHenyeyGreensteinSample(const Vec3d& w, double g) {
  return {InvertHenyeyGreensteinCosSample(w.z, g), detail::AzimuthFraction(w)};
}

}  // namespace probebake
