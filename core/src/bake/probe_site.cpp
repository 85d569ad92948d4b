#include "probe_site.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include "probebake/sampling/hash.h"
#include "ray_offset.h"
#include "tracer_scene.h"

namespace probebake {

constexpr int kSnapBits = 30;

ProbeSites::ProbeSites(const Scene& scene, const Vec3d& offset) : offset_(offset) {
  Vec3d lo, hi;
  double extent = 1;
  if (FiniteSceneBounds(scene, &lo, &hi)) {
    const double m = std::max(MaxComponent(Abs(lo - offset)), MaxComponent(Abs(hi - offset)));
    if (m > 0) extent = m;
  }
  minExponent_ = std::ilogb(extent) - kSnapBits;
}

double ProbeSites::Snap(double x) const {
  if (x == 0) return 0;  // +0, also for -0: the key hashes bits
  const int e = std::max(minExponent_, std::ilogb(x) - kSnapBits);
  // Scaling by powers of two is exact, and so is rounding to an integer: the result is exactly
  // the nearest multiple of 2^e (ties to even). + 0.0 turns a -0 result into +0.
  return std::ldexp(std::nearbyint(std::ldexp(x, -e)), e) + 0.0;
}

ProbeSite ProbeSites::At(const Vec3d& position) const {
  const Vec3d local = position - offset_;
  ProbeSite site;
  site.local = {Snap(local.x), Snap(local.y), Snap(local.z)};
  site.key = Hash(std::bit_cast<uint64_t>(site.local.x), std::bit_cast<uint64_t>(site.local.y),
                  std::bit_cast<uint64_t>(site.local.z));
  return site;
}

Vec3d TraceOrigin(const TracerScene& tracer, const Vec3d& local, int* moves) {
  // Three surfaces at most meet at a grid point that matters (a room's corner); more would be a
  // degenerate vertex, left where the third move puts it.
  constexpr int kMaxMoves = 3;
  Vec3d p = local;
  *moves = 0;
  SurfaceHit on;
  while (*moves < kMaxMoves && tracer.MeshSurfaceAt(p, &on)) {
    p = Vec3d(OffsetRayOrigin(on.p, on.ng, on.vertexScale));
    ++*moves;
  }
  return p;
}

}  // namespace probebake
