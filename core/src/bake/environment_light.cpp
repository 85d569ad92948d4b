#include "environment_light.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "probebake/base/check.h"
#include "probebake/math/frame.h"
#include "probebake/math/sincos_turns.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

constexpr double kPi = std::numbers::pi;

// Continuous Imf::LatLongMap coordinates, relative to the data window origin:
//   latitude(y) = pi (1/2 - y / (h - 1)),  longitude(x) = 2 pi (1/2 - x / (w - 1)),
//   direction = (sin lon cos lat, sin lat, cos lon cos lat).
// (Checked against the library in tests/bake/environment_light_test.cpp.)
double LatitudeOf(double y, int h) {
  return h > 1 ? kPi * (0.5 - y / (h - 1)) : 0.0;
}
double LongitudeOf(double x, int w) {
  return w > 1 ? 2 * kPi * (0.5 - x / (w - 1)) : 0.0;
}

// Above this many texels Prefetch loads ahead: the sampling data per texel (CDF, guide, RGB: 24
// bytes) no longer fits in a core's L2 cache (~1.5 MiB at 256 x 256); below it, prefetching would
// only cost instructions.
constexpr size_t kPrefetchTexels = size_t{1} << 16;

}  // namespace

EnvironmentLight::EnvironmentLight(const Environment& env) : kind_(env.kind) {
  switch (env.kind) {
    case Environment::Kind::kNone:
      return;
    case Environment::Kind::kUniform:
      uniform_ = env.radiance;
      black_ = MaxComponent(uniform_) <= 0;
      importance_ = kPi * Luminance(uniform_);
      return;
    case Environment::Kind::kMap:
      break;
  }
  map_ = env.map;
  PB_CHECK(map_ != nullptr);
  PB_CHECK_GT(map_->width, 0);
  PB_CHECK_GT(map_->height, 0);
  rgb_ = map_->rgb.data();
  scale_ = map_->scale;
  width_ = map_->width;
  worldFromMap_ = map_->worldFromMap;
  mapFromWorld_ = Transpose(worldFromMap_);
  const int w = map_->width, h = map_->height;
  columnLon0_.resize(w), columnLon1_.resize(w), rowZ0_.resize(h), rowZ1_.resize(h);
  for (int ix = 0; ix < w; ++ix) {
    if (w == 1) {
      columnLon0_[ix] = -kPi, columnLon1_[ix] = kPi;
    } else {
      // Column ix covers x in [ix - 1/2, ix + 1/2] clipped to [0, w - 1]; longitude decreases
      // with x.
      const double x0 = std::max(0.0, ix - 0.5), x1 = std::min(double(w - 1), ix + 0.5);
      columnLon0_[ix] = LongitudeOf(x1, w), columnLon1_[ix] = LongitudeOf(x0, w);
    }
  }
  for (int iy = 0; iy < h; ++iy) {
    if (h == 1) {
      rowZ0_[iy] = -1, rowZ1_[iy] = 1;
    } else {
      const double y0 = std::max(0.0, iy - 0.5), y1 = std::min(double(h - 1), iy + 0.5);
      rowZ0_[iy] = std::sin(LatitudeOf(y1, h)), rowZ1_[iy] = std::sin(LatitudeOf(y0, h));
    }
  }
  std::vector<double> weights(size_t(w) * h);
  double sum = 0;
  for (int iy = 0; iy < h; ++iy) {
    for (int ix = 0; ix < w; ++ix) {
      const double solidAngle = CellSolidAngle(ix, iy);
      const size_t k = size_t(iy) * w + ix;
      const float* rgb = Texel(ix, iy);
      const double lum = scale_ * Luminance(Vec3d(rgb[0], rgb[1], rgb[2]));
      weights[k] = std::max(0.0, lum) * solidAngle;
      sum += weights[k];
    }
  }
  black_ = !(sum > 0);
  importance_ = sum / (4 * kPi) * kPi;
  if (!black_) distribution_ = std::make_unique<PiecewiseConstant2D>(weights, h, w);
  prefetch_ = !black_ && size_t(w) * h > kPrefetchTexels;
}

EnvironmentLight::Cell EnvironmentLight::CellBounds(int ix, int iy) const {
  return {columnLon0_[ix], columnLon1_[ix], rowZ0_[iy], rowZ1_[iy]};
}

EnvironmentLight::CellIndex EnvironmentLight::CellOf(const Vec3d& d) const {
  const int w = width_, h = map_->height;
  int ix = 0, iy = 0;
  if (w > 1) {
    const double lon = std::atan2(d.x, d.z);
    const double x = (0.5 - lon / (2 * kPi)) * (w - 1);
    ix = std::clamp(int(std::lround(x)), 0, w - 1);
  }
  if (h > 1) {
    const double lat = std::asin(std::clamp(d.y, -1.0, 1.0));
    const double y = (0.5 - lat / kPi) * (h - 1);
    iy = std::clamp(int(std::lround(y)), 0, h - 1);
  }
  return {ix, iy};
}

Vec3d EnvironmentLight::Radiance(const Vec3d& wi) const {
  if (black_) return {};
  if (kind_ == Environment::Kind::kUniform) return uniform_;
  const CellIndex cell = CellOf(mapFromWorld_ * wi);
  return TexelRadiance(cell.ix, cell.iy);
}

Vec3d EnvironmentLight::Sample(const Vec2d& u, const Vec3d* n, Vec3d* wi, double* pdf) const {
  *pdf = 0;
  if (black_) return {};
  if (kind_ == Environment::Kind::kUniform) {
    if (n) {
      const Vec3d local = SampleCosineHemisphere(u);
      *wi = Framed::FromZ(*n).FromLocal(local);
      *pdf = CosineHemispherePdf(local.z);
    } else {
      *wi = SampleUniformSphere(u);
      *pdf = UniformSpherePdf();
    }
    return *pdf > 0 ? uniform_ : Vec3d{};
  }
  const PiecewiseConstant2DSample s = distribution_->Sample(u);
  const int ix = int(s.col), iy = int(s.row);
  const double pmf = s.pmf;
  const Vec2d uCell = s.uRemapped;
  const Cell c = CellBounds(ix, iy);
  // Uniform in solid angle inside the cell: longitude and sin(latitude) uniform.
  const double lon = c.lon0 + uCell.x * (c.lon1 - c.lon0);
  const double z = c.z0 + uCell.y * (c.z1 - c.z0);
  const double r = std::sqrt(std::max(0.0, (1 - z) * (1 + z)));
  const SinCos sc = SinCosTurns(lon * (0.5 / kPi));
  const Vec3d mapDir{r * sc.sin, z, r * sc.cos};
  *wi = worldFromMap_ * mapDir;
  *pdf = pmf / CellSolidAngle(ix, iy);
  return TexelRadiance(ix, iy);
}

double EnvironmentLight::Pdf(const Vec3d& wi, const Vec3d* n) const {
  if (black_) return 0;
  if (kind_ == Environment::Kind::kUniform) {
    if (n) return CosineHemispherePdf(std::max(0.0, Dot(wi, *n)));
    return UniformSpherePdf();
  }
  const CellIndex cell = CellOf(mapFromWorld_ * wi);
  return distribution_->Pmf(cell.iy, cell.ix) / CellSolidAngle(cell.ix, cell.iy);
}

Vec3d EnvironmentLight::RadianceAndPdf(const Vec3d& wi, const Vec3d* n, double* pdf) const {
  *pdf = 0;
  if (black_) return {};
  if (kind_ == Environment::Kind::kUniform) {
    *pdf = Pdf(wi, n);
    return uniform_;
  }
  const CellIndex cell = CellOf(mapFromWorld_ * wi);
  *pdf = distribution_->Pmf(cell.iy, cell.ix) / CellSolidAngle(cell.ix, cell.iy);
  return TexelRadiance(cell.ix, cell.iy);
}

}  // namespace probebake
