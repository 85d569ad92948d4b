// What one benchmark run measured, and its reports: a README-ready markdown page, a CSV of every
// bake, a JSON document of everything, per-probe CSV of the adaptive bakes, and one log-log
// error-vs-time SVG plot per scene (written by hand: no plotting dependency).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "bench_metrics.h"
#include "bench_raw_embree.h"
#include "bench_ray_replay.h"

namespace probebake::bench {

// One bake of one configuration of one scene.
struct BakeRow {
  std::string scene;
  std::string config;           // id, e.g. "nee_mis_sobol"
  std::string label;            // legend text
  std::string group;            // "ladder", "adaptive", "preset" or "depth"
  std::string reference;        // "exact", "same depth" or "deep"
  int64_t samplesPerProbe = 0;  // requested (the cap when adaptive)
  double targetRelError = 0;
  int shOrder = 0, maxDepth = 0, batches = 0, threads = 1;
  std::string estimator, sampler;
  bool russianRoulette = true;
  double wallSeconds = 0;  // minimum over repeats
  double cpuSeconds = 0;   // process CPU time, minimum over repeats
  int64_t rays = 0, samples = 0, probes = 0;
  bool repeatsIdentical = true;  // every repeat gave the same bits
  ErrorSummary error;
  // Adaptive only: share of probes whose reported std_error met the target (the rest hit the
  // cap), and whose measured L0 error was within the target and twice the target.
  double stoppedByTarget = 0, measuredWithinTarget = 0, measuredWithin2Target = 0;
  // RMS of the measured L0 error over the probes stopped by the target (not by the cap), / target.
  double stoppedRmsOverTarget = 0;
  std::vector<ProbeErrors> probeErrors;  // kept for adaptive rows only
};

struct SceneInfo {
  std::string name, description;
  int64_t gridProbes = 0, bakedProbes = 0, triangles = 0;
  std::string referenceText;        // how the reference was made, its own error
  double depthBiasIrradiance = -1;  // mean rel irradiance difference, same-depth vs deep reference
  int ladderDepth = 0, deepDepth = 0;
};

// The tracer against raw Embree replaying the tracer's own rays (bench_ray_replay.h): a section of
// the default bake (1 thread), recorded once, then in back-to-back pairs of the section's tracer
// CPU time and the replay's rates on one CPU.
struct ReplayInfo {
  bool measured = false;
  uint64_t stride = 1;           // the section: probes whose key hashes to 0 modulo stride
  int64_t calls = 0;             // TraceBatches calls in the section
  int64_t rays[kRayKinds] = {};  // recorded, by RayKind, cast or not
  int64_t cast[kRayKinds] = {};  // of those, cast (what both rates count)
  int64_t packed = 0;            // cast rays the tracer traced in 8-wide packets
  // Per pair: the tracer's cast rays per CPU second in the section, the replay's rate one by one
  // and in packets (Mrays per CPU second), and tracer / the better replay.
  std::vector<double> tracerMrays, singleMrays, packetMrays, fractions;
  std::vector<int> cpus;          // the CPU each pair ran on (-1: not pinned)
  std::vector<ReplayRate> rates;  // per kind and API, measured once after the pairs

  int64_t CastRays() const { return cast[0] + cast[1] + cast[2]; }
};

// The tracer's throughput next to raw Embree on the same scene.
struct ThroughputInfo {
  std::string scene;
  double tracerCpuMrays = 0;   // rays per CPU second, default settings, 1 thread
  double tracerWallMrays = 0;  // rays per wall second, same bake
  int64_t rays = 0, samples = 0, intersectRays = 0, shadowRays = 0, validityRays = 0;
  double embreeOnlySeconds = 0;          // CPU time raw Embree needs for the same ray mix
  double embreeOnlySamplingSeconds = 0;  // the same without the validity rays
  double bakeCpuSeconds = 0;
  // A bake of one sample per probe: the fixed cost (BVH, lights, placement, validity rays).
  double setupCpuSeconds = 0;
  int64_t setupRays = 0;
  RawEmbreeResult raw;
  // Paired readings: a tracer bake (default settings, 1 thread) and the raw probe-ray rate
  // measured right after it, several times; each pair's ratio of rays per CPU second. Load that
  // changes during the run moves both halves of a pair alike, so their median is steadier than
  // the ratio of two measurements taken minutes apart.
  std::vector<double> pairedFractions;
  // The CPU each pair ran on (-1: not pinned), one entry per entry of pairedFractions. A shared
  // VM's vCPUs slow down at different times, and they slow the bake more than raw Embree, so a low
  // pair can be traced to its CPU.
  std::vector<int> pairedCpus;
  ReplayInfo replay;
};

struct ScalingInfo {
  std::string scene;
  int64_t samplesPerProbe = 0, probes = 0;
  std::vector<double> wall1, wall2, cpu1, cpu2;  // every repeat
  double load = 0;
  double rawRatio = 0;  // raw Embree 2-thread / 1-thread wall rate, same moment (control)
};

// The demo room with its ceiling light replaced by N lights, at 1 thread: how the light choice's
// cost and quality scale with N (LightSet picks through a light tree from kLightTreeMinLights
// lights of a kind).
struct ManyLightsRow {
  std::string layout;  // "ceiling": small rects over the ceiling; "volume": mixed, through the room
  int lights = 0;
  int64_t probes = 0, samplesPerProbe = 0;
  double cpu = 0;           // CPU s, best of the repeats
  double meanStdError = 0;  // mean reported relative standard error of L0 over the probes
  size_t treeLights = 0;    // lights chosen through light trees
};

struct MemoryInfo {
  bool measured = false;
  std::string note;
  int64_t probes = 0;
  int shOrder = 0;
  int64_t samplesPerProbe = 0;
  double bakeSeconds = 0;
  int64_t baselineRss = 0;     // before the job was built
  int64_t peakBake = 0;        // VmHWM after the bake
  int64_t shBytes = 0;         // radiance planes
  int64_t volumeBytes = 0;     // every array of the ProbeVolume
  int64_t peakWriteExtra = 0;  // VmHWM during the write minus RSS before it (-1 unknown)
  int64_t vdbBytes = 0;
  double writeSeconds = 0;
};

struct BenchResults {
  bool quick = false;
  std::string date, host, generator;
  int hardwareThreads = 0;
  double loadStart = 0, loadEnd = 0, totalSeconds = 0;
  std::vector<int64_t> ladder;
  std::vector<SceneInfo> scenes;
  std::vector<BakeRow> rows;
  std::vector<ThroughputInfo> throughput;
  ScalingInfo scaling;
  std::vector<ManyLightsRow> manyLights;
  MemoryInfo memory;
  std::string presetText;  // the current preset numbers
};

// Writes results.md, results.csv, results.json, adaptive_probes.csv and error_vs_time_<scene>.svg
// into `dir`.
absl::Status WriteReports(const BenchResults& results, const std::string& dir);

// The replay of the tracer's own rays (ReplayInfo) of every scene that has one, as markdown: the
// fraction table next to the probe-ray pairs' fraction, and each kind's rates.
std::string ReplayMarkdown(const BenchResults& results);

// Reads back a results.json written by WriteReports: everything the document blocks below need
// (the run, scenes, every bake row, throughput, scaling, memory). Not in the JSON, and so left
// empty: the rows' labels and per-probe errors, the many-lights rows and raw Embree's probe count.
// INVALID_ARGUMENT naming the path and the key when the file is not such a document.
absl::StatusOr<BenchResults> ReadResultsJson(const std::string& path);

// The documents that embed the last run's figures, relative to the source folder: README.md and
// docs/accuracy-and-speed.md. Each marks a generated block as
//   <!-- bench:NAME -->
//   ...
//   <!-- /bench:NAME -->
// UpdateDocuments rewrites the text between every such pair from `results`, so those figures are
// never typed by hand; the rest of each document is left as it is. Blocks: run (when, where,
// what the figures mean), time-to-error (the demo room's table of estimators), speedups, presets,
// adaptive, honesty, throughput, scaling-memory, depth, settings. INVALID_ARGUMENT naming the
// document for an unknown block or a marker without its end.
inline constexpr const char* kBenchDocuments[] = {"README.md", "docs/accuracy-and-speed.md"};
absl::Status UpdateDocuments(const BenchResults& results, const std::string& sourceDir);

}  // namespace probebake::bench
