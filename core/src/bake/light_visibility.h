// How much of each light reaches each region of a scene: the visibility factor of light selection.
//
// Light selection (light_set.h) picks a light in proportion to an importance that ignores
// occlusion, so in a room lit through a window the sun and the sky, bright but hidden from most of
// the room, drew 80% of next-event samples at the demo's probes and 92% of those met a wall, while
// the ceiling light, seen from everywhere, drew 11%. This is a grid of cells over the scene's
// geometry; each cell holds, for every entry of the linear choice, the fraction of shadow rays
// that arrive, traced from random points of the cell toward random points of the entry's light.
// LightSet scales an entry's importance at p by Factor = kFloor + (1 - kFloor) * fraction of p's
// cell. Any positive factor keeps the estimator unbiased (a light is still chosen wherever it
// could contribute, and MIS uses the same importance); the floor bounds the cost where a cell's
// fraction misleads (a cell straddling a wall, a sun patch smaller than a cell). The bench's
// errors with and without the table: docs/performance-history.md.
//
// Deterministic: each cell's rays come from its own stream, hashed from the cell's index and a
// fixed key, so the factors depend on the scene alone (not on the grid, seed, thread count or
// sharding).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "cell_grid.h"
#include "probebake/math/vec3.h"

namespace probebake {

class LightSet;
class ProbeIntegrator;
class TracerScene;

class LightVisibility {
 public:
  // The least factor: an entry no ray of a cell reached keeps 1/32 of its importance there (1/8
  // until baker version 21: with the environment guide's samples arriving, the lower floor cut
  // the demo room's variance by 8% and changed neither the courtyard's nor the closed-form
  // scene's; docs/performance-history.md).
  static constexpr double kFloor = 1.0 / 32;
  // Shadow rays per cell and entry.
  static constexpr int kRaysPerCell = 16;
  // At most this many rays in all (the cell count shrinks with the number of entries): 16 x 12 x 6
  // cells for the demo room's 3 entries. A finer table barely lowered the demo's error and cost
  // more than a small bake (docs/performance-history.md).
  static constexpr int64_t kRayBudget = int64_t{1} << 16;

  // One shadow ray from x toward light-choice entry `entry`, its point chosen by u (three numbers
  // in [0, 1)): 1 when it arrives, 0 when it is blocked, -1 when the entry cannot light x (not
  // counted).
  using Trace = std::function<int(size_t entry, const Vec3d& x, const double u[3])>;

  // Factors for `entries` choice entries over the box [lo, hi] (local coordinates; the bounds of
  // the scene's geometry), from `trace`, called from several threads at once. An empty box or
  // fewer than two entries (nothing to weigh against each other) give a table that At() never
  // matches. floor: the least factor, in (0, 1].
  static LightVisibility Build(const Vec3d& lo, const Vec3d& hi, size_t entries, const Trace& trace,
                               double floor = kFloor);

  // The table of a bake: over the tracer's geometry bounds, for `lights`' entries (sampled as
  // LightSet::SampleEntry does), shadow rays traced by `integrator` (its medium attenuates, and
  // counts as arriving unless it blocks all). `lights` is the set without a table; the bake's set
  // is then built from it with this one (LightSet(LightSet&&, LightVisibility)).
  static LightVisibility Build(const TracerScene& tracer, const LightSet& lights,
                               const ProbeIntegrator& integrator, double floor = kFloor);

  // The factors of p's cell, one per entry (in (0, 1]); nullptr outside the box, where importance
  // is left as it is.
  const float* At(const Vec3d& p) const {
    if (factors_.empty()) return nullptr;
    const int64_t cell = grid_.CellOf(p);
    return cell < 0 ? nullptr : factors_.data() + cell * int64_t(entries_);
  }

  // The rays Build traced, for the bake's count.
  int64_t rays() const { return rays_; }
  // Cells per axis (0 when the table is empty).
  int dims(int axis) const { return grid_.dims[axis]; }

 private:
  CellGrid grid_;
  size_t entries_ = 0;
  std::vector<float> factors_;  // cell-major: cell * entries + entry
  int64_t rays_ = 0;
};

}  // namespace probebake
