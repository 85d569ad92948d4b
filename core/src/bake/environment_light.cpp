#include "environment_light.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "probebake/base/check.h"
#include "probebake/math/frame.h"
#include "probebake/math/sincos_turns.h"
#include "probebake/sampling/warps.h"
#include "probebake/sh/sh_basis.h"

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

// Margin of RowBelow and CellBelow, on dot products of unit vectors: far above their rounding
// (~1e-15), far below any cell's extent.
constexpr double kBelowMargin = 1e-9;

// Map-space direction of longitude lon and sin(latitude) z.
Vec3d MapDirection(double lon, double z) {
  const double r = std::sqrt(std::max(0.0, (1 - z) * (1 + z)));
  return {r * std::sin(lon), z, r * std::cos(lon)};
}

}  // namespace

// The angle to `centre` is 1-Lipschitz in arc length along the cell's boundary, so its maximum
// over 9 points per edge plus half their spacing bounds it (meridian edges: latitude steps;
// latitude edges: arcs of at most the longitude step). The farthest direction of a cell from an
// interior point lies on its boundary.
double EnvironmentLight::CellRadius(const Vec3d& centre, const Cell& c) {
  constexpr int kSteps = 8;
  const double lat0 = std::asin(std::clamp(c.z0, -1.0, 1.0));
  const double lat1 = std::asin(std::clamp(c.z1, -1.0, 1.0));
  double radius = 0;
  for (int t = 0; t <= kSteps; ++t) {
    const double f = double(t) / kSteps;
    const double lon = c.lon0 + f * (c.lon1 - c.lon0);
    const double z = std::sin(lat0 + f * (lat1 - lat0));
    for (const Vec3d& w : {MapDirection(lon, c.z0), MapDirection(lon, c.z1),
                           MapDirection(c.lon0, z), MapDirection(c.lon1, z)})
      radius = std::max(radius, AngleBetween(centre, w));
  }
  return radius + std::max(c.lon1 - c.lon0, lat1 - lat0) / (2 * kSteps) + 1e-9;
}

bool EnvironmentLight::RowBelow(const Vec3d& nMap, int iy) const {
  // n . w = ny z + sqrt(1 - z^2) (nx sin lon + nz cos lon) <= g(z) = ny z + h sqrt(1 - z^2),
  // h = sqrt(nx^2 + nz^2); g is concave with its maximum at z = ny (n unit): the band's largest
  // is g at ny clamped to the band.
  const double h = std::sqrt(nMap.x * nMap.x + nMap.z * nMap.z);
  const double z = std::clamp(nMap.y, rowZ0_[iy], rowZ1_[iy]);
  return nMap.y * z + h * std::sqrt(std::max(0.0, (1 - z) * (1 + z))) < -kBelowMargin;
}

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
  // Cell centres and, per row, the largest cell radius: the row's cells are congruent but for
  // the half-width first and last columns, so those three bound them all.
  columnSinCentre_.resize(w), columnCosCentre_.resize(w);
  for (int ix = 0; ix < w; ++ix) {
    const double lon = 0.5 * (columnLon0_[ix] + columnLon1_[ix]);
    columnSinCentre_[ix] = std::sin(lon), columnCosCentre_[ix] = std::cos(lon);
  }
  rowZCentre_.resize(h), rowRCentre_.resize(h), rowBelowDot_.resize(h);
  for (int iy = 0; iy < h; ++iy) {
    const double z = 0.5 * (rowZ0_[iy] + rowZ1_[iy]);
    rowZCentre_[iy] = z, rowRCentre_[iy] = std::sqrt(std::max(0.0, (1 - z) * (1 + z)));
    double radius = 0;
    for (int ix : {0, std::min(1, w - 1), w - 1})
      radius = std::max(radius, CellRadius(CellCentre(ix, iy), CellBounds(ix, iy)));
    // A direction w of the cell is at least angle(n, centre) - radius from n: below the surface
    // when n . centre < cos(pi/2 + radius) = -sin(radius). Cells of a radius near pi/2 or more
    // (maps of one or two pixels a side) are never rejected.
    rowBelowDot_[iy] = radius < 1.5 ? -std::sin(radius) - kBelowMargin : -2.0;
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
  // PiecewiseConstant2D::Sample in its two steps, stopping where the row or the cell is wholly
  // below the surface.
  Vec3d nMap;
  if (n) nMap = mapFromWorld_ * *n;
  const DiscreteSample row = distribution_->SampleRow(u.y);
  const int iy = int(row.index);
  if (n && RowBelow(nMap, iy)) return {};
  const DiscreteSample column = distribution_->SampleColumn(row.index, u.x);
  const int ix = int(column.index);
  if (n && CellBelow(nMap, ix, iy)) return {};
  const double pmf = row.pmf * column.pmf;
  const Vec2d uCell{column.uRemapped, row.uRemapped};
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

std::vector<Vec3d> EnvironmentLight::ProjectSh(int order) const {
  std::vector<Vec3d> out(size_t(ShCoeffCount(order)));
  if (black_) return out;
  if (kind_ == Environment::Kind::kUniform) {
    out[0] = uniform_ * (2 * std::sqrt(kPi));
    return out;
  }
  // Per cell, a 3-point Gauss-Legendre rule on each axis of (sin latitude, longitude), where the
  // solid angle is dz dlon: the cell's integral of Y_i times its constant radiance.
  constexpr double kNodes[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
  constexpr double kWeights[3] = {5.0 / 9, 8.0 / 9, 5.0 / 9};
  const int n = ShCoeffCount(order);
  double y[kMaxShCoeffCount];
  for (int iy = 0; iy < map_->height; ++iy) {
    for (int ix = 0; ix < width_; ++ix) {
      const Vec3d radiance = TexelRadiance(ix, iy);
      if (MaxComponent(radiance) <= 0) continue;
      const Cell c = CellBounds(ix, iy);
      double cell[kMaxShCoeffCount] = {};
      for (int a = 0; a < 3; ++a) {
        const double z = 0.5 * (c.z0 + c.z1) + 0.5 * (c.z1 - c.z0) * kNodes[a];
        for (int b = 0; b < 3; ++b) {
          const double lon = 0.5 * (c.lon0 + c.lon1) + 0.5 * (c.lon1 - c.lon0) * kNodes[b];
          EvalShBasis(order, worldFromMap_ * MapDirection(lon, z), y);
          const double w = kWeights[a] * kWeights[b];
          for (int i = 0; i < n; ++i) cell[i] += w * y[i];
        }
      }
      const double area = 0.25 * (c.z1 - c.z0) * (c.lon1 - c.lon0);
      for (int i = 0; i < n; ++i) out[size_t(i)] += radiance * (cell[i] * area);
    }
  }
  return out;
}

}  // namespace probebake
