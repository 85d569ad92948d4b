// Google Benchmark of the tracer's throughput: a fixed small bake of the demo scene (a 4 x 3 x 2
// probe grid, order 2, default estimator) at one and two threads. Reports rays/s (every ray,
// shadow and validity rays included), samples/s and probes/s per wall second. The job (scene
// load, assets) is built once outside the timed loop; each iteration is one whole Bake().
//
//   probebake_bake_bench [--benchmark_filter=...] [--benchmark_repetitions=N]
#include <benchmark/benchmark.h>

#include <cstdio>
#include <string>

#include "probebake/bake/bake.h"
#include "probebake/base/log.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

#ifndef PROBEBAKE_TEST_DATA_DIR
#error "PROBEBAKE_TEST_DATA_DIR must be defined by the build"
#endif

namespace probebake {
namespace {

// The demo job with a small grid and `samples` samples per probe; aborts the benchmark on error.
BakeJob DemoJob(int64_t samples, v1::BakeSettings::Estimator estimator) {
  const std::string path = std::string(PROBEBAKE_TEST_DATA_DIR) + "/demo/demo.json";
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(path);
  if (!spec.ok()) {
    std::fprintf(stderr, "%s\n", std::string(spec.status().message()).c_str());
    std::abort();
  }
  v1::Grid* grid = spec->mutable_grid();
  grid->clear_spacing();
  grid->clear_counts();
  for (int c : {4, 3, 2}) grid->add_counts(c);
  v1::BakeSettings* s = spec->mutable_settings();
  s->Clear();
  s->set_sh_order(2);
  s->set_samples_per_probe(samples);
  s->set_max_depth(8);
  s->set_estimator(estimator);
  const JobLimits limits;
  absl::StatusOr<BakeJob> job =
      BuildBakeJob(*spec, LocalAssetSource(JobFileDir(path), "", limits.maxAssetBytes), limits);
  if (!job.ok()) {
    std::fprintf(stderr, "%s\n", std::string(job.status().message()).c_str());
    std::abort();
  }
  return *std::move(job);
}

void RunBake(benchmark::State& state, v1::BakeSettings::Estimator estimator) {
  Logger("bake")->set_level(spdlog::level::warn);
  Logger("job")->set_level(spdlog::level::warn);
  const BakeJob job = DemoJob(state.range(0), estimator);
  BakeOptions options;
  options.threads = int(state.range(1));
  int64_t rays = 0, samples = 0, probes = 0;
  for (auto _ : state) {
    absl::StatusOr<ProbeVolume> volume = Bake(job, options);
    if (!volume.ok()) {
      state.SkipWithError(std::string(volume.status().message()).c_str());
      return;
    }
    rays += volume->stats.rays;
    samples += volume->stats.samples;
    probes += volume->stats.probes;
  }
  state.counters["rays/s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsRate);
  state.counters["samples/s"] = benchmark::Counter(double(samples), benchmark::Counter::kIsRate);
  state.counters["probes/s"] = benchmark::Counter(double(probes), benchmark::Counter::kIsRate);
}

void BM_DemoBakeNeeMis(benchmark::State& state) {
  RunBake(state, v1::BakeSettings::NEE_MIS);
}
void BM_DemoBakeDirectionSampling(benchmark::State& state) {
  RunBake(state, v1::BakeSettings::DIRECTION_SAMPLING);
}

// Args: samples per probe, threads. Wall time, since the bake runs its own worker threads.
BENCHMARK(BM_DemoBakeNeeMis)
    ->ArgsProduct({{256, 1024}, {1, 2}})
    ->ArgNames({"samples", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DemoBakeDirectionSampling)
    ->Args({1024, 1})
    ->ArgNames({"samples", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace probebake

BENCHMARK_MAIN();
