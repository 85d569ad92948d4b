// Writing a dense L2 probe volume: time, file size and the memory the write adds.
//
// Memory: the peak resident set (VmHWM) is reset before each write (/proc/self/clear_refs), so
// "extraPeak_MiB" is the most the write added on top of the volume already in memory. Run:
// probebake_volume_bench [--benchmark_filter=...].
#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>

#include "probebake/volume/vdb_io.h"
#include "volume/test_volumes.h"

namespace probebake {
namespace {

using testing::MakeTestMetadata;
using testing::MakeTestVolume;
using testing::TempDir;
using testing::TestVolumeSpec;

constexpr double kMiB = 1024.0 * 1024.0;

double VolumeMiB(const ProbeVolume& v) {
  size_t bytes = v.active.size() + 4 * (v.validity.size() + v.stdError.size() +
                                        v.stdErrorL0.size() + v.sampleCount.size());
  for (const auto& plane : v.radiance) bytes += 4 * plane.size();
  for (const auto& plane : v.irradiance) bytes += 4 * plane.size();
  return double(bytes) / kMiB;
}

// A dense (every probe active and valid) order-2 volume of n^3 probes.
ProbeVolume DenseVolume(int n) {
  TestVolumeSpec spec;
  spec.counts[0] = spec.counts[1] = spec.counts[2] = n;
  spec.shOrder = 2;
  spec.inactiveEvery = 0;
  spec.invalidEvery = 0;
  spec.awkwardValues = false;
  return MakeTestVolume(spec);
}

void BM_WriteDenseL2(benchmark::State& state) {
  const int n = int(state.range(0));
  const bool consume = state.range(1) != 0;
  const ProbeVolume volume = DenseVolume(n);
  TempDir dir;
  const std::string path = dir.File("dense.vdb");
  double extraPeak = 0;
  for (auto _ : state) {
    state.PauseTiming();
    ProbeVolume copy = consume ? volume : ProbeVolume{};
    testing::ResetPeakRss();
    const int64_t before = testing::CurrentRssBytes();
    state.ResumeTiming();
    const absl::Status status = consume
                                    ? WriteProbeVolume(path, std::move(copy), MakeTestMetadata())
                                    : WriteProbeVolume(path, volume, MakeTestMetadata());
    state.PauseTiming();
    extraPeak = std::max(extraPeak, double(testing::PeakRssBytes() - before) / kMiB);
    state.ResumeTiming();
    if (!status.ok()) {
      state.SkipWithError(std::string(status.message()).c_str());
      return;
    }
  }
  state.counters["probes"] = double(volume.grid.ProbeCount());
  state.counters["volume_MiB"] = VolumeMiB(volume);
  state.counters["file_MiB"] = double(std::filesystem::file_size(path)) / kMiB;
  state.counters["extraPeak_MiB"] = extraPeak;
  state.counters["probes_per_s"] = benchmark::Counter(
      double(volume.grid.ProbeCount()), benchmark::Counter::kIsIterationInvariantRate);
}

BENCHMARK(BM_WriteDenseL2)
    ->ArgNames({"n", "consume"})
    ->Args({64, 0})
    ->Args({64, 1})
    ->Args({128, 0})
    ->Args({128, 1})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(2);

void BM_ReadDenseL2(benchmark::State& state) {
  const int n = int(state.range(0));
  TempDir dir;
  const std::string path = dir.File("dense.vdb");
  if (!WriteProbeVolume(path, DenseVolume(n), MakeTestMetadata()).ok()) {
    state.SkipWithError("write failed");
    return;
  }
  for (auto _ : state) {
    const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
    if (!read.ok()) {
      state.SkipWithError(std::string(read.status().message()).c_str());
      return;
    }
    benchmark::DoNotOptimize(read->volume.radiance.data());
  }
  state.counters["probes_per_s"] =
      benchmark::Counter(double(n) * n * n, benchmark::Counter::kIsIterationInvariantRate);
}

BENCHMARK(BM_ReadDenseL2)->Arg(64)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace
}  // namespace probebake

BENCHMARK_MAIN();
