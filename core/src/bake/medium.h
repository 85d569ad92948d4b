// A homogeneous participating medium filling an axis-aligned box (vacuum outside): free-flight
// sampling and transmittance along rays, in the tracer's local coordinates.
//
// Free flight uses spectral MIS over the three channels (one-sample balance heuristic, as pbrt-v3's
// HomogeneousMedium): a channel c is picked uniformly, a distance drawn with density
// sigma_t[c] exp(-sigma_t[c] t), and the returned weight divides by the channel-averaged density,
// so chromatic media stay unbiased and no channel's variance blows up:
//   scattered at t: weight = Tr(t) sigma_s / mean_c(sigma_t[c] Tr_c(t)),
//   passed through a length L inside the box: weight = Tr(L) / mean_c(Tr_c(L)),
// with Tr(t) = exp(-sigma_t t) per channel. Units: sigma per scene unit, distances in scene units.
#pragma once

#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake {

struct MediumSample {
  bool scattered = false;
  double t = 0;           // distance of the scattering event along the ray (when scattered)
  Vec3d weight{1, 1, 1};  // throughput factor for the segment
};

class HomogeneousMedium {
 public:
  // `offset`: the tracer's local origin (tracer_scene.h).
  HomogeneousMedium(const Medium& medium, const Vec3d& offset);

  // Samples an interaction along o + t dir, t in (0, tMax) (tMax may be infinite).
  MediumSample Sample(const Vec3d& o, const Vec3d& dir, double tMax, double uChannel,
                      double uDistance) const;
  // exp(-sigma_t x length of o + t dir, t in (0, tMax), inside the box).
  Vec3d Transmittance(const Vec3d& o, const Vec3d& dir, double tMax) const;
  double g() const { return g_; }

 private:
  // [t0, t1] = the part of (0, tMax) inside the box; false when empty.
  bool Overlap(const Vec3d& o, const Vec3d& dir, double tMax, double* t0, double* t1) const;

  Vec3d sigmaT_, sigmaS_;
  double g_;
  Vec3d lo_, hi_;
};

}  // namespace probebake
