// References the benchmark measures errors against: the exact projection where a closed
// form exists, otherwise a bake with at least 64x the samples of anything compared with it,
// cached on disk under its job digest (which includes the baker version, so a baker change that
// alters numbers invalidates it).
//
// A reference is baked with its own seed, distinct from the seed of the bakes it judges: bakes
// with the same seed share random streams (batch b of every bake of a probe starts with the same
// samples), which would correlate their errors and hide part of them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "bench_scenes.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"
#include "probebake/v1/job.pb.h"

namespace probebake::bench {

struct Reference {
  bool exact = false;           // closed form: no error of its own
  int order = 0;                // SH order of `radiance` (truncate for lower orders)
  int64_t samplesPerProbe = 0;  // baked references
  int maxDepth = 0;
  int batches = 0;
  uint64_t seed = 0;
  std::string jobDigest;
  double bakeSeconds = 0;  // wall time of the bake that produced it (when it was baked)
  bool fromCache = false;
  // Per grid probe (ProbeGrid::LinearIndex): 1 when the reference has a value there.
  std::vector<uint8_t> active;
  std::vector<std::vector<Vec3d>> radiance;  // [probe][coefficient] RGB
  std::vector<std::vector<Vec3d>> stdError;  // same layout, absolute; zero when exact
  // Its std_error and std_error_l0 (probe_finish.h); 0 when exact.
  std::vector<double> relStdError, relStdErrorL0;
};

// The exact projection of the sky_sphere scene at every probe of `job`'s grid.
absl::StatusOr<Reference> AnalyticReference(const BakeJob& job, int order);

// A bake of `scene` with `settings` (which should carry its own seed, many samples and batches),
// read from `cacheDir`/reference-<job digest>.bin when present, else baked on `threads` threads
// (0: all) and stored there.
absl::StatusOr<Reference> BakedReference(const BenchScene& scene, const v1::BakeSettings& settings,
                                         const std::string& cacheDir, int threads);

// Exact radiance SH (order `order`, RGB per coefficient) at world position p of a scene made of a
// uniform environment over a black ground plane z = groundZ (infinite: the bench scene's plane
// is 1e6 wide, which hides the sky to within 2e-6 rad of the horizon) and sphere lights wholly
// above the probe's horizon:
//   L(w) = sky for w.z > 0, replaced by the sphere's radiance inside each sphere's cap; 0 below.
// Cap projections by Funk-Hecke. FAILED_PRECONDITION when the scene is not of that form.
absl::StatusOr<std::vector<Vec3d>> AnalyticSkySphereProjection(const Scene& scene, double groundZ,
                                                               const Vec3d& p, int order);

// Mean over probes of the relative irradiance difference (order `order`) between two references
// valid at the same probes: the bias of a's depth when b is deeper. -1 when no probe is shared.
double ReferenceDifference(const Reference& a, const Reference& b, int order);

// How a reference was made and its own expected error, one paragraph for the report.
// `ladderMax`: the largest sample count compared with it.
std::string ReferenceText(const Reference& r, int64_t ladderMax);

}  // namespace probebake::bench
