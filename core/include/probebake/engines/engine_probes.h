// The per-probe data every engine export and the viewer start from (docs/engines.md): one record
// per baked probe, in probebake's own frame (right-handed, Z up) and SH basis (sh_basis.h).
//
// This is the single place that decides what an engine sees of a probe: where it was baked (grid
// point + relocation offset) and its radiance SH, measured or filled by dilation; every export
// follows.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "probebake/bake/probe_volume.h"
#include "probebake/base/status.h"
#include "probebake/math/vec3.h"

namespace probebake {

struct EngineProbe {
  int64_t index = 0;  // ProbeGrid::LinearIndex of the grid point
  int i = 0, j = 0, k = 0;
  Vec3d position;  // where the probe was baked: grid point + offset; scene units, probebake frame
  Vec3d offset;    // the relocation offset (0 without relocation)
  // Radiance SH of order 2 (9 RGB coefficients, sh_basis.h), in radiance units: the volume's
  // radiance_sh_00..08. A volume of order < 2 leaves the missing bands 0; bands above 2 are
  // dropped (engines read L2).
  std::array<Vec3d, 9> radiance{};
  float validity = 0;     // the volume's validity
  float stdError = 0;     // relative standard error of the irradiance (+inf: unknown)
  float sampleCount = 0;  // sample paths taken
  bool filled = false;    // radiance filled from neighbours by dilation (validity 0)
  // Whether engines get this probe: validity >= 0.5 or filled (the probes the core's sampler
  // reads).
  bool usable = false;
};

// Every active (baked) probe of `volume`, in linear index order. INVALID_ARGUMENT naming the plane
// when the volume's planes do not match its grid.
absl::StatusOr<std::vector<EngineProbe>> EngineProbes(const ProbeVolume& volume);

}  // namespace probebake
