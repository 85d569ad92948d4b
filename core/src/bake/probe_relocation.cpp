#include "probe_relocation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "probebake/sampling/hash.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "ray_offset.h"

namespace probebake {
namespace {

// Stream id of the validity rays, outside the range of batch ids.
constexpr uint64_t kValidityStream = ~uint64_t{0};
// Radii of the search: R k / kRadii, k = 1..kRadii.
constexpr int kRadii = 8;

// The 26 lattice directions, normalised: faces, edges, corners, each group in a fixed order.
std::array<Vec3d, 26> SearchDirections() {
  std::array<Vec3d, 26> dirs;
  int n = 0;
  for (int nonZero = 1; nonZero <= 3; ++nonZero) {
    for (int x = -1; x <= 1; ++x)
      for (int y = -1; y <= 1; ++y)
        for (int z = -1; z <= 1; ++z) {
          if (std::abs(x) + std::abs(y) + std::abs(z) != nonZero) continue;
          dirs[n++] = Normalize(Vec3d(x, y, z));
        }
  }
  return dirs;
}

}  // namespace

bool ProbeValid(const TracerScene& tracer, const BakeSettings& settings, const Vec3d& origin,
                uint64_t key, int64_t* rays) {
  const Vec3f o(origin);
  SobolSampler sampler(settings.seed, Hash(key, kValidityStream));
  int backfaces = 0;
  for (int r = 0; r < kValidityRays; ++r) {
    sampler.StartSample(uint64_t(r));
    const Vec3d wi = SampleUniformSphere(sampler.Get2D());
    SurfaceHit hit;
    ++*rays;
    if (tracer.Intersect(o, wi, std::numeric_limits<double>::infinity(), &hit) &&
        hit.kind == SurfaceKind::kMesh && Dot(wi, hit.ng) > 0 && !tracer.DoubleSided(hit.index))
      ++backfaces;
  }
  return double(backfaces) <= settings.backfaceFraction * kValidityRays;
}

ProbeStart StartAt(const ProbeSites& sites, const TracerScene& tracer, const Vec3d& position) {
  const ProbeSite site = sites.At(position);
  ProbeStart start;
  start.p = TraceOrigin(tracer, site.local, &start.moves);
  start.key = site.key;
  return start;
}

ProbeRelocator::ProbeRelocator(const TracerScene& tracer, const ProbeSites& sites,
                               const BakeSettings& settings, const ProbeGrid& grid)
    : tracer_(tracer), sites_(sites), settings_(settings) {
  const double spacing = std::min({grid.spacing.x, grid.spacing.y, grid.spacing.z});
  maxOffset_ = settings.relocationMaxOffset * spacing;
  clearance_ = maxOffset_ / 4;
}

bool ProbeRelocator::WantsMove(const ProbeStart& start, bool valid) const {
  return Enabled() && (!valid || tracer_.MeshWithin(start.p, clearance_));
}

bool ProbeRelocator::MoveIsClear(const Vec3d& from, const Vec3d& to, bool leaving,
                                 int64_t* rays) const {
  const Vec3d d = to - from;
  const double length = Length(d);
  if (!(length > 0)) return true;
  const Vec3d dir = d / length;
  SurfaceHit hit;
  ++*rays;
  if (!tracer_.Intersect(Vec3f(from), dir, length, &hit)) return true;
  // A back face (the ray leaves through the side the normal points to) of an invalid probe's
  // solid; anything else is a wall or another solid's front.
  if (!leaving || Dot(dir, hit.ng) <= 0 || tracer_.DoubleSided(hit.index)) return false;
  const Vec3f past = OffsetRayOrigin(hit.p, hit.ng, hit.vertexScale);
  const double rest = Length(to - Vec3d(past));
  SurfaceHit again;
  ++*rays;
  return !tracer_.Intersect(past, dir, rest, &again);
}

bool ProbeRelocator::Find(const Vec3d& position, const ProbeStart& start, bool valid, Vec3f* offset,
                          int64_t* rays) const {
  static const std::array<Vec3d, 26> kDirections = SearchDirections();
  for (int k = 1; k <= kRadii; ++k) {
    const double r = maxOffset_ * k / kRadii;
    for (const Vec3d& dir : kDirections) {
      const Vec3f off(dir * r);
      const ProbeStart candidate = StartAt(sites_, tracer_, position + Vec3d(off));
      if (candidate.moves > 0 || tracer_.MeshWithin(candidate.p, clearance_)) continue;
      if (!MoveIsClear(start.p, candidate.p, !valid, rays)) continue;
      if (!ProbeValid(tracer_, settings_, candidate.p, candidate.key, rays)) continue;
      *offset = off;
      return true;
    }
  }
  return false;
}

}  // namespace probebake
