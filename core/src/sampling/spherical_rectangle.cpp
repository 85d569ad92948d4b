#include "probebake/sampling/spherical_rectangle.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

constexpr double kPi = std::numbers::pi;

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

// Quantities of the spherical quad over [x0, x1] x [y0, y1]: the edge-plane normals n0..n3
// (cross products of consecutive corner directions), the interior angles g_i = acos(-n_i.n_{i+1}),
// k = 2 pi - g2 - g3 and the solid angle g0 + g1 - k.
struct Quad {
  double b0, b1, k, solidAngle;
};

Quad MakeQuad(double x0, double x1, double y0, double y1, double z0) {
  const auto normalize = [](Vec3d v) { return v / Length(v); };
  const Vec3d n0 = normalize({0, z0, -y0});
  const Vec3d n1 = normalize({-z0, 0, x1});
  const Vec3d n2 = normalize({0, -z0, y1});
  const Vec3d n3 = normalize({z0, 0, -x0});
  const auto angle = [](const Vec3d& a, const Vec3d& b) {
    return std::acos(std::clamp(-Dot(a, b), -1.0, 1.0));
  };
  const double g0 = angle(n0, n1), g1 = angle(n1, n2), g2 = angle(n2, n3), g3 = angle(n3, n0);
  Quad q;
  q.b0 = n0.z;
  q.b1 = n2.z;
  q.k = 2 * kPi - g2 - g3;
  q.solidAngle = g0 + g1 - q.k;
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
  const double au = u.x * q.solidAngle + q.k;
  const double fu = (std::cos(au) * q.b0 - q.b1) / std::sin(au);
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
