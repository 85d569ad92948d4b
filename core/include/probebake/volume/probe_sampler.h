// The reference sampler of a probe volume: the lighting at any point and surface normal from the
// 8 probes around it, weighted as DDGI does (Majercik et al. 2019, "Dynamic Diffuse Global
// Illumination with Ray-Traced Irradiance Fields"; McGuire et al. 2017, light-field probes), and
// by the cell's connectivity, which cuts off the probes beyond a wall that Chebyshev's bound
// alone lets through where they see the point at a grazing angle. Engines that sample the volume
// themselves should match it (integrations/shaders/ do).
//
// For a point x with unit normal n, in scene coordinates:
//   - the cell of the grid holding x (clamped to the grid) gives 8 probes; each active probe
//     that holds light (validity >= 0.5, or filled by dilation) takes
//       w = trilinear(x) * backface * visibility,
//     - trilinear: x's trilinear weights over the cell's grid points (offsets do not move them);
//     - backface: ((dot(dir to probe, n) + 1) / 2)^2 + 0.2, dir from x to the probe where it was
//       baked (grid point + offset): probes behind the surface count less, never nothing;
//     - visibility, with the volume's moments (the mean and mean square of the inverse
//       first-hit distance s = 1/t in the direction from the probe to a point y at distance d,
//       probebake/volume/visibility_map.h): seen = ProbeVisibility there, taken at two points
//       and the smaller kept: xb = x + n * normalBias * s (s the grid's smallest spacing; DDGI's
//       normal bias, so that a surface does not ask a probe about its own plane), and x itself,
//       so that a bias that crosses a thin wall cannot make the probes beyond it visible;
//     - connectivity: the cell's 12 edges each get the smaller of its two probes' visibility of
//       the other, and b(i, j) is the bottleneck (the largest, over paths of edges from corner i
//       to corner j, of the smallest edge on the path), so the probes on one side of a wall
//       through the cell are connected and the two sides cut apart. A probe claims x unless,
//       along one of its blocked edges, x lies beyond the first surface the probe saw that way
//       (1 / its mean s toward the neighbour: the wall seen head-on, where the moments are
//       sharp; a ramp of 1% of the edge's length; an edge counts as far as it is blocked). A
//       probe's support is sum_j claim_j b(i, j) over the probes weighing in or, where none
//       claims x (x inside what blocks the edges), sum_j seen_j b(i, j); the probe counts at
//       most (support / the largest support)^8. So the side of a wall x lies on is read where
//       the wall crosses the cell's edges, not from a grazing view of x through the wall, which
//       Chebyshev's bound cannot resolve;
//     - the probe's visibility is min(seen, connectivity). Then weights below 0.2 are crushed,
//       w -> w^3 / 0.2^2, after a floor of 1e-30 so that a point hidden from all 8 probes still
//       gets their blend. The cell is chosen at x, not xb, for the same reason as the second
//       visibility point;
//   - the blend is normalised by the weights' sum.
// Irradiance is E(n) = sum_i E_i Y_i(n), E_i the blended irradiance SH when the volume has them,
// else the blended radiance SH times the clamped cosine's band factors; the blended radiance SH
// are returned too.
#pragma once

#include <cstdint>
#include <vector>

#include "probebake/bake/probe_volume.h"
#include "probebake/math/vec3.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {

struct ProbeSamplerOptions {
  // Fraction of the smallest spacing, >= 0. Small (5 mm at a 0.5 m spacing): a bias longer than a
  // point's distance to a thin wall puts the biased point inside it, where the probes on the
  // point's own side no longer see it.
  double normalBias = 0.01;
  bool visibility = true;  // Chebyshev weights (when the volume has moments)
  bool backfaceWeight = true;
  // With visibility: the cell's connectivity. Off, the weights are DDGI's (for comparison).
  bool connectivity = true;
};

struct ProbeSample {
  Vec3d irradiance;               // E(n), RGB
  std::vector<Vec3d> radianceSh;  // blended radiance SH, (L+1)^2 RGB coefficients
  int probes = 0;                 // probes that took part (0: no light known here, all zero)
};

class ProbeSampler {
 public:
  // `volume` must outlive the sampler and be consistent (as ReadProbeVolume returns it).
  explicit ProbeSampler(const ProbeVolume& volume, ProbeSamplerOptions options = {});
  // position: scene coordinates (finite); normal: non-zero (normalised here).
  ProbeSample Sample(const Vec3d& position, const Vec3d& normal) const;

 private:
  const ProbeVolume& volume_;
  ProbeSamplerOptions options_;
  double bias_;                     // scene units
  std::vector<double> bandFactor_;  // per coefficient: A_l, or 1 with irradiance SH
};

}  // namespace probebake
