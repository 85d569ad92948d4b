#include "light_visibility.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>

#include "light_set.h"
#include "probe_integrator.h"
#include "probebake/sampling/sampler.h"
#include "tracer_scene.h"

namespace probebake {
namespace {

// The stream key of the table's rays: fixed, so the factors depend on the scene alone.
constexpr uint64_t kVisibilityKey = 0x6c69676874766973;  // "lightvis"

}  // namespace

LightVisibility LightVisibility::Build(const Vec3d& loIn, const Vec3d& hiIn, size_t entries,
                                       const Trace& trace, double floor) {
  LightVisibility v;
  if (entries < 2) return v;
  v.grid_ = CellGrid::Over(loIn, hiIn, kRayBudget / (int64_t(entries) * kRaysPerCell));
  if (v.grid_.Empty()) return v;
  v.entries_ = entries;
  const int64_t cellCount = v.grid_.Count();
  v.factors_.assign(size_t(cellCount) * entries, 1.0f);

  std::atomic<int64_t> rays{0};
  tbb::parallel_for(tbb::blocked_range<int64_t>(0, cellCount, 16),
                    [&](const tbb::blocked_range<int64_t>& range) {
                      int64_t traced = 0;
                      for (int64_t cell = range.begin(); cell != range.end(); ++cell) {
                        IndependentSampler sampler(kVisibilityKey, uint64_t(cell));
                        for (size_t e = 0; e < entries; ++e) {
                          int arrived = 0, counted = 0;
                          for (int r = 0; r < kRaysPerCell; ++r) {
                            sampler.StartSample(uint64_t(e) * kRaysPerCell + uint64_t(r));
                            const Vec2d a = sampler.Get2D();
                            const Vec2d b = sampler.Get2D();
                            const Vec2d c = sampler.Get2D();
                            const Vec3d x = v.grid_.Point(cell, {a.x, a.y, b.x});
                            const double u[3] = {b.y, c.x, c.y};
                            const int result = trace(e, x, u);
                            if (result < 0) continue;
                            ++traced;
                            ++counted;
                            arrived += result;
                          }
                          if (counted > 0) {
                            v.factors_[size_t(cell) * entries + e] =
                                float(floor + (1 - floor) * double(arrived) / counted);
                          }
                        }
                      }
                      rays.fetch_add(traced, std::memory_order_relaxed);
                    });
  v.rays_ = rays.load();
  return v;
}

LightVisibility LightVisibility::Build(const TracerScene& tracer, const LightSet& lights,
                                       const ProbeIntegrator& integrator, double floor) {
  return Build(
      tracer.boundsMin(), tracer.boundsMax(), lights.ImportanceSize(),
      [&](size_t entry, const Vec3d& x, const double u[3]) {
        LightSample s;
        if (!lights.SampleEntry(entry, x, u[0], {u[1], u[2]}, &s)) return -1;
        TraceCounters unused;  // Build counts the rays
        const Vec3d arrived = integrator.ShadowTransmittance(Vec3f(x), s, &unused);
        return MaxComponent(arrived) > 0 ? 1 : 0;
      },
      floor);
}

}  // namespace probebake
