// Lights at a point: point lights and spot lights, delta lights in position (emitter.h's
// contract, family kDelta). The probe projects them exactly; a path's vertex samples them; no ray
// ever hits them.
//
// A point light of intensity I (W/sr per channel) gives radiance weight I / d^2 at distance d; a
// spot light scales it by a smoothstep from its outer cone (0) to its inner cone (1) about its
// axis. Importance: luminance of I x falloff / d^2, 0 where p's surface faces away.
#pragma once

#include <algorithm>
#include <cmath>

#include "light_sample.h"
#include "light_tree.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake {

// A delta sample toward the point `position` from p: direction, distance and point, with the
// squared distance in *d2 for the radiance weight. False when p is at the point.
inline bool SampleTowardPoint(const Vec3d& position, const Vec3d& p, LightSample* s, double* d2) {
  s->delta = true;
  s->pdf = 1;
  const Vec3d v = position - p;
  *d2 = LengthSquared(v);
  if (!(*d2 > 0)) return false;
  const double d = std::sqrt(*d2);
  s->wi = v * (1 / d);
  s->distance = d;
  s->point = position;
  s->vertexScale = 0;  // a point, not a surface: set, as callers may reuse *s
  return true;
}

class PointEmitter {
 public:
  static constexpr EmitterFamily kFamily = EmitterFamily::kDelta;

  // `offset`: the tracer's local origin (tracer_scene.h).
  PointEmitter(const PointLight& light, const Vec3d& offset)
      : position_(light.position - offset),
        intensity_(light.intensity),
        power_(Luminance(intensity_)) {}

  double power() const { return power_; }

  double Importance(const Vec3d& p, const Vec3d* n) const {
    const Vec3d v = position_ - p;
    const double d2 = LengthSquared(v);
    if (n && Dot(v, *n) <= 0) return 0;
    return power_ / std::max(d2, 1e-300);
  }

  bool EvalDelta(const Vec3d& p, LightSample* s) const {
    double d2;
    if (!SampleTowardPoint(position_, p, s, &d2)) return false;
    s->radiance = intensity_ * (1 / d2);
    return true;
  }

  bool TreeItem(LightTree::Item* item) const {
    item->lo = item->hi = position_;
    item->weight = power_;
    item->clamp = 1e-300;
    return true;
  }

 private:
  Vec3d position_;
  Vec3d intensity_;
  double power_;
};

class SpotEmitter {
 public:
  static constexpr EmitterFamily kFamily = EmitterFamily::kDelta;

  SpotEmitter(const SpotLight& light, const Vec3d& offset)
      : position_(light.position - offset),
        axis_(light.direction),
        intensity_(light.intensity),
        cosInner_(light.cosInner),
        cosOuter_(light.cosOuter),
        power_(Luminance(intensity_)) {}

  double power() const { return power_; }

  double Importance(const Vec3d& p, const Vec3d* n) const {
    const Vec3d v = position_ - p;
    const double d2 = LengthSquared(v);
    if (n && Dot(v, *n) <= 0) return 0;
    if (!(d2 > 0)) return 0;
    const double falloff = Falloff(-v / std::sqrt(d2));
    return power_ * falloff / std::max(d2, 1e-300);
  }

  bool EvalDelta(const Vec3d& p, LightSample* s) const {
    double d2;
    if (!SampleTowardPoint(position_, p, s, &d2)) return false;
    const double falloff = Falloff(-s->wi);
    if (falloff <= 0) return false;
    s->radiance = intensity_ * (falloff / d2);
    return true;
  }

  // Emits within the outer cone: the tree's orientation bound.
  bool TreeItem(LightTree::Item* item) const {
    item->lo = item->hi = position_;
    item->weight = power_;
    item->clamp = 1e-300;
    item->axis = axis_;
    item->thetaO = 0;
    item->thetaE = std::acos(std::clamp(cosOuter_, -1.0, 1.0));
    return true;
  }

 private:
  // Fraction of the axis' intensity emitted along unit direction wFromLight.
  double Falloff(const Vec3d& wFromLight) const {
    const double x = Dot(wFromLight, axis_);
    if (cosOuter_ == cosInner_) return x < cosOuter_ ? 0 : 1;
    const double t = std::clamp((x - cosOuter_) / (cosInner_ - cosOuter_), 0.0, 1.0);
    return t * t * (3 - 2 * t);
  }

  Vec3d position_;
  Vec3d axis_;  // the direction light travels along the axis
  Vec3d intensity_;
  double cosInner_, cosOuter_;
  double power_;
};

}  // namespace probebake
