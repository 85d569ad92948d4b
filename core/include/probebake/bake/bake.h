// Baking a probe volume: the whole job in process, on a oneTBB worker pool.
//
// Contract: the result depends only on the BakeJob (scene, grid, settings with its seed): the same
// job gives the same bits for any thread count, work order or resumption. Long-running; reports
// progress through a callback at a bounded rate and stops within a fraction of a second of
// cancellation. Knows nothing of gRPC; the server adapts its job state to these hooks.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>

#include "absl/status/statusor.h"
#include "probebake/bake/probe_volume.h"
#include "probebake/bake/ray_observer.h"
#include "probebake/scene/scene.h"

namespace probebake {

struct BakeProgress {
  int64_t probesDone = 0;
  int64_t probesTotal = 0;  // probes to bake (known after placement)
  int64_t samples = 0;
  int64_t rays = 0;
  double elapsedSeconds = 0;
  double etaSeconds = -1;  // < 0: unknown
  // Mean std_error (the relative standard error of the probe's irradiance, ProbeVolume::stdError)
  // of the finished probes whose error is known; < 0: none is.
  double errorEstimate = -1;
  // Finished probes whose error is unknown (std_error inf: a single batch, or every sample black
  // while the scene has light to find), left out of errorEstimate.
  int64_t probesErrorUnknown = 0;
};

struct BakeOptions {
  // Worker threads; 0 = every hardware thread.
  int threads = 0;
  // Called from any thread, serialised, at most every `progressIntervalSeconds` and once at the
  // end. Must not block for long.
  std::function<void(const BakeProgress&)> progress;
  double progressIntervalSeconds = 0.25;
  // Set to true (from any thread) to stop the bake; Bake then returns CANCELLED.
  const std::atomic<bool>* cancel = nullptr;
  // Also report the standard error of every radiance coefficient (ProbeVolume::radianceStdError).
  bool coefficientErrors = false;
  // Weigh light selection by how much of each light reaches each region of the scene
  // (core/src/bake/light_visibility.h). Changes the bits of the result, not its expectation: off
  // only in tests and benchmarks that compare the two.
  bool lightVisibility = true;
  // Optional resumption: a partial volume from an earlier run of the same job, whose finished
  // probes ((*resumeDone)[probe] != 0) are kept as they are and not re-baked.
  const ProbeVolume* resumeFrom = nullptr;
  const std::vector<uint8_t>* resumeDone = nullptr;
  // Optional checkpoint hook: called from worker threads, serialised, at most every
  // `checkpointIntervalSeconds` and once more on cancellation, with a snapshot holding the
  // finished probes (others zero) and the per-probe done flags: what resumeFrom/resumeDone take.
  std::function<void(const ProbeVolume&, const std::vector<uint8_t>& done)> checkpoint;
  double checkpointIntervalSeconds = 10;
  // Optional: sees the rays the probes' sampling casts (ray_observer.h; measurement only, the
  // bits do not change). Must outlive the bake, and be thread-safe when threads != 1.
  RayObserver* rayObserver = nullptr;
};

// Adaptive sampling (settings.targetRelError > 0): a probe bakes batches in rounds (the first 8,
// then 2 at a time) and stops once AdaptiveErrorBound(std_error, batches so far) is at or below
// the target at two successive rounds, or at the sample cap. std_error is the relative standard
// error of the probe's irradiance over the sphere of normals (ProbeVolume::stdError), so the
// target bounds the directional light too, not the mean alone. The bound is an upper
// confidence bound on the error rather than the estimate itself: stopping at the first estimate
// that happens to come out low (optional stopping) leaves the achieved error above the target.
// With k batches the estimated standard error has a relative spread of about 1/sqrt(2(k-1))
// (Gaussian batch means); the bound adds kAdaptiveSigmas of it: relError * (1 + 2 / sqrt(2(k-1))).
// std_error pools the spread of several coefficients, so its own spread is smaller than that:
// the bound is conservative.
// Batch means are not Gaussian where a small bright light is found by rare paths: batches that
// have not met them yet report a low value and a low error together, a fluctuation the bound
// cannot see. The second round must confirm the first: on the bench's courtyard a probe that
// stopped at 16 batches with a 0.5% target, 0.35% reported and 2.5% true, read 0.71% at 18.
inline constexpr double kAdaptiveSigmas = 2;
double AdaptiveErrorBound(double relError, int batches);

// Bakes `job`. Errors: CANCELLED when cancelled, INTERNAL for tracer failures (Embree device
// errors), INVALID_ARGUMENT for a job the validator should have rejected.
absl::StatusOr<ProbeVolume> Bake(const BakeJob& job, const BakeOptions& options);

}  // namespace probebake
