// A probe's identity in a bake: the point it is traced from and the key of its random streams, as
// a function of its world position and the scene alone. A grid split into sub-grids on the same
// lattice, baked on several machines, must merge to the same bits as the whole grid
// (docs/job-format.md, `grid`), so nothing about a probe may depend on its index in the grid or on
// the grid's extent (the tracer's local origin depends on the scene only, tracer_scene.h).
//
// A sub-grid computes its probes' positions from its own min (min + spacing * i), which can differ
// from the whole grid's in the last bits (0.3 + 0.8 * 2 != 1.9 in double). So each coordinate of
// the probe's local position x (world minus the local origin) is snapped to the nearest multiple
// of the power-of-two quantum q = 2^(max(ilogb(x), ilogb(extent)) - 30), extent being the largest
// local coordinate of the scene's finite bounds (1 when there are none):
//   - a probe moves by at most q / 2, at most 2^-31 of max(|x|, extent): 100 times finer than the
//     float resolution the tracer works at (docs/job-format.md, precision), so no bake can tell;
//   - two world positions d ulps apart snap to the same point unless they straddle a
//     half-quantum, with probability about d ulp(world) / q: 2^-22 d for a scene around the origin,
//     more for a small scene far from it (2^-15 d at 1e5 units with a 1e3 extent). Near a power of
//     two, where the quantum changes, both sides snap to that power of two.
// Probes closer together than q share a key (correlated noise, each still unbiased).
#pragma once

#include <cstdint>

#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake {

struct ProbeSite {
  Vec3d local;       // the snapped local position (traced from there, unless on a surface)
  uint64_t key = 0;  // hash of `local`'s bits: the key of the probe's random streams
};

class ProbeSites {
 public:
  // `offset`: the tracer's local origin, LocalOrigin(scene).
  ProbeSites(const Scene& scene, const Vec3d& offset);
  // The site of a probe at world position `position` (finite).
  ProbeSite At(const Vec3d& position) const;

 private:
  double Snap(double x) const;
  Vec3d offset_;
  int minExponent_;  // ilogb(extent) - 30
};

class TracerScene;

// Where a probe at local position `local` is traced from: `local` itself, unless it lies on a mesh
// surface (TracerScene::MeshSurfaceAt: closer than the tracer resolves). Such a probe, a grid
// point on a floor or wall being the common case, would start rays on either side of it and mix
// the two (a probe on a room's floor saw the outside below it: half its L0, its gradient
// reversed). It is moved off the surface to its front side, the side validity counts as outside,
// by the offset of a ray leaving that surface; at an edge or corner off each surface in turn.
// Counts the moves in `*moves`. A function of `local` and the scene alone, like the site.
Vec3d TraceOrigin(const TracerScene& tracer, const Vec3d& local, int* moves);

}  // namespace probebake
