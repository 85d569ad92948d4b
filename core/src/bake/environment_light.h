// The environment (radiance from infinitely far away): uniform or a lat-long HDR map, evaluated and
// importance-sampled by direction.
//
// A map is a piecewise-constant function on the sphere: direction -> the pixel nearest to its
// continuous Imf::LatLongMap position (+Y up, longitude 0 toward +Z, pi/2 toward +X, first and last
// columns at longitude +pi and -pi, first and last rows at the poles). Pixel cells are therefore
// bands in longitude and latitude, half-size at the image edges, with exact solid angles
// dlon * (sin latTop - sin latBottom). Sampling picks a cell with probability proportional to
// luminance * solid angle, then a direction uniform in solid angle inside the cell, so the pdf is
// exactly constant on each cell and radiance / pdf is nearly constant: the estimator's variance
// comes from visibility and cosines, not from the map.
//
// Given a surface normal, a sample whose latitude band or cell lies wholly below the surface is
// rejected as soon as its row or cell is known (pdf 0), before its direction is computed: the
// caller would have rejected its direction anyway (n . wi <= 0), so the estimates are the same
// bits, and at the demo room's surface vertices 78% of the sky's samples fell below the surface.
#pragma once

#include <memory>
#include <vector>

#include "probebake/math/mat3.h"
#include "probebake/math/vec3.h"
#include "probebake/sampling/distribution.h"
#include "probebake/scene/scene.h"

namespace probebake {

class EnvironmentLight {
 public:
  explicit EnvironmentLight(const Environment& env);

  bool IsBlack() const { return black_; }
  // Radiance arriving from direction wi (unit, pointing from the scene toward the sky).
  Vec3d Radiance(const Vec3d& wi) const;
  // Samples a direction: proportional to luminance x solid angle for a map; for a uniform
  // environment cosine-weighted about n when a surface normal is given, else uniform. Returns the
  // radiance from wi; pdf per steradian (0 when nothing can be sampled). With a normal, a map's
  // sample whose row or cell is wholly below the surface returns black with pdf 0 (and *wi
  // unset); every other sample is the one drawn without the normal, and Pdf is unchanged: the
  // rejected directions are those where the surface receives nothing.
  Vec3d Sample(const Vec2d& u, const Vec3d* n, Vec3d* wi, double* pdf) const;
  // A hint, no effect on results: for a map whose tables do not fit in the cache, starts loading
  // what Sample(u, ...) will read, so that work done between the two hides the memory latency.
  void Prefetch(const Vec2d& u) const {
    if (!prefetch_) return;
    int64_t row, col;
    distribution_->Prefetch(u, &row, &col);
    __builtin_prefetch(Texel(int(col), int(row)));
  }
  double Pdf(const Vec3d& wi, const Vec3d* n) const;
  // Radiance from wi and the pdf Sample would have had for it, with one pixel lookup.
  Vec3d RadianceAndPdf(const Vec3d& wi, const Vec3d* n, double* pdf) const;
  // Mean luminance over the sphere times pi: the irradiance a surface would get from an
  // unoccluded hemisphere of average sky (the light's selection importance).
  double Importance() const { return importance_; }
  // The SH projection of order `order` of the radiance (RGB, (order+1)^2 entries): uniform
  // exactly, a map cell by cell (probebake/bake/relight.h, ProjectEnvironmentSh).
  std::vector<Vec3d> ProjectSh(int order) const;

 private:
  struct Cell {
    double lon0, lon1;  // longitude range (lon0 < lon1)
    double z0, z1;      // sin(latitude) range (z0 < z1)
  };
  struct CellIndex {
    int ix, iy;  // column, row
  };
  CellIndex CellOf(const Vec3d& mapDir) const;
  const float* Texel(int ix, int iy) const { return rgb_ + 3 * (size_t(iy) * width_ + ix); }
  // Radiance of cell (ix, iy): its texel times the map's scale.
  Vec3d TexelRadiance(int ix, int iy) const {
    const float* rgb = Texel(ix, iy);
    return Vec3d(rgb[0], rgb[1], rgb[2]) * scale_;
  }
  Cell CellBounds(int ix, int iy) const;
  // Largest angle between `centre` and a direction of cell c (an upper bound).
  static double CellRadius(const Vec3d& centre, const Cell& c);
  // Whether every direction of row iy's latitude band, or of cell (ix, iy), is below the
  // surface of map-space normal nMap (n . w < 0), with a margin far above rounding.
  bool RowBelow(const Vec3d& nMap, int iy) const;
  bool CellBelow(const Vec3d& nMap, int ix, int iy) const {
    return Dot(nMap, CellCentre(ix, iy)) < rowBelowDot_[iy];
  }
  // Map-space direction of the cell's centre (its centre longitude and sin(latitude)).
  Vec3d CellCentre(int ix, int iy) const {
    return {rowRCentre_[iy] * columnSinCentre_[ix], rowZCentre_[iy],
            rowRCentre_[iy] * columnCosCentre_[ix]};
  }
  // Solid angle of cell (ix, iy): its longitude range times its sin(latitude) range. Computed,
  // not tabled: a table per texel would be one more cache miss per sample of a large map.
  double CellSolidAngle(int ix, int iy) const {
    return (columnLon1_[ix] - columnLon0_[ix]) * (rowZ1_[iy] - rowZ0_[iy]);
  }

  Environment::Kind kind_;
  bool black_ = true;
  Vec3d uniform_;
  std::shared_ptr<const EnvironmentMap> map_;
  // map_'s texels, scale and width, held here: sampling reads them without a pointer chase.
  const float* rgb_ = nullptr;
  double scale_ = 1;
  int width_ = 0;
  bool prefetch_ = false;  // Prefetch does something
  Mat3d worldFromMap_, mapFromWorld_;
  std::vector<double> columnLon0_, columnLon1_, rowZ0_, rowZ1_;  // cell bounds (CellBounds)
  // Cell centres, (rowRCentre sin lon, rowZCentre, rowRCentre cos lon) at the column's centre
  // longitude, and per row the dot product with the normal under which a cell is wholly below
  // the surface: -sin(largest cell radius of the row) less a margin (CellBelow).
  std::vector<double> columnSinCentre_, columnCosCentre_, rowZCentre_, rowRCentre_, rowBelowDot_;
  std::unique_ptr<PiecewiseConstant2D> distribution_;
  double importance_ = 0;
};

}  // namespace probebake
