#include "probebake/bake/probe_dilation.h"

#include <algorithm>
#include <vector>

#include "probebake/base/check.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {
namespace {

// DDGI's weight floor: see probe_dilation.h.
constexpr double kMinVisibility = 1e-6;

Vec3d BakedAt(const ProbeVolume& v, int64_t p, int i, int j, int k) {
  Vec3d x = v.grid.Position(i, j, k);
  if (!v.offset.empty()) x += Vec3d(v.offset[3 * p], v.offset[3 * p + 1], v.offset[3 * p + 2]);
  return x;
}

}  // namespace

int64_t DilateProbes(ProbeVolume* volume) {
  ProbeVolume& v = *volume;
  const int64_t count = v.grid.ProbeCount();
  PB_CHECK_EQ(int64_t(v.filled.size()), count);
  // 0: measured (a source), 1: to fill, 2: filled at an earlier pass (a source), 3: just filled.
  std::vector<uint8_t> state(size_t(count), 0);
  for (int64_t p = 0; p < count; ++p) {
    v.filled[p] = 0.0f;
    if (v.active[p] && !(v.validity[p] >= 0.5f)) state[size_t(p)] = 1;
  }
  const int coeffs = v.CoeffCount();
  const bool irradiance = !v.irradiance.empty();
  int64_t total = 0;
  std::vector<double> sum(size_t(2 * 3 * coeffs));
  for (bool progress = true; progress;) {
    progress = false;
    for (int64_t p = 0; p < count; ++p) {
      if (state[size_t(p)] != 1) continue;
      int i, j, k;
      v.grid.Coords(p, &i, &j, &k);
      const Vec3d x = BakedAt(v, p, i, j, k);
      std::fill(sum.begin(), sum.end(), 0.0);
      double weights = 0;
      for (int dk = -1; dk <= 1; ++dk)
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            const int a = i + di, b = j + dj, c = k + dk;
            if ((di | dj | dk) == 0 || a < 0 || b < 0 || c < 0 || a >= v.grid.counts[0] ||
                b >= v.grid.counts[1] || c >= v.grid.counts[2])
              continue;
            const int64_t q = v.grid.LinearIndex(a, b, c);
            const uint8_t s = state[size_t(q)];
            if (!v.active[q] || !(s == 0 || s == 2)) continue;
            const Vec3d y = BakedAt(v, q, a, b, c);
            const double d2 = LengthSquared(x - y);
            if (!(d2 > 0)) continue;
            const double visibility =
                v.visibility.empty() ? 1.0 : std::max(ProbeVisibility(v, q, y, x), kMinVisibility);
            const double w = visibility / d2;
            weights += w;
            for (int e = 0; e < coeffs; ++e)
              for (int ch = 0; ch < 3; ++ch) {
                sum[size_t(3 * e + ch)] += w * v.radiance[size_t(e)][size_t(3 * q + ch)];
                if (irradiance)
                  sum[size_t(3 * (coeffs + e) + ch)] +=
                      w * v.irradiance[size_t(e)][size_t(3 * q + ch)];
              }
          }
      if (!(weights > 0)) continue;
      for (int e = 0; e < coeffs; ++e)
        for (int ch = 0; ch < 3; ++ch) {
          v.radiance[size_t(e)][size_t(3 * p + ch)] = float(sum[size_t(3 * e + ch)] / weights);
          if (irradiance)
            v.irradiance[size_t(e)][size_t(3 * p + ch)] =
                float(sum[size_t(3 * (coeffs + e) + ch)] / weights);
        }
      v.filled[p] = 1.0f;
      state[size_t(p)] = 3;
      ++total;
      progress = true;
    }
    for (uint8_t& s : state)
      if (s == 3) s = 2;
  }
  return total;
}

}  // namespace probebake
