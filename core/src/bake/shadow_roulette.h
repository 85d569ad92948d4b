// Russian roulette on shadow rays.
//
// A shadow ray only decides whether a contribution already known arrives: c, what its light
// sample or join adds to the path's radiance when unoccluded. A ray that would add little of the
// probe's radiance costs as much to trace as one that adds much, so below a threshold T > 0 it is
// traced with probability q = c / T only, and what it adds is weighted by 1 / q: the estimate
// stays unbiased (E = q c / q = c) for any T fixed before the number u that decides, and each
// ray traced below T adds T. The variance added per such ray is at most c (T - c), small against
// the probe's when T is a small share of its radiance (the integrator takes T from a pilot of the
// probe's own paths: probe_integrator.h).
#pragma once

namespace probebake {

// The weight of a contribution `contribution` >= 0 (radiance, the largest channel) whose shadow
// ray is played with u in [0, 1) against `threshold` (0: no roulette): 0 when the ray is not to
// be traced, 1 when it is traced as it is, threshold / contribution when it survived.
inline double ShadowRouletteWeight(double contribution, double threshold, double u) {
  if (!(contribution < threshold)) return 1;
  const double q = contribution / threshold;
  return u < q ? 1 / q : 0;
}

}  // namespace probebake
