#include "probebake/engines/engine_probes.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "probebake/sh/sh_basis.h"

namespace probebake {

absl::StatusOr<std::vector<EngineProbe>> EngineProbes(const ProbeVolume& volume) {
  const ProbeGrid& g = volume.grid;
  const size_t n = static_cast<size_t>(g.ProbeCount());
  auto sizeError = [&](const char* plane, size_t got, size_t want) {
    return absl::InvalidArgumentError(
        absl::StrCat("volume: ", plane, ": ", got, " values for ", want, " probes"));
  };
  if (volume.active.size() != n) return sizeError("active", volume.active.size(), n);
  if (volume.validity.size() != n) return sizeError("validity", volume.validity.size(), n);
  if (volume.shOrder < 0 || static_cast<int>(volume.radiance.size()) != volume.CoeffCount())
    return absl::InvalidArgumentError(absl::StrCat("volume: radiance: ", volume.radiance.size(),
                                                   " planes for order ", volume.shOrder));
  for (const std::vector<float>& plane : volume.radiance)
    if (plane.size() != 3 * n) return sizeError("radiance", plane.size() / 3, n);
  const int coeffs = std::min(volume.CoeffCount(), ShCoeffCount(2));
  std::vector<EngineProbe> probes;
  for (size_t p = 0; p < n; ++p) {
    if (!volume.active[p]) continue;
    EngineProbe probe;
    probe.index = static_cast<int64_t>(p);
    g.Coords(probe.index, &probe.i, &probe.j, &probe.k);
    if (volume.offset.size() == 3 * n)
      probe.offset = {volume.offset[3 * p], volume.offset[3 * p + 1], volume.offset[3 * p + 2]};
    probe.position = g.Position(probe.i, probe.j, probe.k) + probe.offset;
    for (int c = 0; c < coeffs; ++c)
      probe.radiance[c] = {volume.radiance[c][3 * p], volume.radiance[c][3 * p + 1],
                           volume.radiance[c][3 * p + 2]};
    probe.validity = volume.validity[p];
    probe.stdError = p < volume.stdError.size() ? volume.stdError[p] : 0.0f;
    probe.sampleCount = p < volume.sampleCount.size() ? volume.sampleCount[p] : 0.0f;
    probe.filled = volume.filled.size() == n && volume.filled[p] > 0.5f;
    probe.usable = probe.validity >= 0.5f || probe.filled;
    probes.push_back(probe);
  }
  return probes;
}

}  // namespace probebake
