#include "probebake/sampling/spherical_rectangle.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

// The rectangle in the local frame of Urena et al.: x along ex, y along ey, z the normal turned
// away from o, origin at o, so the rectangle is [x0, x1] x [y0, y1] at height z0 < 0.
struct Setup {
  Vec3d x, y, z;
  double x0, x1, y0, y1, z0;
};

Setup MakeSetup(const Vec3d& o, const Vec3d& s, const Vec3d& ex, const Vec3d& ey) {
  Setup r;
  const double exLength = Length(ex), eyLength = Length(ey);
  r.x = ex / exLength;
  r.y = ey / eyLength;
  r.z = Cross(r.x, r.y);
  const Vec3d d = s - o;
  r.x0 = Dot(d, r.x);
  r.y0 = Dot(d, r.y);
  r.z0 = Dot(d, r.z);
  if (r.z0 > 0) {
    r.z = -r.z;
    r.z0 = -r.z0;
  }
  r.x1 = r.x0 + exLength;
  r.y1 = r.y0 + eyLength;
  return r;
}

// Quantities of the spherical quad over [x0, x1] x [y0, y1] at height z0 < 0 that Urena et al.'s
// sampling needs, with one atan2 in place of four acos. Their edge-plane normals n0..n3 (cross
// products of consecutive corner directions) meet at interior angles g_i, cos g_i = -n_i.n_{i+1},
// whose sine is the length of n_i x n_{i+1}: both are ratios of the corners' coordinates and
// distances. The sampling uses b0 = n0.z, b1 = n2.z and k = 2 pi - g2 - g3 through cos k and sin k
// only. The solid angle is the two triangles' of Van Oosterom and Strackee, tan(omega_t / 2) =
// |a.(b x c)| / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|), summed as one angle: a sum of
// positive terms wherever the rectangle looks small, so the solid angle keeps a relative error of a
// few eps however small it is (the sum of four angles minus 2 pi it replaces kept an absolute one,
// and cost four acos).
struct Quad {
  double b0, b1, cosK, sinK, solidAngle;
};

Quad MakeQuad(double x0In, double x1In, double y0In, double y1In, double z0In) {
  // Every quantity is scale-free: work at unit scale, so that products of six lengths neither
  // overflow nor underflow.
  const double scale = 1 / std::max({std::abs(x0In), std::abs(x1In), std::abs(y0In), std::abs(y1In),
                                     std::abs(z0In)});
  const double x0 = x0In * scale, x1 = x1In * scale, y0 = y0In * scale, y1 = y1In * scale,
               z0 = z0In * scale;
  const double zz = z0 * z0;
  // Edge-plane normals' lengths before normalisation: n0 = (0, z0, -y0), n1 = (-z0, 0, x1),
  // n2 = (0, -z0, y1), n3 = (z0, 0, -x0).
  const double l0 = std::sqrt(zz + y0 * y0), l2 = std::sqrt(zz + y1 * y1);
  const double l3 = std::sqrt(zz + x0 * x0);
  // Corner distances.
  const double d00 = std::sqrt(x0 * x0 + y0 * y0 + zz), d10 = std::sqrt(x1 * x1 + y0 * y0 + zz);
  const double d11 = std::sqrt(x1 * x1 + y1 * y1 + zz), d01 = std::sqrt(x0 * x0 + y1 * y1 + zz);
  Quad q;
  q.b0 = -y0 / l0;
  q.b1 = y1 / l2;
  // g2 at the corner (x0, y1), between n2 and n3; g3 at (x0, y0), between n3 and n0.
  const double r2 = 1 / (l2 * l3), r3 = 1 / (l3 * l0);
  const double c2 = x0 * y1 * r2, s2 = -z0 * d01 * r2;
  const double c3 = -x0 * y0 * r3, s3 = -z0 * d00 * r3;
  q.cosK = c2 * c3 - s2 * s3;     // cos(g2 + g3)
  q.sinK = -(s2 * c3 + c2 * s3);  // -sin(g2 + g3)
  // Triangles (00, 10, 11) and (00, 11, 01): the same triple product, |z0| times the area.
  const double num = -z0 * (x1 - x0) * (y1 - y0);
  // Corner-corner dot products (their z parts are all z0^2).
  const double dot0010 = x0 * x1 + y0 * y0 + zz, dot0011 = x0 * x1 + y0 * y1 + zz;
  const double dot1011 = x1 * x1 + y0 * y1 + zz, dot0001 = x0 * x0 + y0 * y1 + zz;
  const double dot1101 = x1 * x0 + y1 * y1 + zz;
  const double den1 = d00 * d10 * d11 + dot0010 * d11 + dot0011 * d10 + dot1011 * d00;
  const double den2 = d00 * d11 * d01 + dot0011 * d01 + dot0001 * d11 + dot1101 * d00;
  // (den1 + i num)(den2 + i num) has the argument omega / 2, in [0, pi).
  q.solidAngle = 2 * std::atan2(std::max(0.0, num * (den1 + den2)), den1 * den2 - num * num);
  return q;
}

bool Degenerate(const Setup& r, const Quad& q) {
  return !(r.z0 < 0) || !(q.solidAngle > 0) || !std::isfinite(q.solidAngle);
}

}  // namespace

SphericalRectangleSample SampleSphericalRectangle(Vec2d u, const Vec3d& o, const Vec3d& s,
                                                  const Vec3d& ex, const Vec3d& ey) {
  const Setup r = MakeSetup(o, s, ex, ey);
  const Quad q = MakeQuad(r.x0, r.x1, r.y0, r.y1, r.z0);
  if (Degenerate(r, q)) return {s, 0};
  // x: invert the solid angle swept from x0 (Urena et al. eq. 6-8).
  // au = u.x * solidAngle + k, by the angle-sum formulas.
  const double cosUs = std::cos(u.x * q.solidAngle), sinUs = std::sin(u.x * q.solidAngle);
  const double cosAu = cosUs * q.cosK - sinUs * q.sinK, sinAu = sinUs * q.cosK + cosUs * q.sinK;
  const double fu = (cosAu * q.b0 - q.b1) / sinAu;
  const double cu =
      std::clamp(std::copysign(1.0, fu) / std::sqrt(fu * fu + q.b0 * q.b0), -1.0, 1.0);
  const double xu = std::clamp(-(cu * r.z0) / std::sqrt(std::max(0.0, 1 - cu * cu)), r.x0, r.x1);
  // y: uniform in h = sin(elevation) along the chosen column (eq. 10-11).
  const double dd = std::sqrt(xu * xu + r.z0 * r.z0);
  const double h0 = r.y0 / std::sqrt(dd * dd + r.y0 * r.y0);
  const double h1 = r.y1 / std::sqrt(dd * dd + r.y1 * r.y1);
  const double hv = h0 + u.y * (h1 - h0);
  const double hv2 = hv * hv;
  const double yv = hv2 < 1 ? std::clamp(hv * dd / std::sqrt(1 - hv2), r.y0, r.y1) : r.y1;
  return {o + r.x * xu + r.y * yv + r.z * r.z0, 1 / q.solidAngle};
}

double SphericalRectangleSolidAngle(const Vec3d& o, const Vec3d& s, const Vec3d& ex,
                                    const Vec3d& ey) {
  const Setup r = MakeSetup(o, s, ex, ey);
  const Quad q = MakeQuad(r.x0, r.x1, r.y0, r.y1, r.z0);
  return Degenerate(r, q) ? 0 : q.solidAngle;
}

double SphericalRectanglePdf(const Vec3d& o, const Vec3d& s, const Vec3d& ex, const Vec3d& ey) {
  const double solidAngle = SphericalRectangleSolidAngle(o, s, ex, ey);
  return solidAngle > 0 ? 1 / solidAngle : 0;
}

Vec2d InvertSphericalRectangleSample(const Vec3d& p, const Vec3d& o, const Vec3d& s,
                                     const Vec3d& ex, const Vec3d& ey) {
  const Setup r = MakeSetup(o, s, ex, ey);
  const Quad q = MakeQuad(r.x0, r.x1, r.y0, r.y1, r.z0);
  if (Degenerate(r, q)) return {0, 0};
  const Vec3d d = p - o;
  const double xu = std::clamp(Dot(d, r.x), r.x0, r.x1);
  const double yv = std::clamp(Dot(d, r.y), r.y0, r.y1);
  // u.x is the fraction of the solid angle lying in the sub-rectangle [x0, xu].
  const double ux = xu > r.x0 ? MakeQuad(r.x0, xu, r.y0, r.y1, r.z0).solidAngle / q.solidAngle : 0;
  const double dd = std::sqrt(xu * xu + r.z0 * r.z0);
  const double h0 = r.y0 / std::sqrt(dd * dd + r.y0 * r.y0);
  const double h1 = r.y1 / std::sqrt(dd * dd + r.y1 * r.y1);
  const double hv = yv / std::sqrt(dd * dd + yv * yv);
  return {std::clamp(ux, 0.0, kOneMinusEpsilon),
          std::clamp((hv - h0) / (h1 - h0), 0.0, kOneMinusEpsilon)};
}

}  // namespace probebake
