// Merging the volumes of a sharded bake (docs/volume-format.md): sub-grids of one grid, each baked
// on its own (another machine, another job) with the same scene, settings and seed, into one
// volume. A probe's values depend only on the scene, the settings, the seed and the probe's
// position (core/src/bake/probe_site.h), so the merged volume holds exactly what one bake of the
// union grid would have produced at every probe the parts cover.
//
// The parts must agree on everything but their grids' extents, or the merge fails with
// INVALID_ARGUMENT "part <i> (<name>): <field>: <reason>": sh_order, has_irradiance, sh_window
// (AUTO: its kind; the summary is recombined), placement, surface distance, spacing (the exact
// doubles), samples_per_probe, max_depth, seed, scene_digest, settings and generator; each
// part's min must lie on the lattice of the first part's (min_0 + spacing * n, n integer, to
// 1e-6 of the spacing). Probes baked by two parts must be identical in every value.
//
// The merged grid is the bounding box of the parts: per axis its min is the lowest part's min
// (that part's exact double), its counts reach the highest part's last probe; probes no part
// covers are inactive; a bounding box of more than twice the parts' probes (plus 2^20) is
// refused as not one tiled grid. Stats: probes and invalidProbes count the merged volume's active
// probes and those of them with validity 0, as a bake counts its own (a probe two parts hold counts
// once); samples, rays and threads add up (the work of every machine: a probe baked twice counts
// twice); wallSeconds is the longest part's (parts run side by side). Parts with the AUTO window
// must not overlap, as its summary counts windowed probes. With dilation flags (relocation on) the
// merged volume is dilated again (probebake/bake/probe_dilation.h): a part filled its probes from
// its own neighbours only, so those values are neither compared between parts nor kept.
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/volume/vdb_io.h"

namespace probebake {

struct VolumePart {
  std::string name;  // for messages, e.g. the file's path
  ProbeVolumeFile file;
};

absl::StatusOr<ProbeVolumeFile> MergeProbeVolumes(std::vector<VolumePart> parts);

}  // namespace probebake
