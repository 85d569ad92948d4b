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
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "distant_light_paths.h"
#include "environment_guide.h"
#include "probe_finish.h"
#include "probe_integrator.h"
#include "probe_relocation.h"
#include "probe_site.h"
#include "probebake/bake/probe_dilation.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/sampling/hash.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/volume/visibility_map.h"
#include "tracer_scene.h"

namespace probebake {
namespace {

using Clock = std::chrono::steady_clock;

// Adaptive sampling looks at the error estimate only once this many batches exist: fewer give
// too noisy an estimate of the standard error.
constexpr int kMinAdaptiveBatches = 8;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// Whether every radiance, irradiance and sky transfer value of `probe` is finite: a sum finite in
// double can overflow the volume's floats (a point light 1e-5 from a probe gives I / d^2 = 1e40
// from I = 1e30), and a T entry beyond 65504 its half precision.
bool FitsInFloats(const ProbeVolume& volume, int64_t probe) {
  for (const auto* planes : {&volume.radiance, &volume.irradiance, &volume.skyTransfer}) {
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
  if (s.skyTransferOrder < 0 || s.skyTransferOrder > kMaxShOrder)
    return FieldError("settings.skyTransfer.order",
                      "must be in [0, " + std::to_string(kMaxShOrder) + "]");
  if (s.skyTransferOrder > 0 && s.targetRelError > 0)
    return FieldError("settings.skyTransfer.order",
                      "sky transfer does not support adaptive sampling (targetRelError > 0)");
  for (int a = 0; a < 3; ++a) {
    if (job.grid.counts[a] < 1) return FieldError("grid.counts", "must be >= 1 on every axis");
    if (!(job.grid.spacing[a] > 0)) return FieldError("grid.spacing", "must be > 0");
  }
  return absl::OkStatus();
}

// The stages of a bake, in the order BakeInArena runs them:
//   1. TraceableScene::Build: the tracer, the lights (weighted by their visibility table) and
//      the integrator, once per job;
//   2. NewVolume: the volume the probes are written to, all zero;
//   3. PlaceProbes: each probe's validity, and whether the placement bakes it;
//   4. ListProbesToBake: the probes left to bake, the ones resumed from a checkpoint copied;
//   5. BakeProbes: every probe on the list, in parallel, each by ProbeBaker::Bake (delta lights
//      exactly, then rounds of batches, adaptive or not, then the finished coefficients);
//   6. FinishVolume: the AUTO window's summary and the statistics.
// A cancellation or a probe too bright for the volume's floats ends the bake after stage 5.

// The scene as the bake traces it. Built once per job; read-only once built.
struct TraceableScene {
  // Builds the BVH, the lights and the integrator, and (options.lightVisibility) the table of how
  // much of each light reaches each region (light_visibility.h), which the lights then weigh
  // their choice by. Errors: the tracer's (INTERNAL).
  static absl::StatusOr<TraceableScene> Build(const BakeJob& job, const BakeOptions& options);

  Vec3d offset;  // the tracer's local origin (tracer_scene.h)
  // Behind pointers: the lights and the integrator keep references to the tracer and the lights.
  std::unique_ptr<TracerScene> tracer;
  std::unique_ptr<LightSet> lights;
  std::unique_ptr<ProbeIntegrator> integrator;
  // Light traced from the directional lights, joined to the probes (null: none to trace).
  std::unique_ptr<DistantLightPaths> lightPaths;
  int64_t setupRays = 0;  // traced to build the environment guide and the visibility table
};

// Builds the visibility table of `unweighted` (traced with a temporary integrator over it) and
// returns the lights that weigh their choice by it. *rays gets the rays it traced.
std::unique_ptr<LightSet> WithLightVisibility(const BakeJob& job, const TracerScene& tracer,
                                              LightSet unweighted, int64_t* rays) {
  const auto start = Clock::now();
  const double floor = job.settings.lightVisibilityFloor > 0 ? job.settings.lightVisibilityFloor
                                                             : LightVisibility::kFloor;
  LightVisibility visibility = LightVisibility::Build(
      tracer, unweighted, ProbeIntegrator(job.scene, tracer, unweighted, job.settings), floor);
  *rays = visibility.rays();
  if (visibility.dims(0) > 0) {
    Logger("bake")->info("light visibility: {} x {} x {} cells, {} entries, {} rays, {:.3f} s",
                         visibility.dims(0), visibility.dims(1), visibility.dims(2),
                         unweighted.ImportanceSize(), *rays, Seconds(start));
  }
  return std::make_unique<LightSet>(std::move(unweighted), std::move(visibility));
}

// Samples the environment of `lights` (when it has one) through a guide of where it reaches each
// region of the scene (environment_guide.h), traced with a temporary integrator over *lights.
// Returns the rays it traced.
int64_t AddEnvironmentGuide(const BakeJob& job, const TracerScene& tracer, LightSet* lights) {
  if (!lights->environment() || lights->environment()->IsBlack()) return 0;
  const auto start = Clock::now();
  auto guide = std::make_unique<EnvironmentGuide>(EnvironmentGuide::Build(
      tracer, *lights->environment(), ProbeIntegrator(job.scene, tracer, *lights, job.settings)));
  if (guide->dims(0) > 0) {
    Logger("bake")->info(
        "environment guide: {:.3f} of the sky arrives, {} x {} x {} cells, {} guided, {} rays, "
        "{:.3f} s",
        guide->OpenFraction(), guide->dims(0), guide->dims(1), guide->dims(2), guide->GuidedCells(),
        guide->rays(), Seconds(start));
  }
  const int64_t rays = guide->rays();
  lights->SetEnvironmentGuide(std::move(guide));
  return rays;
}

absl::StatusOr<TraceableScene> TraceableScene::Build(const BakeJob& job,
                                                     const BakeOptions& options) {
  TraceableScene s;
  s.offset = LocalOrigin(job.scene);
  PB_ASSIGN_OR_RETURN(s.tracer, TracerScene::Build(job.scene, s.offset));
  // A sky-transfer bake leaves the environment out of its lights: the escaping paths measure T
  // instead (probe_integrator.h).
  LightSet unweighted(job.scene, *s.tracer, kLightTreeMinLights,
                      /*environment=*/job.settings.skyTransferOrder == 0);
  // Where geometry can hide lights. The pure direction-sampling estimator never chooses a light.
  const bool samplesLights =
      job.settings.estimator != Estimator::kDirectionSampling && !job.scene.meshes.empty();
  if (job.settings.environmentGuide && samplesLights)
    s.setupRays += AddEnvironmentGuide(job, *s.tracer, &unweighted);
  if (options.lightVisibility && samplesLights) {
    int64_t rays = 0;
    s.lights = WithLightVisibility(job, *s.tracer, std::move(unweighted), &rays);
    s.setupRays += rays;
  } else {
    s.lights = std::make_unique<LightSet>(std::move(unweighted));
  }
  s.integrator = std::make_unique<ProbeIntegrator>(job.scene, *s.tracer, *s.lights, job.settings);
  s.integrator->SetRayObserver(options.rayObserver);
  if (job.settings.distantLightTracing) {
    const auto start = Clock::now();
    const BakeSettings& settings = job.settings;
    const int batches = int(std::min<int64_t>(settings.batches, settings.samplesPerProbe));
    std::vector<int64_t> sizes(size_t(std::max(batches, 0)));
    for (int b = 0; b < batches; ++b)
      sizes[size_t(b)] = BatchSize(settings.samplesPerProbe, batches, b);
    s.lightPaths = DistantLightPaths::Build(job.scene, *s.tracer, s.lights.get(), settings, sizes);
    if (s.lightPaths) {
      s.integrator->SetLightPaths(s.lightPaths.get());
      Logger("bake")->info("light traced from the directional lights: {} vertices kept, {:.3f} s",
                           s.lightPaths->VertexCount(), Seconds(start));
      for (size_t i = 0; i < job.scene.lights.size(); ++i)
        if (s.lightPaths->Traces(uint32_t(i)))
          Logger("bake")->info("  light {}: {} paths a sample, {:.4f} of their first hits kept", i,
                               s.lightPaths->Lambda(uint32_t(i)),
                               s.lightPaths->KeptFraction(uint32_t(i)));
    }
  }
  return s;
}

// A volume over the job's grid with every plane the settings and options ask for, all zero, no
// probe active.
ProbeVolume NewVolume(const BakeJob& job, const BakeOptions& options,
                      const ProbeFinisher& finisher) {
  const BakeSettings& settings = job.settings;
  const int64_t probeCount = job.grid.ProbeCount();
  const int coeffs = ShCoeffCount(settings.shOrder);
  ProbeVolume volume;
  volume.grid = job.grid;
  volume.shOrder = settings.shOrder;
  volume.window = finisher.WindowName();
  volume.active.assign(probeCount, 0);
  volume.validity.assign(probeCount, 0.0f);
  volume.stdError.assign(probeCount, 0.0f);
  volume.stdErrorL0.assign(probeCount, 0.0f);
  volume.sampleCount.assign(probeCount, 0.0f);
  volume.radiance.assign(coeffs, std::vector<float>(3 * probeCount, 0.0f));
  if (settings.irradiance)
    volume.irradiance.assign(coeffs, std::vector<float>(3 * probeCount, 0.0f));
  if (settings.irradiance && settings.window == ShWindow::kAuto)
    volume.autoWindowT.assign(probeCount, 0.0f);
  if (options.coefficientErrors)
    volume.radianceStdError.assign(coeffs, std::vector<float>(3 * probeCount, 0.0f));
  if (settings.visibility)
    volume.visibility.assign(kVisibilityTexels, std::vector<float>(3 * probeCount, 0.0f));
  if (settings.skyTransferOrder > 0) {
    volume.skyTransferOrder = settings.skyTransferOrder;
    const size_t entries = size_t(coeffs) * size_t(volume.SkyCoeffCount());
    volume.skyTransfer.assign(entries, std::vector<float>(3 * probeCount, 0.0f));
    if (options.coefficientErrors)
      volume.skyTransferStdError.assign(entries, std::vector<float>(3 * probeCount, 0.0f));
  }
  return volume;
}

// Where probe `probe` of the grid is traced from and its stream key: from its world position
// alone (moved by its relocation offset, when it has one), so that sub-grids bake their probes as
// the whole grid does (probe_site.h, probe_relocation.h).
Vec3d BakedPosition(const ProbeVolume& volume, int64_t probe) {
  int i, j, k;
  volume.grid.Coords(probe, &i, &j, &k);
  const Vec3d at = volume.grid.Position(i, j, k);
  if (volume.offset.empty()) return at;
  const float* o = &volume.offset[3 * probe];
  return at + Vec3d(Vec3f(o[0], o[1], o[2]));
}

// Sets every probe's validity (inside geometry or not: probe_relocation.h), its relocation
// offset when relocation is on, and whether the placement bakes it (volume->active). Returns the
// rays traced.
int64_t PlaceProbes(const BakeJob& job, const TracerScene& tracer, const ProbeSites& sites,
                    ProbeVolume* volume) {
  const BakeSettings& settings = job.settings;
  const ProbeGrid& grid = job.grid;
  const ProbeRelocator relocator(tracer, sites, settings, grid);
  if (relocator.Enabled()) volume->offset.assign(3 * grid.ProbeCount(), 0.0f);
  std::atomic<int64_t> placementRays{0};
  std::atomic<int64_t> onSurfaces{0};
  std::atomic<int64_t> moved{0};
  std::atomic<int64_t> stuck{0};
  tbb::parallel_for(tbb::blocked_range<int64_t>(0, grid.ProbeCount(), 64),
                    [&](const tbb::blocked_range<int64_t>& range) {
                      int64_t rays = 0;
                      for (int64_t probe = range.begin(); probe != range.end(); ++probe) {
                        const Vec3d position = BakedPosition(*volume, probe);
                        ProbeStart start = StartAt(sites, tracer, position);
                        if (start.moves > 0) onSurfaces.fetch_add(1, std::memory_order_relaxed);
                        bool valid = ProbeValid(tracer, settings, start.p, start.key, &rays);
                        if (relocator.WantsMove(start, valid)) {
                          Vec3f offset;
                          if (relocator.Find(position, start, valid, &offset, &rays)) {
                            volume->offset[3 * probe] = offset.x;
                            volume->offset[3 * probe + 1] = offset.y;
                            volume->offset[3 * probe + 2] = offset.z;
                            start = StartAt(sites, tracer, BakedPosition(*volume, probe));
                            valid = true;  // the search found it valid
                            moved.fetch_add(1, std::memory_order_relaxed);
                          } else {
                            stuck.fetch_add(1, std::memory_order_relaxed);
                          }
                        }
                        volume->validity[probe] = valid ? 1.0f : 0.0f;
                        bool active = true;
                        if (grid.placement == Placement::kOutsideGeometry) active = valid;
                        if (grid.placement == Placement::kNearSurfaces)
                          active = valid && tracer.MeshWithin(start.p, grid.surfaceDistance);
                        volume->active[probe] = active ? 1 : 0;
                      }
                      placementRays.fetch_add(rays, std::memory_order_relaxed);
                    });
  if (const int64_t n = onSurfaces.load(); n > 0)
    Logger("bake")->info(
        "{} grid points lie on a mesh surface; each is traced from just off it, on its front "
        "side",
        n);
  if (relocator.Enabled())
    Logger("bake")->info(
        "relocation: {} probes moved, {} inside or too close to geometry found no free point "
        "within {} of the spacing",
        moved.load(), stuck.load(), settings.relocationMaxOffset);
  return placementRays.load();
}

// The active probes left to bake, in index order, and how many were resumed: those finished in
// options.resumeFrom are copied into *volume and marked in *done instead, when the resume data
// matches the job (a warning otherwise).
struct ProbesToBake {
  std::vector<int64_t> todo;
  int64_t resumed = 0;
  int64_t Active() const { return int64_t(todo.size()) + resumed; }
};
ProbesToBake ListProbesToBake(const BakeJob& job, const BakeOptions& options, ProbeVolume* volume,
                              std::vector<std::atomic<uint8_t>>* done) {
  auto log = Logger("bake");
  const int64_t probeCount = job.grid.ProbeCount();
  const bool resume = options.resumeFrom && options.resumeDone &&
                      options.resumeFrom->grid.ProbeCount() == probeCount &&
                      options.resumeDone->size() == size_t(probeCount) &&
                      options.resumeFrom->shOrder == job.settings.shOrder &&
                      options.resumeFrom->skyTransferOrder == job.settings.skyTransferOrder;
  if (options.resumeFrom && !resume)
    log->warn("resume data does not match this job; baking every probe");
  ProbesToBake list;
  for (int64_t probe = 0; probe < probeCount; ++probe) {
    if (!volume->active[probe]) continue;
    if (resume && (*options.resumeDone)[probe]) {
      CopyProbe(*options.resumeFrom, probe, volume);
      (*done)[probe].store(1, std::memory_order_relaxed);
      ++list.resumed;
      continue;
    }
    list.todo.push_back(probe);
  }
  // Not an error: a sub-grid of a sharded bake may lie wholly inside geometry, and its empty
  // part still merges. But a whole grid that bakes nothing is most likely a mistake.
  if (list.Active() == 0)
    log->warn("no probe to bake: the placement left out all {} grid points ({})", probeCount,
              job.grid.placement == Placement::kNearSurfaces
                  ? "inside geometry or farther than surfaceDistance from a mesh"
                  : "inside geometry");
  return list;
}

// Bakes one probe at a time into a volume: its delta lights projected exactly, then its batches
// in rounds, then its finished coefficients. Thread-safe: probes bake in parallel, each round's
// groups of batches too.
class ProbeBaker {
 public:
  enum class Outcome {
    kDone,     // the probe is written
    kStopped,  // cancelled or stopped: the probe is not written
    kOverflow  // its values overflow the volume's floats
  };

  // cancel: the caller's (BakeOptions::cancel, may be null), which the tracing polls too; stop:
  // the bake's own, read between rounds.
  ProbeBaker(const BakeJob& job, const TraceableScene& scene, const ProbeFinisher& finisher,
             SharedCounters* counters, const std::atomic<bool>* cancel,
             const std::atomic<bool>* stop)
      : settings_(job.settings),
        lights_(*scene.lights),
        integrator_(*scene.integrator),
        finisher_(finisher),
        counters_(counters),
        cancel_(cancel),
        stop_(stop),
        maxBatches_(int(std::min<int64_t>(settings_.batches, settings_.samplesPerProbe))),
        batchesPerCall_(int(std::clamp<int64_t>(
            ProbeIntegrator::kSamplesPerCall / (settings_.samplesPerProbe / maxBatches_), 1,
            ProbeIntegrator::kSamplesPerCall))),
        sampledMayBeNonZero_(SampledMayBeNonZero(job.scene, lights_)),
        visibilityMaxDistance_(VisibilityMaxDistance(job.grid)),
        minBatches_(MinBatches(settings_, maxBatches_)) {}

  // Bakes the probe at start.p into probe `probe` of *volume, unless `cancel` or `stop` is raised
  // before it is done.
  Outcome Bake(int64_t probe, const ProbeStart& start, ProbeVolume* volume) const {
    ProbeEstimate estimate(
        ShCoeffCount(settings_.shOrder), maxBatches_, sampledMayBeNonZero_, settings_.visibility,
        settings_.skyTransferOrder > 0 ? ShCoeffCount(settings_.skyTransferOrder) : 0);
    AddDeltaLights(start.p, &estimate);
    const double roulette =
        integrator_.RouletteRadiance(start.p, start.key, settings_.samplesPerProbe, counters_);
    int batches = 0;
    if (!TraceRounds(start, roulette, &estimate, &batches)) return Outcome::kStopped;
    finisher_.Finish(estimate, batches, probe, volume);
    return FitsInFloats(*volume, probe) ? Outcome::kDone : Outcome::kOverflow;
  }

 private:
  // Whether a sample can ever be non-zero: light to find, or delta light that a surface or a
  // medium scatters into the samples.
  static bool SampledMayBeNonZero(const Scene& scene, const LightSet& lights) {
    bool scatters = scene.medium && MaxComponent(scene.medium->sigmaS) > 0;
    for (const TriangleMesh& mesh : scene.meshes)
      scatters = scatters || MaxComponent(scene.materials[mesh.material].albedo) > 0;
    return lights.HasEmission(/*delta=*/false) || (lights.HasEmission(/*delta=*/true) && scatters);
  }

  // Delta lights project exactly (docs/job-format.md, scene.lights): c_i += (I / d^2) V Y_i(w),
  // once per probe, V the visibility times the medium's transmittance when there is one.
  void AddDeltaLights(const Vec3d& p, ProbeEstimate* estimate) const {
    TraceCounters counters;
    for (uint32_t light : lights_.deltaLights()) {
      LightSample s;
      if (!lights_.EvalDelta(light, p, &s)) continue;
      const Vec3d tr = integrator_.ShadowTransmittance(Vec3f(p), s, &counters);
      if (MaxComponent(tr) > 0) estimate->AddExact(settings_.shOrder, s.wi, s.radiance * tr);
    }
    counters_->Add(counters);
  }

  // Traces the probe's batches in rounds: all of them at once, or (adaptive) a first round of
  // kMinAdaptiveBatches and then pairs until the error target is met at two successive rounds
  // (bake.h). The rounds are fixed by the settings alone, so the result never depends on the
  // thread count. Every round plays the shadow rays' roulette against `roulette`
  // (ProbeIntegrator::RouletteRadiance). Sets *batches to the batches traced; false when stopped.
  bool TraceRounds(const ProbeStart& start, double roulette, ProbeEstimate* estimate,
                   int* batches) const {
    const bool adaptive = settings_.targetRelError > 0;
    int next = 0;
    bool metBefore = false;  // the previous round's bound was under the target
    while (next < maxBatches_) {
      const int roundEnd = !adaptive
                               ? maxBatches_
                               : std::min(maxBatches_, next == 0 ? kMinAdaptiveBatches : next + 2);
      if (!TraceBatches(start, roulette, next, roundEnd, estimate) || Stopped()) return false;
      next = roundEnd;
      if (adaptive) {
        const bool met = AdaptiveErrorBound(estimate->Relative(next).irradiance, next) <=
                         settings_.targetRelError;
        if (met && metBefore && next >= minBatches_) break;
        metBefore = met;
      }
    }
    *batches = next;
    return true;
  }

  // Traces batches [first, end) in parallel, consecutive batches in groups of about
  // ProbeIntegrator::kSamplesPerCall samples, so that the rays from the probe of small batches
  // share packets (same sums). False when cancelled.
  bool TraceBatches(const ProbeStart& start, double roulette, int first, int end,
                    ProbeEstimate* estimate) const {
    std::atomic<bool> cancelled{false};  // the tracing saw `cancel` raised
    const int groups = (end - first + batchesPerCall_ - 1) / batchesPerCall_;
    tbb::parallel_for(0, groups, [&](int g) {
      const int from = first + g * batchesPerCall_;
      const int to = std::min(end, from + batchesPerCall_);
      ProbeIntegrator::BatchWork work[ProbeIntegrator::kSamplesPerCall];
      for (int b = from; b < to; ++b)
        work[b - from] = {BatchSize(settings_.samplesPerProbe, maxBatches_, b),
                          estimate->BatchSum(b), estimate->BatchMoments(b), visibilityMaxDistance_,
                          estimate->BatchTransfer(b)};
      if (!integrator_.TraceBatches(start.p, start.key, uint32_t(from), {work, size_t(to - from)},
                                    counters_, cancel_, roulette))
        cancelled.store(true, std::memory_order_relaxed);
      for (int b = from; b < to; ++b) estimate->SetBatchSamples(b, work[b - from].count);
    });
    return !cancelled.load();
  }

  bool Stopped() const {
    return stop_->load(std::memory_order_relaxed) ||
           (cancel_ && cancel_->load(std::memory_order_relaxed));
  }

  const BakeSettings& settings_;
  const LightSet& lights_;
  const ProbeIntegrator& integrator_;
  const ProbeFinisher& finisher_;
  SharedCounters* counters_;
  const std::atomic<bool>* cancel_;
  const std::atomic<bool>* stop_;
  const int maxBatches_;
  // With visibility, adaptive sampling stops no sooner than this many batches: enough samples
  // (kMinVisibilitySamples, or all of them) that the moments' texels hold a few rays each.
  static int MinBatches(const BakeSettings& settings, int maxBatches) {
    if (!settings.visibility || !(settings.targetRelError > 0)) return 0;
    const int64_t want = std::min(settings.samplesPerProbe, kMinVisibilitySamples);
    int64_t samples = 0;
    int n = 0;
    while (n < maxBatches && samples < want)
      samples += BatchSize(settings.samplesPerProbe, maxBatches, n++);
    return n;
  }
  const int batchesPerCall_;
  const bool sampledMayBeNonZero_;
  const double visibilityMaxDistance_;
  const int minBatches_;
};

// How BakeProbes ended: every probe baked, cancelled, or stopped by a probe whose values overflow
// the volume's floats (the lowest such probe).
struct BakeRun {
  bool cancelled = false;
  int64_t overflow = -1;
};

// Bakes the probes of `todo` in parallel into *volume, marking each in *done and telling the
// reporter as it is finished. Stops at options.cancel or at the first probe that overflows.
BakeRun BakeProbes(const BakeJob& job, const BakeOptions& options, const TraceableScene& scene,
                   const ProbeSites& sites, const ProbeFinisher& finisher,
                   const std::vector<int64_t>& todo, SharedCounters* counters, Reporter* reporter,
                   ProbeVolume* volume, std::vector<std::atomic<uint8_t>>* done) {
  // Raised when a probe is cancelled or overflows: the other probes stop at their next round.
  std::atomic<bool> stop{false};
  FirstProbe overflow;
  const std::atomic<bool>* cancel = options.cancel;
  auto stopped = [&] {
    return stop.load(std::memory_order_relaxed) ||
           (cancel && cancel->load(std::memory_order_relaxed));
  };
  const ProbeBaker baker(job, scene, finisher, counters, cancel, &stop);
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, todo.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t t = range.begin(); t != range.end(); ++t) {
          if (stopped()) return;
          const int64_t probe = todo[t];
          // Found again rather than kept from the placement: one point query against
          // thousands of rays, where keeping it would cost 24 bytes for every grid
          // point.
          const ProbeStart start = StartAt(sites, *scene.tracer, BakedPosition(*volume, probe));
          switch (baker.Bake(probe, start, volume)) {
            case ProbeBaker::Outcome::kDone:
              (*done)[probe].store(1, std::memory_order_release);
              reporter->ProbeDone(volume->stdError[probe]);
              break;
            case ProbeBaker::Outcome::kStopped:
              stop.store(true, std::memory_order_relaxed);
              return;
            case ProbeBaker::Outcome::kOverflow:
              overflow.Note(probe);
              stop.store(true, std::memory_order_relaxed);
              return;
          }
        }
      });
  BakeRun run;
  run.overflow = overflow.First();
  run.cancelled = stopped();
  return run;
}

// The error of a bake stopped by a probe whose values overflow the volume's floats.
absl::Status OverflowError(const ProbeGrid& grid, int64_t probe) {
  int i, j, k;
  grid.Coords(probe, &i, &j, &k);
  const Vec3d at = grid.Position(i, j, k);
  return absl::InvalidArgumentError(absl::StrCat(
      "grid: the probe (", i, ", ", j, ", ", k, ") at (", at.x, ", ", at.y, ", ", at.z,
      ") receives more light than the volume's 32-bit floats hold (over 3.4e38 in a "
      "coefficient): is a point or spot light almost on it? (their light grows as 1 / d^2); or, "
      "with settings.skyTransfer, an entry of its transfer is above 65504, the largest half "
      "float: an albedo too close to 1 in a closed space?"));
}

// Records, once every probe is baked, the AUTO window's summary (when per-probe windows were
// chosen) and the bake's statistics.
void FinishVolume(int64_t activeCount, const SharedCounters& counters, int threads,
                  Clock::time_point start, ProbeVolume* volume) {
  const int64_t probeCount = volume->grid.ProbeCount();
  if (!volume->autoWindowT.empty()) {
    int64_t windowed = 0;
    double maxT = 0;
    for (int64_t p = 0; p < probeCount; ++p) {
      if (!volume->active[p] || volume->autoWindowT[p] <= 0) continue;
      ++windowed;
      maxT = std::max(maxT, double(volume->autoWindowT[p]));
    }
    volume->window = AutoWindowSummary(windowed, activeCount, maxT);
  }
  volume->stats.wallSeconds = Seconds(start);
  volume->stats.threads = threads;
  volume->stats.probes = activeCount;
  volume->stats.samples = counters.samples.load();
  volume->stats.rays = counters.rays.load();
  int64_t invalid = 0;
  for (int64_t probe = 0; probe < probeCount; ++probe)
    if (volume->active[probe] && volume->validity[probe] == 0.0f) ++invalid;
  volume->stats.invalidProbes = invalid;
}

absl::StatusOr<ProbeVolume> BakeInArena(const BakeJob& job, const BakeOptions& options,
                                        int threads) {
  const auto start = Clock::now();
  auto log = Logger("bake");
  const BakeSettings& settings = job.settings;
  const int64_t probeCount = job.grid.ProbeCount();

  PB_ASSIGN_OR_RETURN(const TraceableScene scene, TraceableScene::Build(job, options));
  log->info(
      "scene ready in {:.3f} s: {} meshes, {} lights ({} chosen through light trees), {} probes, "
      "order {}, {} samples/probe",
      Seconds(start), job.scene.meshes.size(), scene.lights->Count(),
      scene.lights->TreeLightCount(), probeCount, settings.shOrder, settings.samplesPerProbe);
  if (settings.visibility && settings.samplesPerProbe < kMinVisibilitySamples) {
    log->warn(
        "visibility: {} samples per probe leave {:.1f} rays per texel of the {} x {} map; below "
        "{} samples texels go empty and thin walls leak (README, \"Light leaks\")",
        settings.samplesPerProbe, double(settings.samplesPerProbe) / kVisibilityTexels,
        kVisibilityMapSize, kVisibilityMapSize, kMinVisibilitySamples);
  }

  const ProbeFinisher finisher(settings);
  ProbeVolume volume = NewVolume(job, options, finisher);
  const ProbeSites sites(job.scene, scene.offset);
  const int64_t placementRays = PlaceProbes(job, *scene.tracer, sites, &volume);
  std::vector<std::atomic<uint8_t>> done(probeCount);
  const ProbesToBake list = ListProbesToBake(job, options, &volume, &done);
  log->info("placement: {} of {} probes active ({} resumed), {} invalid, {:.3f} s", list.Active(),
            probeCount, list.resumed,
            std::count(volume.validity.begin(), volume.validity.end(), 0.0f), Seconds(start));

  SharedCounters counters;
  counters.rays.fetch_add(placementRays + scene.setupRays, std::memory_order_relaxed);
  Reporter reporter(options, counters, list.Active(), list.resumed, start, volume, done);
  const BakeRun run = BakeProbes(job, options, scene, sites, finisher, list.todo, &counters,
                                 &reporter, &volume, &done);
  if (run.overflow >= 0) {
    reporter.Stop(/*checkpoint=*/false);
    const absl::Status error = OverflowError(job.grid, run.overflow);
    log->error("{}", std::string(error.message()));
    return error;
  }
  if (run.cancelled) {
    reporter.Stop(/*checkpoint=*/true);
    log->info("cancelled after {:.3f} s", Seconds(start));
    return absl::CancelledError("bake cancelled");
  }

  if (settings.relocationMaxOffset > 0) {
    volume.filled.assign(size_t(probeCount), 0.0f);
    const int64_t filled = DilateProbes(&volume);
    if (filled > 0)
      log->info("dilation: {} probes left inside geometry filled from neighbours", filled);
  }
  FinishVolume(list.Active(), counters, threads, start, &volume);
  reporter.Stop(/*checkpoint=*/false);
  log->info("baked {} probes in {:.3f} s: {} samples, {} rays ({:.2f} Mrays/s)", list.Active(),
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
