// Dilation (docs/volume-format.md, `filled`): radiance for the probes relocation could not move
// out of geometry, from their neighbours, as Unity's APV dilation and DDGI's inactive probes
// do, so that an engine interpolating the volume never blends in the black of a probe inside a
// wall.
//
// Every active probe with validity 0 is refilled from scratch, in passes: at pass k, each such
// probe not filled yet whose 26 lattice neighbours include active sources (probes with validity
// 1, or filled at an earlier pass) takes the weighted mean of their radiance SH (and irradiance
// SH when the volume has them), weights
//   w = V / d^2,
// d the distance from the source's baked position (grid point + offset) to the probe's grid
// point + offset, V the source's visibility of that point (ProbeVisibility,
// probebake/volume/visibility_map.h) floored at 1e-6 (DDGI's floor: a probe inside a solid is
// hidden from every neighbour, and then distance alone decides), or 1 without visibility
// moments. It is flagged filled (1). Passes stop when one fills nothing; probes no source
// reaches keep their baked values, flag 0. Other values (validity, std_error, sample_count,
// offset, visibility) stay as baked.
//
// A filled probe's value is a function of the sources alone, never of its own baked value, so
// dilating the merge of sharded parts gives the whole grid's bits: MergeProbeVolumes dilates
// again what the parts dilated, each part having seen only its own neighbours.
#pragma once

#include "probebake/bake/probe_volume.h"

namespace probebake {

// Dilates `volume` in place: requires volume->filled sized to the probe count (its old flags
// are ignored and rewritten). Returns the number of probes filled.
int64_t DilateProbes(ProbeVolume* volume);

}  // namespace probebake
