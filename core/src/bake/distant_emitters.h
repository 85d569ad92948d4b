// Lights at infinity (emitter.h's contract): a directional light of zero size (family kDelta), the
// sun, a directional light with an angular radius (kDistant), and the environment (kDistant,
// environment_light.h). Their samples have distance infinity; the same direction arrives at every
// point.
//
// Importance, in irradiance units like the finite lights': E for a directional light and the sun
// (a disk of uniform radiance L and angular radius theta gives E = L pi sin^2(theta) on a surface
// facing it), the environment's mean luminance x pi. Zero where the light lies wholly below p's
// tangent plane (the environment: never, its importance ignores p).
#pragma once

#include <cmath>
#include <numbers>

#include "environment_guide.h"
#include "environment_light.h"
#include "light_sample.h"
#include "light_tree.h"
#include "probebake/math/frame.h"
#include "probebake/math/vec3.h"
#include "probebake/sampling/warps.h"
#include "probebake/scene/scene.h"

namespace probebake {

class DirectionalEmitter {
 public:
  static constexpr EmitterFamily kFamily = EmitterFamily::kDelta;

  // Precondition: light.cosHalfAngle >= 1.
  explicit DirectionalEmitter(const DirectionalLight& light)
      : toLight_(-light.direction), irradiance_(light.irradiance), power_(Luminance(irradiance_)) {}

  double power() const { return power_; }

  double Importance(const Vec3d& /*p*/, const Vec3d* n) const {
    if (n && Dot(toLight_, *n) <= 0) return 0;
    return power_;
  }

  bool EvalDelta(const Vec3d& /*p*/, LightSample* s) const {
    s->delta = true;
    s->pdf = 1;
    s->wi = toLight_;
    s->distance = std::numeric_limits<double>::infinity();
    s->radiance = irradiance_;
    return true;
  }

  bool TreeItem(LightTree::Item*) const { return false; }

 private:
  Vec3d toLight_;  // unit
  Vec3d irradiance_;
  double power_;
};

// A disk of directions of uniform radiance, sampled uniformly in solid angle.
class SunEmitter {
 public:
  static constexpr EmitterFamily kFamily = EmitterFamily::kDistant;

  // Precondition: light.cosHalfAngle < 1.
  explicit SunEmitter(const DirectionalLight& light)
      : toLight_(-light.direction),
        frame_(Framed::FromZ(toLight_)),
        cosOuter_(light.cosHalfAngle),
        oneMinusCos_(1 - light.cosHalfAngle),
        sin2Outer_(oneMinusCos_ * (1 + light.cosHalfAngle)),
        sinOuter_(std::sqrt(sin2Outer_)),
        radiance_(light.irradiance / (std::numbers::pi * sin2Outer_)),
        power_(Luminance(radiance_)) {}

  double power() const { return power_; }

  double Importance(const Vec3d& /*p*/, const Vec3d* n) const {
    // The cap is wholly below the tangent plane when its axis is more than 90 degrees + its
    // radius from n.
    if (n && Dot(toLight_, *n) <= -sinOuter_) return 0;
    return power_ * std::numbers::pi * sin2Outer_;
  }

  bool Sample(const Vec3d& /*p*/, const Vec3d* /*n*/, const Vec2d& u, LightSample* s) const {
    s->wi = frame_.FromLocal(SampleUniformCone(u, cosOuter_));
    s->distance = std::numeric_limits<double>::infinity();
    s->radiance = radiance_;
    s->pdf = UniformConePdf(cosOuter_);
    return true;
  }

  // A ray from p along wi escaped the scene; pmf: the probability of choosing this light.
  bool EvalEscaped(const Vec3d& /*p*/, const Vec3d& wi, const Vec3d* /*n*/, double pmf,
                   LightHit* out) const {
    if (Dot(wi, toLight_) < cosOuter_) return false;
    out->radiance = radiance_;
    out->pdf = pmf / (2 * std::numbers::pi * oneMinusCos_);
    return true;
  }

  bool TreeItem(LightTree::Item*) const { return false; }

 private:
  Vec3d toLight_;       // unit, the disk's centre
  Framed frame_;        // about toLight_, built once rather than per sample
  double cosOuter_;     // cos of the angular radius
  double oneMinusCos_;  // 1 - cosOuter_, without cancellation
  double sin2Outer_, sinOuter_;
  Vec3d radiance_;
  double power_;
};

// The environment (environment_light.h) as one of a scene's lights. Does not own it.
//
// With a guide (environment_guide.h), at a surface point p (n given) whose cell has alpha > 0 a
// direction is drawn from the guide with probability alpha and from the environment's own
// distribution otherwise, and every pdf there (Sample's, EvalEscaped's) is the mixture's,
// alpha p_g + (1 - alpha) p_e. Elsewhere (probes, media, unguided cells) sampling is the
// environment's alone, bit for bit.
class EnvironmentEmitter {
 public:
  static constexpr EmitterFamily kFamily = EmitterFamily::kDistant;

  // Precondition: !environment.IsBlack(); `environment` outlives this.
  explicit EnvironmentEmitter(const EnvironmentLight& environment)
      : environment_(&environment), power_(environment.Importance()) {}

  // Samples from now on through `guide` (null: none), which outlives this.
  void SetGuide(const EnvironmentGuide* guide) { guide_ = guide; }

  double power() const { return power_; }

  double Importance(const Vec3d& /*p*/, const Vec3d* /*n*/) const { return power_; }

  bool Sample(const Vec3d& p, const Vec3d* n, const Vec2d& u, LightSample* s) const {
    s->distance = std::numeric_limits<double>::infinity();
    int32_t cell;
    const double alpha = guide_ && n ? guide_->Alpha(p, &cell) : 0.0;
    if (alpha > 0) {
      double pdf;
      if (u.x < alpha) {
        s->wi = guide_->Sample(cell, {std::min(u.x / alpha, kOneMinusEpsilon), u.y});
        if (Dot(*n, s->wi) <= 0) return false;  // no light arrives from below the surface
        s->radiance = environment_->RadianceAndPdf(s->wi, n, &pdf);
      } else {
        const double ux = std::min((u.x - alpha) / (1 - alpha), kOneMinusEpsilon);
        s->radiance = environment_->Sample({ux, u.y}, n, &s->wi, &pdf);
        if (!(pdf > 0)) return false;
      }
      s->pdf = alpha * guide_->Pdf(cell, s->wi) + (1 - alpha) * pdf;
      return s->pdf > 0 && MaxComponent(s->radiance) > 0;
    }
    s->radiance = environment_->Sample(u, n, &s->wi, &s->pdf);
    return s->pdf > 0 && MaxComponent(s->radiance) > 0;
  }

  bool EvalEscaped(const Vec3d& p, const Vec3d& wi, const Vec3d* n, double pmf,
                   LightHit* out) const {
    double pdf;
    out->radiance = environment_->RadianceAndPdf(wi, n, &pdf);
    if (MaxComponent(out->radiance) <= 0) return false;
    int32_t cell;
    const double alpha = guide_ && n ? guide_->Alpha(p, &cell) : 0.0;
    if (alpha > 0) pdf = alpha * guide_->Pdf(cell, wi) + (1 - alpha) * pdf;
    out->pdf = pmf * pdf;
    return true;
  }

  bool TreeItem(LightTree::Item*) const { return false; }

 private:
  const EnvironmentLight* environment_;
  const EnvironmentGuide* guide_ = nullptr;
  double power_;
};

}  // namespace probebake
