// The visibility moments of a probe (docs/volume-format.md, `visibility_NN`), after DDGI and
// McGuire et al.'s light-field probes: over an octahedral map of kVisibilityMapSize^2 texels, the
// mean and mean square of the inverse distance s = 1/t from the probe to the first surface its
// own primary rays hit, a miss (or a hit beyond VisibilityMaxDistance) counting as s = 0. A
// sampler reads them as a Chebyshev bound on whether a point at distance d in a texel's
// direction is visible from the probe (probebake/volume/probe_sampler.h, ProbeVisibility).
// Inverse distances rather than DDGI's distances: see InverseDistance.//
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
#include <cstdint>

#include "probebake/bake/probe_volume.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake {

inline constexpr int kVisibilityMapSize = 8;
inline constexpr int kVisibilityTexels = kVisibilityMapSize * kVisibilityMapSize;
// The fewest samples per probe whose moments the leak tests hold to (4 rays a texel on average):
// below, a bake with visibility warns (tests/volume/probe_sampler_test.cpp, Leak.*).
inline constexpr int64_t kMinVisibilitySamples = 4 * kVisibilityTexels;

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

// The texel (column, row) with the octahedral map's border wrapped: a step off an edge lands on
// the mirrored texel of the same edge (the edge's two halves are the same directions), a corner
// on the opposite corner (all four are the -Z pole).
inline int WrappedTexel(int column, int row) {
  constexpr int n = kVisibilityMapSize;
  if (column < 0 || column >= n) {
    column = column < 0 ? 0 : n - 1;
    row = n - 1 - row;
  }
  if (row < 0 || row >= n) {
    row = row < 0 ? 0 : n - 1;
    column = n - 1 - column;
  }
  return row * n + column;
}

// The unit direction at octahedral coordinates (u, v) in [-1, 1]^2 (the inverse of
// OctahedralEncode).
inline Vec3d OctahedralDecode(double u, double v) {
  Vec3d w(u, v, 1 - std::abs(u) - std::abs(v));
  if (w.z < 0) {
    w.x = (1 - std::abs(v)) * (u >= 0 ? 1 : -1);
    w.y = (1 - std::abs(u)) * (v >= 0 ? 1 : -1);
  }
  return Normalize(w);
}

// The unit direction through the centre of texel t.
inline Vec3d VisibilityTexelCentre(int t) {
  const auto centre = [](int i) { return (i + 0.5) / kVisibilityMapSize * 2 - 1; };
  return OctahedralDecode(centre(t % kVisibilityMapSize), centre(t / kVisibilityMapSize));
}

// The four texels around unit direction w, bilinear between texel centres, and their weights
// (summing to 1).
struct VisibilityTaps {
  int texel[4];
  double weight[4];
  bool wrapped = false;  // a tap lies across the map's border (the direction is near its seam)
};
inline VisibilityTaps VisibilityBilinear(const Vec3d& w) {
  double u, v;
  OctahedralEncode(w, &u, &v);
  const double fu = (u + 1) * 0.5 * kVisibilityMapSize - 0.5;
  const double fv = (v + 1) * 0.5 * kVisibilityMapSize - 0.5;
  const int i = int(std::floor(fu)), j = int(std::floor(fv));
  const double a = fu - i, b = fv - j;
  VisibilityTaps taps;
  for (int k = 0; k < 4; ++k) {
    const int di = k & 1, dj = k >> 1;
    taps.texel[k] = WrappedTexel(i + di, j + dj);
    taps.wrapped = taps.wrapped || i + di < 0 || i + di >= kVisibilityMapSize || j + dj < 0 ||
                   j + dj >= kVisibilityMapSize;
    taps.weight[k] = (di ? a : 1 - a) * (dj ? b : 1 - b);
  }
  return taps;
}

// The inverse first-hit distance s = 1 / t a ray adds to its texel's moments: 0 for a miss or a
// hit beyond maxDistance (free as far as any sampler asks), t floored at 1e-6 maxDistance.
// Why 1/t and not t: over a texel's footprint the distance to a plane varies as 1 / cos, without
// bound at grazing angles, while 1/t is linear in the direction (dot(w, n) / h for the plane at
// distance h with normal n), so a texel's mean is the plane's value at its rays' mean direction
// and interpolation between texels stays on the plane.
inline double InverseDistance(double t, double maxDistance) {
  return t > maxDistance ? 0.0 : 1 / std::max(t, 1e-6 * maxDistance);
}

// The distance beyond which a hit counts as a miss (s = 0): twice the diagonal of a grid cell,
// farther than any point a sampler asks a probe about (at most a cell diagonal plus relocation
// offsets of half a spacing each).
inline double VisibilityMaxDistance(const ProbeGrid& grid) {
  return 2 * Length(grid.spacing);
}

// The variance ProbeVisibility leaves at least, relative to the squared mean: a standard
// deviation of 7.7% of s. A point on a surface the probe sees has s = mean only where the texel
// holds one plane; in a concave corner (a floor at a wall's foot) the texel's mean mixes the
// nearer wall in, a few percent above the point's s, and a floor of 1% hid such points from the
// probes that see them (a leak of 35% at the foot of the README's thin wall). Larger floors let
// points beyond a thin wall through: at 1e-2 a point 4 cm beyond a 4 cm wall 0.25 away passes
// the 0.04 the tests allow. Measured between (test Visibility.*, Leak.*; README "Light leaks").
inline constexpr double kVisibilityMinRelativeVariance = 6e-3;

inline double VisibilityL1(const Vec3d& w) {
  return std::abs(w.x) + std::abs(w.y) + std::abs(w.z);
}

// The mean and variance of s = 1/t that probe `probe` of `volume` saw around unit direction w:
// the moments of the four texels around w, bilinear between texel centres in the octahedral map
// (each texel's s scaled by 1 / |centre|_1, which makes a plane's s linear in the map's
// coordinates, and the blend scaled back by |w|_1; raw s where a tap lies across the map's seam,
// whose mirrored taps do not surround w in the map), texels no ray went through left out; the
// variance is the texels' own, less what the trend between them explains, and at least
// kVisibilityMinRelativeVariance times the mean^2. False when no ray went through any of them.
inline bool VisibilityMoments(const ProbeVolume& volume, int64_t probe, const Vec3d& w,
                              double* meanOut, double* varianceOut) {
  const VisibilityTaps taps = VisibilityBilinear(w);
  double weight[4], total = 0;
  for (int k = 0; k < 4; ++k) {
    const bool seen = volume.visibility[size_t(taps.texel[k])][3 * size_t(probe) + 2] > 0;
    weight[k] = seen ? taps.weight[k] : 0.0;
    total += weight[k];
  }
  if (!(total > 0)) return false;
  double mean = 0, variance = 0, q[4];
  for (int k = 0; k < 4; ++k) {
    const float* m = &volume.visibility[size_t(taps.texel[k])][3 * size_t(probe)];
    const double scale =
        taps.wrapped ? 1.0 : 1 / VisibilityL1(VisibilityTexelCentre(taps.texel[k]));
    q[k] = scale * m[0];
    weight[k] /= total;
    mean += weight[k] * q[k];
    variance += weight[k] * scale * scale * std::max(double(m[1]) - double(m[0]) * m[0], 0.0);
  }
  // An empty texel takes the others' mean: no trend through it.
  for (int k = 0; k < 4; ++k)
    if (weight[k] == 0) q[k] = mean;
  // Less the part of the texels' spread that the trend between them explains (a linear ramp
  // across a texel has variance gradient^2 / 12 per axis): interpolated, it is no uncertainty.
  const double wu = taps.weight[1] + taps.weight[3], wv = taps.weight[2] + taps.weight[3];
  const double gu = (q[1] - q[0]) * (1 - wv) + (q[3] - q[2]) * wv;
  const double gv = (q[2] - q[0]) * (1 - wu) + (q[3] - q[1]) * wu;
  variance =
      std::max(variance - (gu * gu + gv * gv) / 12, kVisibilityMinRelativeVariance * mean * mean);
  const double scale = taps.wrapped ? 1.0 : VisibilityL1(w);
  *meanOut = mean * scale;
  *varianceOut = variance * scale * scale;
  return true;
}

// Chebyshev's visibility, in [0, 1], of a point at distance d > 0 where the moments of s = 1/t
// are (mean, variance): 1 when 1/d >= mean (the point nearer than the surfaces seen that way),
// else the one-sided bound p = var / (var + (mean - 1/d)^2), cubed as DDGI does.
inline double ChebyshevVisibility(double mean, double variance, double d) {
  const double s = 1 / d;
  if (s >= mean) return 1;
  const double excess = mean - s;
  const double p = variance / (variance + excess * excess);
  return p * p * p;
}

// The visibility, in [0, 1], of point x from probe `probe` of `volume` (which must have
// visibility moments) baked at probePos (grid point + offset): ChebyshevVisibility of the
// moments around the direction to x (VisibilityMoments), 1 where no ray went that way.
inline double ProbeVisibility(const ProbeVolume& volume, int64_t probe, const Vec3d& probePos,
                              const Vec3d& x) {
  const Vec3d fromProbe = x - probePos;
  const double d = Length(fromProbe);
  if (!(d > 0)) return 1;
  double mean, variance;
  if (!VisibilityMoments(volume, probe, fromProbe / d, &mean, &variance)) return 1;
  return ChebyshevVisibility(mean, variance, d);
}

}  // namespace probebake
