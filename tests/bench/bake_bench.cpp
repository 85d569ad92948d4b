// Google Benchmark of the tracer's throughput: a fixed small bake of the demo scene (a 4 x 3 x 2
// probe grid, order 2, default estimator) at one and two threads. Reports rays/s (every ray,
// shadow and validity rays included), samples/s and probes/s per wall second. The job (scene
// load, assets) is built once outside the timed loop; each iteration is one whole Bake().
// BM_DemoBakeSkyScale bakes the same job with each texel of its sky repeated k x k times: the
// same light, in tables k^2 times as large, so the difference is what a large map costs (building
// its tables once per bake, and reading them from memory per sample).
// BM_LoftBake bakes the authored demo level (demo-gltf.json: textures, a cutout trellis, a KHR
// lamp) as authored and with every material made constant (its texture's mean colour, no cutout):
// the same geometry, lights and grid, so rays/s is what textures and cutouts cost per ray.
//
//   probebake_bake_bench [--benchmark_filter=...] [--benchmark_repetitions=N]
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include "core/src/bake/surface_material.h"
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

// A demo job (`file` in tests/data/demo) with a small grid and `samples` samples per probe; aborts
// the benchmark on error.
BakeJob DemoJob(int64_t samples, v1::BakeSettings::Estimator estimator,
                const std::string& file = "demo.json") {
  const std::string path = std::string(PROBEBAKE_TEST_DATA_DIR) + "/demo/" + file;
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

// Times whole bakes of `job` and reports rays, samples and probes per second.
void TimeBakes(benchmark::State& state, const BakeJob& job, int threads) {
  BakeOptions options;
  options.threads = threads;
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

void QuietLogs() {
  Logger("bake")->set_level(spdlog::level::warn);
  Logger("job")->set_level(spdlog::level::warn);
}

void RunBake(benchmark::State& state, v1::BakeSettings::Estimator estimator) {
  QuietLogs();
  TimeBakes(state, DemoJob(state.range(0), estimator), int(state.range(1)));
}

// The map with every texel repeated k x k times (nearest-neighbour upsampling: the same sky).
std::shared_ptr<const EnvironmentMap> Upsampled(const EnvironmentMap& map, int k) {
  auto big = std::make_shared<EnvironmentMap>(map);
  big->width = map.width * k;
  big->height = map.height * k;
  big->rgb.assign(size_t(big->width) * big->height * 3, 0.0f);
  for (int y = 0; y < big->height; ++y) {
    for (int x = 0; x < big->width; ++x) {
      const float* src = &map.rgb[3 * (size_t(y / k) * map.width + x / k)];
      std::copy(src, src + 3, &big->rgb[3 * (size_t(y) * big->width + x)]);
    }
  }
  big->digest += "-upsampled";
  return big;
}

void BM_DemoBakeSkyScale(benchmark::State& state) {
  QuietLogs();
  BakeJob job = DemoJob(state.range(1), v1::BakeSettings::NEE_MIS);
  if (!job.scene.environment.map) {
    state.SkipWithError("the demo scene has no environment map");
    return;
  }
  const int k = int(state.range(0));
  if (k > 1) job.scene.environment.map = Upsampled(*job.scene.environment.map, k);
  state.SetLabel(std::to_string(job.scene.environment.map->width) + " x " +
                 std::to_string(job.scene.environment.map->height) + " sky");
  TimeBakes(state, job, 1);
}

// Args: constant (0: as authored, 1: every material constant), threads.
void BM_LoftBake(benchmark::State& state) {
  QuietLogs();
  BakeJob job = DemoJob(1024, v1::BakeSettings::NEE_MIS, "demo-gltf.json");
  int textured = 0, cutouts = 0;
  for (Material& m : job.scene.materials) {
    textured += m.AlbedoVaries();
    cutouts += m.HasCutout();
    if (state.range(0) == 0) continue;
    m.albedo = MeanAlbedo(m);
    m.albedoMap = m.coverageMap = TextureMap{};
    m.vertexColors = false;
    m.alphaCutoff = 0;
  }
  state.SetLabel(state.range(0) ? "constant albedo, no cutout"
                                : std::to_string(textured) + " textured materials, " +
                                      std::to_string(cutouts) + " cutout");
  TimeBakes(state, job, int(state.range(1)));
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
BENCHMARK(BM_LoftBake)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->ArgNames({"constant", "threads"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
// Args: k, the sky's upsampling (1: the bundled 128 x 64; 16: 2048 x 1024), and samples per probe;
// 1 thread. Building the sky's tables is part of each bake: the difference between the two sample
// counts is the sampling's cost alone.
BENCHMARK(BM_DemoBakeSkyScale)
    ->ArgsProduct({{1, 4, 16}, {256, 4096}})
    ->ArgNames({"k", "samples"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace probebake

BENCHMARK_MAIN();
