#include "light_visibility.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>

#include "light_set.h"
#include "probe_integrator.h"
#include "probebake/sampling/sampler.h"
#include "tracer_scene.h"

namespace probebake {
namespace {

// The stream key of the table's rays: fixed, so the factors depend on the scene alone.
constexpr uint64_t kVisibilityKey = 0x6c69676874766973;  // "lightvis"
// Cells along the box's longest axis, at most.
constexpr int kMaxCellsPerAxis = 32;

}  // namespace

LightVisibility LightVisibility::Build(const Vec3d& loIn, const Vec3d& hiIn, size_t entries,
                                       const Trace& trace) {
  LightVisibility v;
  if (entries < 2) return v;
  double longest = 0;
  for (int a = 0; a < 3; ++a) {
    if (!(hiIn[a] >= loIn[a])) return v;  // empty
    longest = std::max(longest, hiIn[a] - loIn[a]);
  }
  if (!(longest > 0) || !std::isfinite(longest)) return v;

  // Cubic cells, as many as the ray budget allows; flat axes (a single floor) get one layer a
  // cell thick, centred on them.
  int perAxis = kMaxCellsPerAxis;
  for (;; perAxis = std::max(1, perAxis / 2)) {
    const double size = longest / perAxis;
    int64_t cells = 1;
    for (int a = 0; a < 3; ++a)
      cells *= std::max<int64_t>(1, int64_t(std::ceil((hiIn[a] - loIn[a]) / size)));
    if (cells * int64_t(entries) * kRaysPerCell <= kRayBudget || perAxis == 1) break;
  }
  const double size = longest / perAxis;
  // The box reaches at least 2^-20 of its size past the geometry's bounds on every side: bounce
  // vertices lie on the walls and floors that make its faces, and points rounded a few ulps
  // outside fell out of a 1e-3-wide room's table altogether (there importance went unweighed).
  const double margin = longest * 0x1p-20;
  Vec3d lo, hi;
  for (int a = 0; a < 3; ++a) {
    const double extent = hiIn[a] - loIn[a];
    v.dims_[a] = std::max(1, int(std::ceil(extent / size)));
    const double pad = std::max(margin, (v.dims_[a] * size - extent) / 2);
    lo[a] = loIn[a] - pad;
    hi[a] = hiIn[a] + pad;
    v.inverseSize_[a] = v.dims_[a] / (hi[a] - lo[a]);
  }
  v.lo_ = lo;
  v.entries_ = entries;
  const int64_t cellCount = int64_t(v.dims_[0]) * v.dims_[1] * v.dims_[2];
  v.factors_.assign(size_t(cellCount) * entries, 1.0f);

  std::atomic<int64_t> rays{0};
  tbb::parallel_for(tbb::blocked_range<int64_t>(0, cellCount, 16),
                    [&](const tbb::blocked_range<int64_t>& range) {
                      int64_t traced = 0;
                      for (int64_t cell = range.begin(); cell != range.end(); ++cell) {
                        const int ix = int(cell % v.dims_[0]);
                        const int iy = int(cell / v.dims_[0] % v.dims_[1]);
                        const int iz = int(cell / (int64_t(v.dims_[0]) * v.dims_[1]));
                        IndependentSampler sampler(kVisibilityKey, uint64_t(cell));
                        for (size_t e = 0; e < entries; ++e) {
                          int arrived = 0, counted = 0;
                          for (int r = 0; r < kRaysPerCell; ++r) {
                            sampler.StartSample(uint64_t(e) * kRaysPerCell + uint64_t(r));
                            const Vec2d a = sampler.Get2D();
                            const Vec2d b = sampler.Get2D();
                            const Vec2d c = sampler.Get2D();
                            const Vec3d x{lo.x + (ix + a.x) / v.inverseSize_.x,
                                          lo.y + (iy + a.y) / v.inverseSize_.y,
                                          lo.z + (iz + b.x) / v.inverseSize_.z};
                            const double u[3] = {b.y, c.x, c.y};
                            const int result = trace(e, x, u);
                            if (result < 0) continue;
                            ++traced;
                            ++counted;
                            arrived += result;
                          }
                          // cell = (iz * ny + iy) * nx + ix, as At() computes it.
                          if (counted > 0) {
                            v.factors_[size_t(cell) * entries + e] =
                                float(kFloor + (1 - kFloor) * double(arrived) / counted);
                          }
                        }
                      }
                      rays.fetch_add(traced, std::memory_order_relaxed);
                    });
  v.rays_ = rays.load();
  return v;
}

LightVisibility LightVisibility::Build(const TracerScene& tracer, const LightSet& lights,
                                       const ProbeIntegrator& integrator) {
  return Build(tracer.boundsMin(), tracer.boundsMax(), lights.ImportanceSize(),
               [&](size_t entry, const Vec3d& x, const double u[3]) {
                 LightSample s;
                 if (!lights.SampleEntry(entry, x, u[0], {u[1], u[2]}, &s)) return -1;
                 TraceCounters unused;  // Build counts the rays
                 const Vec3d arrived = integrator.ShadowTransmittance(Vec3f(x), s, &unused);
                 return MaxComponent(arrived) > 0 ? 1 : 0;
               });
}

}  // namespace probebake
