// Lights with a surface of uniform radiance that rays can hit (emitter.h's contract, family
// kSurface): rect (a parallelogram), disk and sphere lights; emissive meshes are in
// mesh_emitter.h. The tracer holds their surfaces (tracer_scene.h), so a ray finds them as it
// finds the scene's meshes.
//
// Sampling: a rectangle (orthogonal edges) that looks large from p by solid angle, else by area; a
// disk by area; a sphere uniformly within the cone it subtends. Importance: luminance x the
// emitting area / d^2 (a sphere's: its disk seen from afar), d^2 floored at that area, and 0 where
// p is behind a one-sided light, inside a sphere, or where the light lies wholly below p's tangent
// plane.
#pragma once

#include <algorithm>
#include <numbers>

#include "light_sample.h"
#include "light_tree.h"
#include "probebake/math/frame.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"
#include "tracer_scene.h"

namespace probebake {

// The importance of a light of luminance `power` and emitting area `area` centred at `centre`,
// seen from p: power x area / d^2, d^2 floored at the area so that points next to the light do
// not weigh it without bound.
inline double AreaImportance(double power, double area, const Vec3d& centre, const Vec3d& p) {
  return power * area / std::max(LengthSquared(centre - p), area);
}

// What rect and disk lights share: a flat emitter, one-sided (toward its normal) or two-sided.
class PlanarEmitter {
 public:
  static constexpr EmitterFamily kFamily = EmitterFamily::kSurface;

  double power() const { return power_; }

 protected:
  // The kind's constructor sets the geometry: normal_, area_ and vertexScale_.
  PlanarEmitter(const Vec3d& radiance, bool twoSided)
      : radiance_(radiance), twoSided_(twoSided), power_(Luminance(radiance)) {}

  // Whether p is behind a one-sided light (onLight: a point of its plane).
  bool Behind(const Vec3d& p, const Vec3d& onLight) const {
    return !twoSided_ && Dot(p - onLight, normal_) <= 0;
  }
  // The sample of point q of the light seen from p: its pdf is solidAnglePdf when q was sampled
  // by solid angle, else the area pdf turned into solid angle. False when q cannot light p
  // (behind a one-sided light, or grazing).
  bool FinishSample(const Vec3d& p, const Vec3d& q, double solidAnglePdf, LightSample* s) const;
  // The cosine at the light of a ray along wi, and whether that ray can receive light from it.
  bool Receives(const Vec3d& wi, double* cosLight) const {
    *cosLight = -Dot(wi, normal_);
    return !(*cosLight <= 0 && !twoSided_);
  }
  // pmf x the pdf of a direction sampled by area, met at distance t with cosine cosLight.
  double AreaPdf(double cosLight, double t, double pmf) const {
    return cosLight != 0 ? pmf * (t * t) / (area_ * std::abs(cosLight)) : 0;
  }
  // The tree's weight, floor and orientation (lo, hi: the kind's).
  void FillTreeItem(LightTree::Item* item) const;

  Vec3d normal_;  // unit, the emitting side of a one-sided light
  double area_ = 0;
  Vec3d radiance_;
  bool twoSided_;
  double vertexScale_ = 0;  // LightSample::vertexScale
  double power_;
};

class RectEmitter : public PlanarEmitter {
 public:
  RectEmitter(const RectLight& light, const Vec3d& offset);

  double Importance(const Vec3d& p, const Vec3d* n) const {
    if (Behind(p, corners_[0])) return 0;
    if (n) {
      bool below = true;
      for (const Vec3d& q : corners_) below = below && Dot(q - p, *n) <= 0;
      if (below) return 0;
    }
    return AreaImportance(power_, area_, centre_, p);
  }
  bool Sample(const Vec3d& p, const Vec3d* n, const Vec2d& u, LightSample* s) const;
  // A ray from p along wi hit the light at hit.t; pmf: the probability of choosing it.
  bool EvalHit(const Vec3d& p, const Vec3d& wi, const SurfaceHit& hit, double pmf,
               LightHit* out) const;
  bool TreeItem(LightTree::Item* item) const;

 private:
  // Whether the light is sampled by solid angle from p (else by area).
  bool UseSolidAngleSampling(const Vec3d& p) const;
  // The solid-angle pdf of the light seen from p, or 0 when it is sampled by area.
  double SolidAnglePdf(const Vec3d& p) const;

  Vec3d edge1_, edge2_;
  Vec3d corners_[4];  // corner, +edge1, +edge1+edge2, +edge2
  Vec3d centre_;
  bool rectangular_;  // orthogonal edges (to rounding)
};

class DiskEmitter : public PlanarEmitter {
 public:
  DiskEmitter(const DiskLight& light, const Vec3d& offset);

  double Importance(const Vec3d& p, const Vec3d* n) const {
    if (Behind(p, centre_)) return 0;
    if (n && Dot(centre_ - p, *n) <= -radius_) return 0;
    return AreaImportance(power_, area_, centre_, p);
  }
  bool Sample(const Vec3d& p, const Vec3d* n, const Vec2d& u, LightSample* s) const;
  bool EvalHit(const Vec3d& p, const Vec3d& wi, const SurfaceHit& hit, double pmf,
               LightHit* out) const;
  bool TreeItem(LightTree::Item* item) const;

 private:
  Vec3d centre_;
  Framed frame_;  // about the normal, built once rather than per sample
  double radius_;
};

// Emits outward only: p inside it receives nothing.
class SphereEmitter {
 public:
  static constexpr EmitterFamily kFamily = EmitterFamily::kSurface;

  SphereEmitter(const SphereLight& light, const Vec3d& offset);

  double power() const { return power_; }

  double Importance(const Vec3d& p, const Vec3d* n) const {
    const double d2 = LengthSquared(centre_ - p);
    if (d2 <= radius_ * radius_) return 0;
    if (n && Dot(centre_ - p, *n) <= -radius_) return 0;
    // Seen from afar, its emitting area is a disk.
    return AreaImportance(power_, std::numbers::pi * radius_ * radius_, centre_, p);
  }
  bool Sample(const Vec3d& p, const Vec3d* n, const Vec2d& u, LightSample* s) const;
  bool EvalHit(const Vec3d& p, const Vec3d& wi, const SurfaceHit& hit, double pmf,
               LightHit* out) const;
  bool TreeItem(LightTree::Item* item) const;

 private:
  Vec3d centre_;
  double radius_;
  Vec3d radiance_;
  double vertexScale_;
  double power_;
};

}  // namespace probebake
