// Structural validation of a job (docs/job-format.md): every check that needs no asset bytes, so
// bad input is rejected before anything is uploaded or baked. BuildBakeJob runs it first; the
// server runs it in CreateBakeJob; the CLI runs it before uploading.
//
// Checked: NaN or infinity in any number; vector lengths (3 for points, directions and RGB, 16
// for transforms); negative radiance, intensity, irradiance, emission and medium coefficients;
// albedo outside [0, 1); zero-area rect lights (an edge of zero length, or parallel edges); zero
// radius; zero directions and normals; spot cone angles out of order; degenerate transforms (a
// singular 3x3 part or a last row other than (0, 0, 0, 1)); inline positions and indices (lengths,
// indices in range); mesh sources (exactly one of file, blob, positions; a known format; relative
// paths; well-formed digests); material names (present, unique, every mesh's material defined);
// the environment (exactly one kind, scale >= 0); the medium (|g| < 1); the grid (min <= max,
// exactly one of counts (each >= 1) or spacing (a number or three, each > 0), several probes on an
// axis of zero extent, surfaceDistance > 0 for NEAR_SURFACES); settings ranges and enums; the
// window needing irradiance; and the limits that are known without assets (probes, SH order,
// samples, depth, lights, inline triangles, blob sizes).
//
// The result is OK or INVALID_ARGUMENT with one "<field path>: <reason>" line per error found
// (joined by "\n", at most 50, the first error first), e.g.
//   scene.lights[2].rect.edge1: zero length
//   grid.max[1]: less than grid.min[1] (-1 < 0)
// Paths use the JSON names of job.proto (lowerCamelCase) and array indices.
#pragma once

#include "absl/status/status.h"
#include "probebake/job/limits.h"
#include "probebake/v1/job.pb.h"

namespace probebake {

absl::Status ValidateJobSpec(const v1::JobSpec& job, const JobLimits& limits);

}  // namespace probebake
