// The visibility moments of a probe (docs/volume-format.md, `visibility_NN`), after DDGI and
// McGuire et al.'s light-field probes: over an octahedral map of kVisibilityMapSize^2 texels, the
// mean distance and mean squared distance from the probe to the first surface its own primary
// rays hit, with a miss (or a hit beyond it) counted as VisibilityMaxDistance. A sampler reads
// them as a Chebyshev bound on whether a point at distance d in a texel's direction is visible
// from the probe.
//
// Why 8 x 8: the moments come from the probe's own rays at no extra cost, so the texel count
// trades the map's angular resolution (a texel spans about 4 pi / 64 = 0.2 sr, some 25 degrees)
// against the rays per texel (16 at the default 1024 samples, so a texel's mean is itself
// reliable). DDGI's 16 x 16 maps are filled by hundreds of rays per frame, accumulated over many
// frames; a bake has its samples once. 64 Vec3S grids per probe are 768 bytes, 7 times an
// order-2 probe's radiance.
//
// Octahedral map: a unit direction w maps to the square [-1, 1]^2 by (w.x, w.y) / |w|_1, the
// lower hemisphere (w.z < 0) folded over the diagonals, then to [0, 1)^2 and the texel
// (u, v) -> v * size + u. World axes, +Z the pole, as the SH grids.
#pragma once

#include <algorithm>
#include <cmath>

#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake {

inline constexpr int kVisibilityMapSize = 8;
inline constexpr int kVisibilityTexels = kVisibilityMapSize * kVisibilityMapSize;

// The octahedral coordinates of unit direction w, in [-1, 1]^2.
inline void OctahedralEncode(const Vec3d& w, double* u, double* v) {
  const double l1 = std::abs(w.x) + std::abs(w.y) + std::abs(w.z);
  double x = w.x / l1, y = w.y / l1;
  if (w.z < 0) {
    const double fx = (1 - std::abs(y)) * (x >= 0 ? 1 : -1);
    const double fy = (1 - std::abs(x)) * (y >= 0 ? 1 : -1);
    x = fx;
    y = fy;
  }
  *u = x;
  *v = y;
}

// The texel of unit direction w, in [0, kVisibilityTexels).
inline int VisibilityTexel(const Vec3d& w) {
  double u, v;
  OctahedralEncode(w, &u, &v);
  const auto cell = [](double x) {
    return std::clamp(int(std::floor((x + 1) * 0.5 * kVisibilityMapSize)), 0,
                      kVisibilityMapSize - 1);
  };
  return cell(v) * kVisibilityMapSize + cell(u);
}

// The distance a miss counts as, and the cap on hits: twice the diagonal of a grid cell, farther
// than any point a sampler asks a probe about (at most a cell diagonal plus relocation offsets of
// half a spacing each).
inline double VisibilityMaxDistance(const ProbeGrid& grid) {
  return 2 * Length(grid.spacing);
}

}  // namespace probebake
