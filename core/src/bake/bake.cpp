#include "probebake/bake/bake.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <mutex>
#include <numeric>
#include <thread>

#include "absl/strings/str_cat.h"
#include "probe_finish.h"
#include "probe_integrator.h"
#include "probe_site.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/sampling/hash.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "probebake/sh/sh_basis.h"
#include "tracer_scene.h"

namespace probebake {
namespace {

using Clock = std::chrono::steady_clock;

// Rays per probe for the inside-geometry test (SPEC 3): a probe is invalid when more than
// backfaceFraction of them first hit a back face. 128 directions of one Sobol stream resolve the
// fraction to 1/128, far finer than any sensible threshold.
constexpr int kValidityRays = 128;
// Stream id of the validity rays, outside the range of batch ids.
constexpr uint64_t kValidityStream = ~uint64_t{0};
// Adaptive sampling looks at the error estimate only once this many batches exist: fewer give
// too noisy an estimate of the standard error.
constexpr int kMinAdaptiveBatches = 8;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// Whether every radiance and irradiance value of `probe` is finite: a sum finite in double can
// overflow the volume's floats (a point light 1e-5 from a probe gives I / d^2 = 1e40 from I =
// 1e30).
bool FitsInFloats(const ProbeVolume& volume, int64_t probe) {
  for (const auto* planes : {&volume.radiance, &volume.irradiance}) {
    for (const std::vector<float>& plane : *planes) {
      for (int ch = 0; ch < 3; ++ch)
        if (!std::isfinite(plane[3 * probe + ch])) return false;
    }
  }
  return true;
}

// The lowest probe index noted, from any thread; -1 when none was.
class FirstProbe {
 public:
  void Note(int64_t probe) {
    int64_t seen = first_.load(std::memory_order_relaxed);
    while (probe < seen && !first_.compare_exchange_weak(seen, probe)) {
    }
  }
  int64_t First() const {
    const int64_t p = first_.load();
    return p == std::numeric_limits<int64_t>::max() ? -1 : p;
  }

 private:
  std::atomic<int64_t> first_{std::numeric_limits<int64_t>::max()};
};

// Sample counts of the batches of one probe: `batches` nearly equal parts of `samples`.
int64_t BatchSize(int64_t samples, int batches, int b) {
  return samples / batches + (b < samples % batches ? 1 : 0);
}

// Reports progress and takes checkpoints from its own thread at their intervals while workers
// run (so a long batch never delays a report or a cancellation), and once more when stopped.
class Reporter {
 public:
  Reporter(const BakeOptions& options, SharedCounters& counters, int64_t total, int64_t resumed,
           Clock::time_point start, const ProbeVolume& volume,
           const std::vector<std::atomic<uint8_t>>& done)
      : options_(options),
        counters_(counters),
        total_(total),
        resumed_(resumed),
        start_(start),
        volume_(volume),
        done_(done),
        probesDone_(resumed) {
    if (options_.progress || options_.checkpoint) thread_ = std::thread([this] { Run(); });
  }
  ~Reporter() { Stop(false); }

  void ProbeDone(double relError) {
    std::lock_guard lock(mutex_);
    ++probesDone_;
    if (std::isfinite(relError)) {
      errorSum_ += relError;
      ++errorCount_;
    } else {
      ++errorUnknown_;
    }
  }

  // Ends the thread; a last progress report, and a last checkpoint when asked (cancellation).
  void Stop(bool checkpoint) {
    {
      std::lock_guard lock(mutex_);
      if (stopped_) return;
      stopped_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
    if (options_.progress) options_.progress(Snapshot());
    if (checkpoint && options_.checkpoint) Checkpoint();
  }

 private:
  void Run() {
    auto lastCheckpoint = Clock::now();
    const auto interval =
        std::chrono::duration<double>(std::max(0.001, options_.progressIntervalSeconds));
    std::unique_lock lock(mutex_);
    while (!wake_.wait_for(lock, interval, [&] { return stopped_; })) {
      lock.unlock();
      if (options_.progress) options_.progress(Snapshot());
      if (options_.checkpoint && Seconds(lastCheckpoint) >= options_.checkpointIntervalSeconds) {
        lastCheckpoint = Clock::now();
        Checkpoint();
      }
      lock.lock();
    }
  }

  void Checkpoint() {
    // Workers keep writing unfinished probes: hand out a copy of the finished ones only.
    ProbeVolume snapshot = EmptyLike(volume_);
    std::vector<uint8_t> flags(done_.size());
    for (size_t i = 0; i < flags.size(); ++i) {
      flags[i] = done_[i].load(std::memory_order_acquire);
      if (flags[i]) CopyProbe(volume_, int64_t(i), &snapshot);
    }
    options_.checkpoint(snapshot, flags);
  }

  BakeProgress Snapshot() {
    BakeProgress p;
    {
      std::lock_guard lock(mutex_);
      p.probesDone = probesDone_;
      p.errorEstimate = errorCount_ ? errorSum_ / double(errorCount_) : -1;
      p.probesErrorUnknown = errorUnknown_;
    }
    p.probesTotal = total_;
    p.samples = counters_.samples.load(std::memory_order_relaxed);
    p.rays = counters_.rays.load(std::memory_order_relaxed);
    p.elapsedSeconds = Seconds(start_);
    if (p.probesDone >= total_) {
      p.etaSeconds = 0;
    } else if (p.probesDone > resumed_) {
      p.etaSeconds =
          p.elapsedSeconds * double(total_ - p.probesDone) / double(p.probesDone - resumed_);
    }
    return p;
  }

  const BakeOptions& options_;
  SharedCounters& counters_;
  const int64_t total_, resumed_;
  const Clock::time_point start_;
  const ProbeVolume& volume_;
  const std::vector<std::atomic<uint8_t>>& done_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopped_ = false;
  int64_t probesDone_ = 0, errorCount_ = 0, errorUnknown_ = 0;
  double errorSum_ = 0;
  std::thread thread_;
};

absl::Status CheckSettings(const BakeJob& job) {
  const BakeSettings& s = job.settings;
  if (s.shOrder < 0 || s.shOrder > kMaxShOrder)
    return FieldError("settings.shOrder", "must be in [0, " + std::to_string(kMaxShOrder) + "]");
  if (s.samplesPerProbe < 1 || s.samplesPerProbe >= (int64_t{1} << 32))
    return FieldError("settings.samplesPerProbe", "must be in [1, 2^32)");
  if (s.maxDepth < 1) return FieldError("settings.maxDepth", "must be >= 1");
  if (s.batches < 1) return FieldError("settings.batches", "must be >= 1");
  for (int a = 0; a < 3; ++a) {
    if (job.grid.counts[a] < 1) return FieldError("grid.counts", "must be >= 1 on every axis");
    if (!(job.grid.spacing[a] > 0)) return FieldError("grid.spacing", "must be > 0");
  }
  return absl::OkStatus();
}

absl::StatusOr<ProbeVolume> BakeInArena(const BakeJob& job, const BakeOptions& options,
                                        int threads) {
  const auto start = Clock::now();
  auto log = Logger("bake");
  const BakeSettings& settings = job.settings;
  const ProbeGrid& grid = job.grid;
  const int64_t probeCount = grid.ProbeCount();
  const int coeffs = ShCoeffCount(settings.shOrder);

  const Vec3d offset = LocalOrigin(job.scene);
  const ProbeSites sites(job.scene, offset);
  PB_ASSIGN_OR_RETURN(std::unique_ptr<TracerScene> tracer, TracerScene::Build(job.scene, offset));
  LightSet unweighted(job.scene, *tracer);
  const ProbeFinisher finisher(settings);
  // Where geometry can hide lights, how much of each light reaches each region
  // (light_visibility.h). The pure direction-sampling estimator never chooses a light.
  int64_t visibilityRays = 0;
  LightVisibility visibility;
  if (options.lightVisibility && settings.estimator != Estimator::kDirectionSampling &&
      !job.scene.meshes.empty()) {
    const auto visibilityStart = Clock::now();
    visibility = LightVisibility::Build(*tracer, unweighted,
                                        ProbeIntegrator(job.scene, *tracer, unweighted, settings));
    visibilityRays = visibility.rays();
    if (visibility.dims(0) > 0) {
      log->info("light visibility: {} x {} x {} cells, {} entries, {} rays, {:.3f} s",
                visibility.dims(0), visibility.dims(1), visibility.dims(2),
                unweighted.ImportanceSize(), visibilityRays, Seconds(visibilityStart));
    }
  }
  const LightSet lights(std::move(unweighted), std::move(visibility));
  const ProbeIntegrator integrator(job.scene, *tracer, lights, settings);
  log->info(
      "scene ready in {:.3f} s: {} meshes, {} lights ({} chosen through light trees), {} probes, "
      "order {}, {} samples/probe",
      Seconds(start), job.scene.meshes.size(), lights.Count(), lights.TreeLightCount(), probeCount,
      settings.shOrder, settings.samplesPerProbe);

  ProbeVolume volume;
  volume.grid = grid;
  volume.shOrder = settings.shOrder;
  volume.window = finisher.WindowName();
  volume.active.assign(probeCount, 0);
  volume.validity.assign(probeCount, 0.0f);
  volume.stdError.assign(probeCount, 0.0f);
  volume.sampleCount.assign(probeCount, 0.0f);
  volume.radiance.assign(coeffs, std::vector<float>(3 * probeCount, 0.0f));
  if (settings.irradiance)
    volume.irradiance.assign(coeffs, std::vector<float>(3 * probeCount, 0.0f));
  if (settings.irradiance && settings.window == ShWindow::kAuto)
    volume.autoWindowT.assign(probeCount, 0.0f);
  if (options.coefficientErrors)
    volume.radianceStdError.assign(coeffs, std::vector<float>(3 * probeCount, 0.0f));

  // Where probe `probe` is traced from (local coordinates) and its stream key: from its world
  // position alone, so sub-grids bake their probes as the whole grid does (probe_site.h).
  auto siteOf = [&](int64_t probe) {
    int i, j, k;
    grid.Coords(probe, &i, &j, &k);
    return sites.At(grid.Position(i, j, k));
  };

  // Placement and validity: which probes are inside geometry, which are near a surface.
  std::atomic<int64_t> prepassRays{0};
  std::atomic<int64_t> onSurfaces{0};
  tbb::parallel_for(
      tbb::blocked_range<int64_t>(0, probeCount, 64),
      [&](const tbb::blocked_range<int64_t>& range) {
        int64_t rays = 0;
        for (int64_t probe = range.begin(); probe != range.end(); ++probe) {
          const ProbeSite site = siteOf(probe);
          int moves;
          const Vec3d p = TraceOrigin(*tracer, site.local, &moves);
          if (moves > 0) onSurfaces.fetch_add(1, std::memory_order_relaxed);
          const Vec3f origin(p);
          SobolSampler sampler(settings.seed, Hash(site.key, kValidityStream));
          int backfaces = 0;
          for (int r = 0; r < kValidityRays; ++r) {
            sampler.StartSample(uint64_t(r));
            const Vec3d wi = SampleUniformSphere(sampler.Get2D());
            SurfaceHit hit;
            ++rays;
            if (tracer->Intersect(origin, wi, std::numeric_limits<double>::infinity(), &hit) &&
                hit.kind == SurfaceKind::kMesh && Dot(wi, hit.ng) > 0)
              ++backfaces;
          }
          const bool valid = double(backfaces) <= settings.backfaceFraction * kValidityRays;
          volume.validity[probe] = valid ? 1.0f : 0.0f;
          bool active = true;
          if (grid.placement == Placement::kOutsideGeometry) active = valid;
          if (grid.placement == Placement::kNearSurfaces)
            active = valid && tracer->MeshWithin(p, grid.surfaceDistance);
          volume.active[probe] = active ? 1 : 0;
        }
        prepassRays.fetch_add(rays, std::memory_order_relaxed);
      });

  std::vector<int64_t> todo;
  std::vector<std::atomic<uint8_t>> done(probeCount);
  int64_t resumed = 0;
  const bool resume = options.resumeFrom && options.resumeDone &&
                      options.resumeFrom->grid.ProbeCount() == probeCount &&
                      options.resumeDone->size() == size_t(probeCount) &&
                      options.resumeFrom->shOrder == settings.shOrder;
  for (int64_t probe = 0; probe < probeCount; ++probe) {
    if (!volume.active[probe]) continue;
    if (resume && (*options.resumeDone)[probe]) {
      CopyProbe(*options.resumeFrom, probe, &volume);
      done[probe].store(1, std::memory_order_relaxed);
      ++resumed;
      continue;
    }
    todo.push_back(probe);
  }
  const int64_t activeCount = int64_t(todo.size()) + resumed;
  if (options.resumeFrom && !resume)
    log->warn("resume data does not match this job; baking every probe");
  // Not an error: a sub-grid of a sharded bake may lie wholly inside geometry, and its empty
  // part still merges. But a whole grid that bakes nothing is most likely a mistake.
  if (activeCount == 0)
    log->warn("no probe to bake: the placement left out all {} grid points ({})", probeCount,
              grid.placement == Placement::kNearSurfaces
                  ? "inside geometry or farther than surfaceDistance from a mesh"
                  : "inside geometry");
  log->info("placement: {} of {} probes active ({} resumed), {} invalid, {:.3f} s", activeCount,
            probeCount, resumed, std::count(volume.validity.begin(), volume.validity.end(), 0.0f),
            Seconds(start));
  if (const int64_t n = onSurfaces.load(); n > 0)
    log->info(
        "{} grid points lie on a mesh surface; each is traced from just off it, on its front "
        "side",
        n);

  SharedCounters counters;
  counters.rays.fetch_add(prepassRays.load() + visibilityRays, std::memory_order_relaxed);
  Reporter reporter(options, counters, activeCount, resumed, start, volume, done);
  std::atomic<bool> cancelled{false};
  FirstProbe overflow;  // a probe whose values overflowed the volume's floats
  const std::atomic<bool>* cancel = options.cancel;
  auto isCancelled = [&] {
    return cancelled.load(std::memory_order_relaxed) ||
           (cancel && cancel->load(std::memory_order_relaxed));
  };

  const int maxBatches = int(std::min<int64_t>(settings.batches, settings.samplesPerProbe));
  const int batchesPerCall = int(std::clamp<int64_t>(
      ProbeIntegrator::kSamplesPerCall / (settings.samplesPerProbe / maxBatches), 1,
      ProbeIntegrator::kSamplesPerCall));
  const bool adaptive = settings.targetRelError > 0;
  // Whether a sample can ever be non-zero: light to find, or delta light that a surface or a
  // medium scatters into the samples.
  bool scatters = job.scene.medium && MaxComponent(job.scene.medium->sigmaS) > 0;
  for (const TriangleMesh& mesh : job.scene.meshes)
    scatters = scatters || MaxComponent(job.scene.materials[mesh.material].albedo) > 0;
  const bool sampledMayBeNonZero =
      lights.HasEmission(/*delta=*/false) || (lights.HasEmission(/*delta=*/true) && scatters);

  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, todo.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t t = range.begin(); t != range.end(); ++t) {
          if (isCancelled()) return;
          const int64_t probe = todo[t];
          const ProbeSite site = siteOf(probe);
          // Found again rather than kept from the placement pass: one point query against
          // thousands of rays, where keeping it would cost 24 bytes for every grid point.
          int moves;
          const Vec3d p = TraceOrigin(*tracer, site.local, &moves);
          ProbeEstimate estimate(coeffs, maxBatches, sampledMayBeNonZero);

          // Delta lights project exactly (SPEC 3): c_i += (I / d^2) V Y_i(w), once per probe.
          TraceCounters exactCounters;
          for (uint32_t light : lights.deltaLights()) {
            LightSample s;
            if (!lights.EvalDelta(light, p, &s)) continue;
            // Visibility, times the medium's transmittance when there is one.
            const Vec3d tr = integrator.ShadowTransmittance(Vec3f(p), s, &exactCounters);
            if (MaxComponent(tr) > 0) estimate.AddExact(settings.shOrder, s.wi, s.radiance * tr);
          }
          counters.Add(exactCounters);

          // Batches run in rounds: all of them at once, or (adaptive) a first round of
          // kMinAdaptiveBatches and then pairs until the error target is met at two successive
          // rounds (bake.h). The rounds are fixed by the settings alone, so the result never
          // depends on the thread count.
          int next = 0;
          bool metBefore = false;  // the previous round's bound was under the target
          while (next < maxBatches) {
            const int roundEnd =
                !adaptive ? maxBatches
                          : std::min(maxBatches, next == 0 ? kMinAdaptiveBatches : next + 2);
            // Consecutive batches in groups of about ProbeIntegrator::kSamplesPerCall samples,
            // so that the rays from the probe of small batches share packets (same sums).
            const int groups = (roundEnd - next + batchesPerCall - 1) / batchesPerCall;
            tbb::parallel_for(0, groups, [&](int g) {
              const int first = next + g * batchesPerCall;
              const int end = std::min(roundEnd, first + batchesPerCall);
              ProbeIntegrator::BatchWork work[ProbeIntegrator::kSamplesPerCall];
              for (int b = first; b < end; ++b)
                work[b - first] = {BatchSize(settings.samplesPerProbe, maxBatches, b),
                                   estimate.BatchSum(b)};
              if (!integrator.TraceBatches(p, site.key, uint32_t(first),
                                           {work, size_t(end - first)}, &counters, cancel)) {
                cancelled.store(true, std::memory_order_relaxed);
              }
              for (int b = first; b < end; ++b) estimate.SetBatchSamples(b, work[b - first].count);
            });
            if (isCancelled()) return;
            next = roundEnd;
            if (adaptive) {
              const bool met =
                  AdaptiveErrorBound(estimate.RelativeError(next), next) <= settings.targetRelError;
              if (met && metBefore) break;
              metBefore = met;
            }
          }
          finisher.Finish(estimate, next, probe, &volume);
          if (!FitsInFloats(volume, probe)) {
            overflow.Note(probe);
            cancelled.store(true, std::memory_order_relaxed);
            return;
          }
          done[probe].store(1, std::memory_order_release);
          reporter.ProbeDone(volume.stdError[probe]);
        }
      });

  if (const int64_t probe = overflow.First(); probe >= 0) {
    reporter.Stop(/*checkpoint=*/false);
    int i, j, k;
    grid.Coords(probe, &i, &j, &k);
    const Vec3d at = grid.Position(i, j, k);
    const std::string message = absl::StrCat(
        "grid: the probe (", i, ", ", j, ", ", k, ") at (", at.x, ", ", at.y, ", ", at.z,
        ") receives more light than the volume's 32-bit floats hold (over 3.4e38 in a "
        "coefficient): is a point or spot light almost on it? (their light grows as 1 / d^2)");
    log->error("{}", message);
    return absl::InvalidArgumentError(message);
  }
  if (isCancelled()) {
    reporter.Stop(/*checkpoint=*/true);
    log->info("cancelled after {:.3f} s", Seconds(start));
    return absl::CancelledError("bake cancelled");
  }

  if (!volume.autoWindowT.empty()) {
    int64_t windowed = 0;
    double maxT = 0;
    for (int64_t p = 0; p < probeCount; ++p) {
      if (!volume.active[p] || volume.autoWindowT[p] <= 0) continue;
      ++windowed;
      maxT = std::max(maxT, double(volume.autoWindowT[p]));
    }
    volume.window = AutoWindowSummary(windowed, activeCount, maxT);
  }
  volume.stats.wallSeconds = Seconds(start);
  volume.stats.threads = threads;
  volume.stats.probes = activeCount;
  volume.stats.samples = counters.samples.load();
  volume.stats.rays = counters.rays.load();
  int64_t invalid = 0;
  for (int64_t probe = 0; probe < probeCount; ++probe)
    if (volume.active[probe] && volume.validity[probe] == 0.0f) ++invalid;
  volume.stats.invalidProbes = invalid;
  reporter.Stop(/*checkpoint=*/false);
  log->info("baked {} probes in {:.3f} s: {} samples, {} rays ({:.2f} Mrays/s)", activeCount,
            volume.stats.wallSeconds, volume.stats.samples, volume.stats.rays,
            volume.stats.rays / std::max(volume.stats.wallSeconds, 1e-9) * 1e-6);
  return volume;
}

}  // namespace

double AdaptiveErrorBound(double relError, int batches) {
  return relError * (1 + kAdaptiveSigmas / std::sqrt(2.0 * std::max(1, batches - 1)));
}

absl::StatusOr<ProbeVolume> Bake(const BakeJob& job, const BakeOptions& options) {
  PB_RETURN_IF_ERROR(CheckSettings(job));
  const int threads =
      options.threads > 0 ? options.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  absl::StatusOr<ProbeVolume> result;
  arena.execute([&] { result = BakeInArena(job, options, threads); });
  return result;
}

}  // namespace probebake
