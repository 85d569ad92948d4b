// Where the environment reaches each region of a scene: per cell of a grid over the geometry, a
// histogram of the directions through which the sky arrives, which the environment's next-event
// samples are partly drawn from.
//
// Why: inside a room lit through a window, the environment's own distribution (its luminance x
// solid angle) sends nearly every next-event sample into a wall; the few directions through the
// window carry all the sky's light a point receives, and paths that find them by chance made
// most of the demo room's remaining variance after the sun's (docs/performance-history.md). The
// light-visibility table (light_visibility.h) only lowers how often the sky is chosen there; this
// makes the samples it still takes arrive.
//
// A pilot of kPilotRays rays from random points of the scene's box first measures the share of
// the environment's light that arrives; where it is most of it (an open courtyard, a landscape)
// nothing is built. Otherwise each cell of a grid over the box traces kRaysPerCell rays from
// random points of the cell, and adds f / q to the bin of each, f the luminance that arrives (0
// when blocked) and q the density its direction was drawn from: an estimate of the light each
// bin of directions brings. The first kFirstStageRays rays of every cell sample as the
// environment does (q = p_e); the rest, half from what those found in the cell and its
// neighbours, so that a small opening's bins get rays of their own. Bins are kZBins x kPhiBins
// equal-area cells of the sphere (z = cos theta of the local frame, phi about +z), solid angle
// 4 pi / kBins each; each bin also lends kNeighbourWeight of its weight to its 8 neighbours. The
// guide samples a bin by its weight and a direction uniform in it, pdf p_g. The environment then
// samples the mixture
//   p(wi) = alpha p_g(wi) + (1 - alpha) p_e(wi)
// (EnvironmentEmitter), so every direction it could sample before keeps a positive density and
// the estimator stays unbiased whatever the histogram's noise. alpha is chosen per cell among
// kAlphas: the one whose second moment of f / p, estimated from the cell's own rays with each
// ray left out of the histogram it is scored against, is least (a cell whose rays mostly
// arrive keeps 0; so does a sparse histogram, or a bright sun in the map the bins would blur).
//
// Surfaces only: the environment's samples at a probe (no normal) and in a medium are its own.
// At the probe the environment is the first vertex of the Sobol sequence, whose stratified
// directions integrate the sky's edges faster than n^-1/2; the mixture's choice between the two
// densities and the bins' inverse CDF break that stratification, and in a test box at 8192
// samples the guide there doubled the probes' error near the window. At surface vertices, deep
// in the sequence's dimensions, it cut a floor point's variance of the sky's irradiance to 0.28.
//
// Deterministic: each cell's rays come from its own stream (a fixed key and the cell's index), so
// the guide depends on the scene alone, never the grid, seed, thread count or sharding.
// Immutable once built; const methods may be called from any thread.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <numbers>
#include <vector>

#include "cell_grid.h"
#include "probebake/math/vec3.h"
#include "probebake/sampling/distribution.h"

namespace probebake {

class EnvironmentLight;
class ProbeIntegrator;
class TracerScene;

class EnvironmentGuide {
 public:
  static constexpr int kZBins = 8;
  static constexpr int kPhiBins = 16;
  static constexpr int kBins = kZBins * kPhiBins;
  static constexpr int kRaysPerCell = 512;
  // The first kFirstStageRays of every cell's rays are sampled as the environment samples; the
  // rest half from the histogram of those rays around the cell, so that a small opening's bins,
  // which few of the first rays find, are learned from rays of their own.
  static constexpr int kFirstStageRays = 128;
  // At most this many rays in all: cells are cubes, as many as fit (8 x 6 x 3 in the demo room).
  static constexpr int64_t kRayBudget = int64_t{1} << 17;
  // The guide is built only when less than kOpenFraction of the environment's light arrives along
  // kPilotRays rays from random points of the box (below); where it reaches most of the scene
  // there is little to learn, and the cells' rays would cost more than they save. The pilot's
  // share has a standard error of at most 2.7% near kOpenFraction (the demo room reads 0.031, the
  // closed-form scene 0.53, the courtyard 0.68), and its rays are all an open scene pays.
  static constexpr int kPilotRays = 256;
  // A cell where this fraction of the environment's light arrives along its first
  // kPilotRaysPerCell rays is open: the environment's own sampling is left alone there, and the
  // rest of its rays are not traced.
  static constexpr int kPilotRaysPerCell = 64;
  static constexpr double kOpenFraction = 0.25;
  // Each bin's weight, learned from a few hundred rays, is also added, times this, to its 8
  // neighbours: a bin of an opening that no ray found would have guided density 0 there, and a
  // sample the environment's own sampling draws there would weigh 1 / (1 - alpha) times more
  // than without the guide (in a 4 x 4 x 3 m box with a small window, up to 2.3 times the
  // variance at some floor points; with the spread, 0.28 of it on average, against 0.63).
  static constexpr double kNeighbourWeight = 0.1;
  // A cell's histogram is used only when this many of its rays arrived (else those of the cells
  // around it).
  static constexpr int kMinArrived = 8;
  static constexpr std::array<double, 4> kAlphas = {0.0, 0.25, 0.5, 0.75};

  // One training ray from x along *wi, or when wi is null along a direction the environment
  // samples with u: the direction, the environment's pdf of it per steradian (0: nothing
  // sampled), the luminance of the radiance from there and of what arrives (times the
  // transmittance; 0 when blocked).
  struct Ray {
    Vec3d wi;
    double pdf = 0;
    double emitted = 0, arrived = 0;
  };
  using Trace = std::function<Ray(const Vec3d& x, const Vec3d* wi, const Vec2d& u)>;

  // A guide over the box [lo, hi] (local coordinates) from `trace`, called from several threads
  // at once. An empty or infinite box gives a guide whose Alpha is 0 everywhere.
  static EnvironmentGuide Build(const Vec3d& lo, const Vec3d& hi, const Trace& trace);
  // The guide of a bake: over the tracer's geometry bounds, rays sampled from `environment` and
  // traced by `integrator` (its medium attenuates).
  static EnvironmentGuide Build(const TracerScene& tracer, const EnvironmentLight& environment,
                                const ProbeIntegrator& integrator);

  // The mixture weight at p (0 outside the box or where the cell keeps the environment's own
  // sampling), and when it is positive the cell for Sample and Pdf.
  double Alpha(const Vec3d& p, int32_t* cell) const {
    if (alpha_.empty()) return 0;
    const int64_t c = grid_.CellOf(p);
    if (c < 0) return 0;
    *cell = int32_t(c);
    return alpha_[size_t(c)];
  }
  // A direction of cell `cell` (Alpha > 0) for u in [0, 1)^2, distributed as p_g. Its density is
  // Pdf(cell, wi): computed from the direction, as for one a ray found, so the two agree.
  Vec3d Sample(int32_t cell, const Vec2d& u) const;
  // p_g of wi (unit) in cell `cell` (Alpha > 0).
  double Pdf(int32_t cell, const Vec3d& wi) const {
    return bins_[size_t(cell)].Pmf(Bin(wi)) * kInverseBinSolidAngle;
  }

  // For logs and tests: the pilot's fraction of the environment's light that arrived (whether
  // the cells were traced: below kOpenFraction), cells per axis (0 when empty), cells that guide
  // (alpha > 0), and rays traced.
  double OpenFraction() const { return openFraction_; }
  int dims(int axis) const { return grid_.dims[axis]; }
  int64_t GuidedCells() const;
  int64_t rays() const { return rays_; }

  // The bin of unit direction wi, and the inverse of a bin's solid angle.
  static int Bin(const Vec3d& wi);
  static constexpr double kInverseBinSolidAngle = kBins / (4 * std::numbers::pi);

 private:
  CellGrid grid_;
  std::vector<float> alpha_;  // per cell
  // Per cell, the bins' distribution (a single bin for cells whose alpha is 0).
  std::vector<DiscreteDistribution> bins_;
  double openFraction_ = 0;
  int64_t rays_ = 0;
};

}  // namespace probebake
