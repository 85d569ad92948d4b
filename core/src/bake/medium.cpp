#include "medium.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace probebake {
namespace {

Vec3d Exp(const Vec3d& v) {
  return {std::exp(v.x), std::exp(v.y), std::exp(v.z)};
}
double Mean(const Vec3d& v) {
  return (v.x + v.y + v.z) / 3;
}

}  // namespace

HomogeneousMedium::HomogeneousMedium(const Medium& medium, const Vec3d& offset)
    : sigmaT_(medium.sigmaA + medium.sigmaS),
      sigmaS_(medium.sigmaS),
      g_(medium.g),
      lo_(medium.boundsMin - offset),
      hi_(medium.boundsMax - offset) {}

bool HomogeneousMedium::Overlap(const Vec3d& o, const Vec3d& dir, double tMax, double* t0,
                                double* t1) const {
  double enter = 0, exit = tMax;
  for (int a = 0; a < 3; ++a) {
    if (dir[a] == 0) {
      if (o[a] < lo_[a] || o[a] > hi_[a]) return false;
      continue;
    }
    const double inv = 1 / dir[a];
    double tNear = (lo_[a] - o[a]) * inv, tFar = (hi_[a] - o[a]) * inv;
    if (tNear > tFar) std::swap(tNear, tFar);
    enter = std::max(enter, tNear);
    exit = std::min(exit, tFar);
    if (enter >= exit) return false;
  }
  *t0 = enter;
  *t1 = exit;
  return true;
}

MediumSample HomogeneousMedium::Sample(const Vec3d& o, const Vec3d& dir, double tMax,
                                       double uChannel, double uDistance) const {
  MediumSample s;
  double t0, t1;
  if (!Overlap(o, dir, tMax, &t0, &t1)) return s;
  const int c = std::min(int(uChannel * 3), 2);
  const double distance = sigmaT_[c] > 0 ? -std::log1p(-uDistance) / sigmaT_[c]
                                         : std::numeric_limits<double>::infinity();
  if (distance < t1 - t0) {
    const Vec3d tr = Exp(-sigmaT_ * distance);
    s.scattered = true;
    s.t = t0 + distance;
    const double pdf = Mean(sigmaT_ * tr);
    s.weight = pdf > 0 ? tr * sigmaS_ / pdf : Vec3d{};
  } else {
    const Vec3d tr = Exp(-sigmaT_ * (t1 - t0));
    const double pdf = Mean(tr);  // 0 only if every channel underflowed: nothing gets through
    s.weight = pdf > 0 ? tr / pdf : Vec3d{};
  }
  return s;
}

Vec3d HomogeneousMedium::Transmittance(const Vec3d& o, const Vec3d& dir, double tMax) const {
  double t0, t1;
  if (!Overlap(o, dir, tMax, &t0, &t1)) return {1, 1, 1};
  return Exp(-sigmaT_ * (t1 - t0));
}

}  // namespace probebake
