#include "area_emitters.h"

#include <cmath>
#include <limits>

#include "probebake/sampling/spherical_rectangle.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

constexpr double kPi = std::numbers::pi;

// A rectangle seen nearly edge-on subtends almost no solid angle however near it is; there the
// solid-angle map degenerates (a sliver of the sphere spread over the whole rectangle), and area
// sampling, well behaved at any angle, takes over.
constexpr double kMaxSolidAnglePdf = 1e6;
// Solid-angle sampling pays only where a rectangle looks large: area sampling's radiance / pdf
// varies across the light as cos / d^2, by (1 + (a / d)^2)^(-3/2) from its centre to an edge a
// away, which is 28% where area / d^2 = 1 (a square of side d, spanning ~53 degrees) and 4% at
// 0.1. Beyond that area sampling's noise is small next to the rest of the estimate's, at a
// fraction of the cost (solid-angle sampling: ~150 ns a sample, probebake_sampling_bench); the
// bench's figures for this threshold are in docs/performance-history.md.
constexpr double kMinSolidAngleRatio = 1;

// cos of the half-angle of the cap a sphere subtends from p; false when p is inside it.
bool SphereCapCos(const Vec3d& centre, double radius, const Vec3d& p, double* cosMax,
                  double* oneMinusCos) {
  const double dc2 = LengthSquared(centre - p);
  const double r2 = radius * radius;
  if (dc2 <= r2) return false;
  const double sin2 = r2 / dc2;
  *cosMax = std::sqrt(std::max(0.0, 1 - sin2));
  // For small caps 1 - cos without cancellation: from r / d ~ 1e-8 the difference was 0, the pdf
  // infinite and the bake NaN (1e-7: 2% off). Above 1e-6 the difference is accurate to 1e-10 and
  // keeps the bits of earlier versions.
  *oneMinusCos = sin2 < 1e-6 ? sin2 / (1 + *cosMax) : 1 - *cosMax;
  if (!(*oneMinusCos > 0)) return false;  // r^2 / d^2 underflowed: the sphere is not there
  return true;
}

}  // namespace

bool PlanarEmitter::FinishSample(const Vec3d& p, const Vec3d& q, double solidAnglePdf,
                                 LightSample* s) const {
  const Vec3d v = q - p;
  const double d2 = LengthSquared(v);
  if (!(d2 > 0)) return false;
  const double d = std::sqrt(d2);
  s->wi = v * (1 / d);
  const double cosLight = -Dot(s->wi, normal_);
  if ((cosLight <= 0 && !twoSided_) || cosLight == 0) return false;
  s->distance = d;
  s->point = q;
  s->vertexScale = vertexScale_;
  s->radiance = radiance_;
  s->pdf = solidAnglePdf > 0 ? solidAnglePdf : d2 / (area_ * std::abs(cosLight));
  return true;
}

void PlanarEmitter::FillTreeItem(LightTree::Item* item) const {
  item->weight = power_ * area_;
  item->clamp = area_;
  if (!twoSided_) item->axis = normal_, item->thetaO = 0, item->thetaE = kPi / 2;
}

RectEmitter::RectEmitter(const RectLight& light, const Vec3d& offset)
    : PlanarEmitter(light.radiance, light.twoSided), edge1_(light.edge1), edge2_(light.edge2) {
  const Vec3d c = Cross(edge1_, edge2_);
  area_ = Length(c);
  normal_ = c / area_;
  rectangular_ = std::abs(Dot(edge1_, edge2_)) <= 1e-12 * Length(edge1_) * Length(edge2_);
  const Vec3d corner = light.corner - offset;
  corners_[0] = corner;
  corners_[1] = corner + edge1_;
  corners_[2] = corner + edge1_ + edge2_;
  corners_[3] = corner + edge2_;
  centre_ = corner + (edge1_ + edge2_) * 0.5;
  for (const Vec3d& q : corners_) vertexScale_ = std::max(vertexScale_, MaxComponent(Abs(q)));
}

bool RectEmitter::UseSolidAngleSampling(const Vec3d& p) const {
  return rectangular_ && area_ >= kMinSolidAngleRatio * LengthSquared(centre_ - p);
}

double RectEmitter::SolidAnglePdf(const Vec3d& p) const {
  if (!UseSolidAngleSampling(p)) return 0;
  const double pdf = SphericalRectanglePdf(p, corners_[0], edge1_, edge2_);
  return pdf > 0 && pdf <= kMaxSolidAnglePdf ? pdf : 0;
}

bool RectEmitter::Sample(const Vec3d& p, const Vec3d* /*n*/, const Vec2d& u, LightSample* s) const {
  if (UseSolidAngleSampling(p)) {
    // Unless the rectangle is too small a target for it (then area sampling below, with the same
    // u: the choice depends on p alone, as in EvalHit).
    const SphericalRectangleSample r = SampleSphericalRectangle(u, p, corners_[0], edge1_, edge2_);
    if (r.pdf > 0 && r.pdf <= kMaxSolidAnglePdf) return FinishSample(p, r.p, r.pdf, s);
  }
  return FinishSample(p, SampleUniformParallelogram(u, corners_[0], edge1_, edge2_), 0, s);
}

bool RectEmitter::EvalHit(const Vec3d& p, const Vec3d& wi, const SurfaceHit& hit, double pmf,
                          LightHit* out) const {
  double cosLight;
  if (!Receives(wi, &cosLight)) return false;
  out->radiance = radiance_;
  const double solidAnglePdf = SolidAnglePdf(p);
  out->pdf = solidAnglePdf > 0 ? pmf * solidAnglePdf : AreaPdf(cosLight, hit.t, pmf);
  return true;
}

bool RectEmitter::TreeItem(LightTree::Item* item) const {
  item->lo = item->hi = corners_[0];
  for (const Vec3d& q : corners_) item->lo = Min(item->lo, q), item->hi = Max(item->hi, q);
  FillTreeItem(item);
  return true;
}

DiskEmitter::DiskEmitter(const DiskLight& light, const Vec3d& offset)
    : PlanarEmitter(light.radiance, light.twoSided),
      centre_(light.center - offset),
      frame_(Framed::FromZ(light.normal)),
      radius_(light.radius) {
  normal_ = light.normal;
  area_ = kPi * radius_ * radius_;
  vertexScale_ = MaxComponent(Abs(centre_)) + radius_;
}

bool DiskEmitter::Sample(const Vec3d& p, const Vec3d* /*n*/, const Vec2d& u, LightSample* s) const {
  const Vec2d d = SampleUniformDiskConcentric(u);
  return FinishSample(p, centre_ + (frame_.s * d.x + frame_.t * d.y) * radius_, 0, s);
}

bool DiskEmitter::EvalHit(const Vec3d& /*p*/, const Vec3d& wi, const SurfaceHit& hit, double pmf,
                          LightHit* out) const {
  double cosLight;
  if (!Receives(wi, &cosLight)) return false;
  out->radiance = radiance_;
  out->pdf = AreaPdf(cosLight, hit.t, pmf);
  return true;
}

bool DiskEmitter::TreeItem(LightTree::Item* item) const {
  const Vec3d r{radius_, radius_, radius_};
  item->lo = centre_ - r, item->hi = centre_ + r;
  FillTreeItem(item);
  return true;
}

SphereEmitter::SphereEmitter(const SphereLight& light, const Vec3d& offset)
    : centre_(light.center - offset),
      radius_(light.radius),
      radiance_(light.radiance),
      vertexScale_(MaxComponent(Abs(centre_)) + radius_),
      power_(Luminance(radiance_)) {}

bool SphereEmitter::Sample(const Vec3d& p, const Vec3d* /*n*/, const Vec2d& u,
                           LightSample* s) const {
  double cosMax, oneMinusCos;
  if (!SphereCapCos(centre_, radius_, p, &cosMax, &oneMinusCos)) return false;
  const Vec3d toCentre = centre_ - p;
  const double dc2 = LengthSquared(toCentre);
  const double r2 = radius_ * radius_;
  const Vec3d axis = toCentre / std::sqrt(dc2);
  const Vec3d local = SampleUniformConeFromOneMinusCos(u, oneMinusCos);
  s->wi = Framed::FromZ(axis).FromLocal(local);
  // Nearest intersection with the sphere; at the silhouette rounding may leave the discriminant
  // slightly negative: take the tangent point.
  const double b = Dot(toCentre, s->wi);
  const double disc = r2 - (dc2 - b * b);
  s->distance = b - std::sqrt(std::max(0.0, disc));
  s->point = p + s->wi * s->distance;
  s->vertexScale = vertexScale_;
  s->radiance = radiance_;
  s->pdf = UniformConePdfFromOneMinusCos(oneMinusCos);
  return true;
}

bool SphereEmitter::EvalHit(const Vec3d& p, const Vec3d& /*wi*/, const SurfaceHit& /*hit*/,
                            double pmf, LightHit* out) const {
  double cosMax, oneMinusCos;
  if (!SphereCapCos(centre_, radius_, p, &cosMax, &oneMinusCos)) return false;
  out->radiance = radiance_;
  out->pdf = pmf * UniformConePdfFromOneMinusCos(oneMinusCos);
  return true;
}

bool SphereEmitter::TreeItem(LightTree::Item* item) const {
  const Vec3d r{radius_, radius_, radius_};
  item->lo = centre_ - r, item->hi = centre_ + r;
  // As Importance: the emitting area is the disk seen from afar.
  item->weight = power_ * kPi * radius_ * radius_;
  item->clamp = kPi * radius_ * radius_;
  return true;
}

}  // namespace probebake
