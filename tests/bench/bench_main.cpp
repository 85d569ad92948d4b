// probebake-bench: the accuracy and speed benchmark (docs/accuracy-and-speed.md). Run by
// scripts/bench.sh; see tests/bench/README.md for what it measures and how.
//
//   probebake-bench [--quick] [--out DIR] [--cache DIR] [--work DIR] [--source DIR]
//                   [--repeats N] [--scenes a,b] [--no-memory] [--no-embree] [--scaling-only]
//                   [--replay-only] [--docs-only]
//
// Bakes every scene (bench_scenes.h) at a ladder of sample counts for several estimator
// configurations, adaptive targets and the quality presets, at one thread each (so time measures
// work, not scheduling), compares each bake with a reference (bench_reference.h), measures raw
// Embree on the same probes' rays (bench_raw_embree.h) and on the rays the tracer itself casts,
// recorded and replayed (bench_ray_replay.h), 1- vs 2-thread scaling, and the peak memory of a
// dense 128^3 order-2 bake in a child process, then writes the reports (bench_report.h). A full
// run into the source tree also rewrites the figures README.md and docs/accuracy-and-speed.md
// embed; --docs-only rewrites them from the committed results.json alone.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>

#include "bench_metrics.h"
#include "bench_raw_embree.h"
#include "bench_ray_replay.h"
#include "bench_reference.h"
#include "bench_report.h"
#include "bench_scenes.h"
#include "bench_util.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/bake/bake.h"
#include "probebake/base/check.h"
#include "probebake/base/log.h"
#include "probebake/base/version.h"
#include "probebake/job/job.h"
#include "probebake/sampling/hash.h"
#include "probebake/sampling/sampler.h"
#include "probebake/volume/vdb_io.h"

#ifndef PROBEBAKE_SOURCE_DIR
#error "PROBEBAKE_SOURCE_DIR must be defined by the build"
#endif
#ifndef PROBEBAKE_BINARY_DIR
#error "PROBEBAKE_BINARY_DIR must be defined by the build"
#endif

namespace probebake::bench {
namespace {

// Reference sample counts are this multiple of the largest count compared with them: a reference
// bake's own error is then an eighth of the bakes' it judges.
constexpr int64_t kReferenceFactor = 64;
// Depth of the ladder's bakes, and of the "deep" reference that stands for unlimited depth.
constexpr int kLadderDepth = 8;
constexpr int kDeepDepth = 64;
constexpr uint64_t kBakeSeed = 1;
constexpr uint64_t kReferenceSeed = 0x5eed0001;
constexpr int kReferenceOrder = 3;
constexpr int kReferenceBatches = 64;
// Paired tracer / raw Embree readings per scene (ThroughputInfo::pairedFractions). Seven, so
// that their median holds when a load spike hits up to three of them.
constexpr int kThroughputPairs = 7;
// The replay's section holds about this many probes (ReplayInfo), and is read in this many pairs.
constexpr int64_t kReplayProbes = 16;
constexpr int kReplayPairs = 5;

struct Options {
  bool quick = false;
  std::string out, cache, work, source = PROBEBAKE_SOURCE_DIR;
  int repeats = -1;
  std::vector<std::string> scenes;
  bool memory = true, embree = true;
  bool scalingOnly = false;  // only the 1- vs 2-thread scaling (for a quiet moment)
  // Only the tracer against raw Embree (the probe-ray pairs and the replay of the tracer's own
  // rays) at the throughput bake's settings, reported in <out>/replay.md.
  bool replayOnly = false;
  // Rebuild the documents' generated blocks from <out>/results.json; no bake.
  bool docsOnly = false;
  // The reports go to the source's tests/bench/results: the documents embedding their figures
  // (kBenchDocuments) are then updated too.
  bool committedResults = false;
};

struct Config {
  std::string id, label, group;
  v1::BakeSettings settings;  // samples_per_probe unset for ladder configs
  // The default of baker version 19, before light traced from directional lights (20), the
  // environment guide and the visibility floor of 1/32 (21) and the shadow rays' roulette (23):
  // BakeSettings' distantLightTracing, environmentGuide and shadowRoulette off and
  // lightVisibilityFloor 1/8, none of them job fields.
  bool formerDefault = false;
};

v1::BakeSettings BaseSettings() {
  v1::BakeSettings s;
  s.set_sh_order(2);
  s.set_max_depth(kLadderDepth);
  s.set_seed(kBakeSeed);
  s.set_irradiance(false);
  s.set_estimator(v1::BakeSettings::NEE_MIS);
  s.set_sampler(v1::BakeSettings::SOBOL);
  s.set_russian_roulette(true);
  // batches unset: the default (4, or 64 when adaptive).
  return s;
}

std::vector<Config> LadderConfigs() {
  std::vector<Config> out;
  auto add = [&](std::string id, std::string label, auto&& edit) {
    Config c{std::move(id), std::move(label), "ladder", BaseSettings()};
    edit(c.settings);
    out.push_back(std::move(c));
  };
  add("naive", "naive: direction sampling, independent", [](v1::BakeSettings& s) {
    s.set_estimator(v1::BakeSettings::DIRECTION_SAMPLING);
    s.set_sampler(v1::BakeSettings::INDEPENDENT);
  });
  add("nee_sobol", "NEE only, Sobol",
      [](v1::BakeSettings& s) { s.set_estimator(v1::BakeSettings::LIGHT_SAMPLING); });
  add("nee_mis_independent", "NEE+MIS, independent",
      [](v1::BakeSettings& s) { s.set_sampler(v1::BakeSettings::INDEPENDENT); });
  add("nee_mis_sobol", "NEE+MIS, Sobol (default)", [](v1::BakeSettings&) {});
  add("nee_mis_sobol_b16", "NEE+MIS, Sobol, 16 batches",
      [](v1::BakeSettings& s) { s.set_batches(16); });
  add("nee_mis_sobol_v19", "NEE+MIS, Sobol, the default of baker version 19",
      [](v1::BakeSettings&) {});
  out.back().formerDefault = true;
  add("nee_mis_sobol_no_rr", "NEE+MIS, Sobol, no roulette",
      [](v1::BakeSettings& s) { s.set_russian_roulette(false); });
  add("order1", "NEE+MIS, Sobol, order 1", [](v1::BakeSettings& s) { s.set_sh_order(1); });
  add("order3", "NEE+MIS, Sobol, order 3", [](v1::BakeSettings& s) { s.set_sh_order(3); });
  return out;
}

std::vector<Config> AdaptiveConfigs(bool quick, int64_t cap) {
  std::vector<Config> out;
  const std::vector<double> targets =
      quick ? std::vector<double>{0.05, 0.02} : std::vector<double>{0.05, 0.02, 0.01, 0.005};
  for (int batches : {16, 64}) {
    for (double t : targets) {
      Config c{Format("adaptive_b%d_%g", batches, t),
               Format("adaptive %g%% (%d batches)", 100 * t, batches), "adaptive", BaseSettings()};
      c.settings.set_samples_per_probe(cap);
      c.settings.set_target_rel_error(t);
      c.settings.set_batches(batches);
      out.push_back(std::move(c));
    }
  }
  return out;
}

std::vector<Config> PresetConfigs() {
  std::vector<Config> out;
  for (auto q :
       {v1::BakeSettings::PREVIEW, v1::BakeSettings::PRODUCTION, v1::BakeSettings::REFERENCE}) {
    Config c{"preset_" + v1::BakeSettings::Quality_Name(q), v1::BakeSettings::Quality_Name(q),
             "preset", BaseSettings()};
    c.settings.clear_max_depth();
    c.settings.clear_batches();  // the preset's own default
    c.settings.set_quality(q);
    out.push_back(std::move(c));
  }
  return out;
}

std::string EstimatorName(Estimator e) {
  switch (e) {
    case Estimator::kNeeMis:
      return "NEE_MIS";
    case Estimator::kLightSampling:
      return "LIGHT_SAMPLING";
    case Estimator::kDirectionSampling:
      return "DIRECTION_SAMPLING";
  }
  return "?";
}

struct Timed {
  ProbeVolume volume;
  double wall = 0, cpu = 0;
  bool identical = true;
};

bool SameBits(const ProbeVolume& a, const ProbeVolume& b) {
  return a.radiance == b.radiance && a.stdError == b.stdError && a.stdErrorL0 == b.stdErrorL0 &&
         a.sampleCount == b.sampleCount && a.active == b.active;
}

// A bake longer than this (CPU seconds) is not repeated: its timing noise is small already.
constexpr double kRepeatBelowSeconds = 2;

// Bakes `job` up to `repeats` times on `threads` threads; the minimum wall and CPU time.
absl::StatusOr<Timed> TimedBake(const BakeJob& job, int threads, int repeats) {
  Timed t;
  t.wall = t.cpu = std::numeric_limits<double>::infinity();
  BakeOptions options;
  options.threads = threads;
  options.coefficientErrors = true;
  for (int r = 0; r < repeats; ++r) {
    const double w0 = WallSeconds(), c0 = ProcessCpuSeconds();
    absl::StatusOr<ProbeVolume> v = Bake(job, options);
    const double wall = WallSeconds() - w0, cpu = ProcessCpuSeconds() - c0;
    if (!v.ok()) return v.status();
    t.wall = std::min(t.wall, wall);
    t.cpu = std::min(t.cpu, cpu);
    if (r == 0) {
      t.volume = *std::move(v);
    } else if (!SameBits(t.volume, *v)) {
      t.identical = false;
    }
    if (cpu > kRepeatBelowSeconds) break;
  }
  return t;
}

// Bakes `a` and `b` in turn, `repeats` times each (a, b, a, b, ...) on one thread; the minimum
// CPU and wall time of each. For two configurations whose times are compared: this machine's
// load drifts over minutes, and a ladder of one after the other's would carry the drift into
// their ratio.
absl::StatusOr<std::pair<Timed, Timed>> TimedPair(const BakeJob& a, const BakeJob& b, int repeats) {
  std::pair<Timed, Timed> t;
  for (int r = 0; r < repeats; ++r) {
    PB_ASSIGN_OR_RETURN(Timed ta, TimedBake(a, 1, 1));
    PB_ASSIGN_OR_RETURN(Timed tb, TimedBake(b, 1, 1));
    if (r == 0) {
      t = {std::move(ta), std::move(tb)};
      continue;
    }
    for (auto [kept, now] : {std::pair{&t.first, &ta}, std::pair{&t.second, &tb}}) {
      kept->wall = std::min(kept->wall, now->wall);
      kept->cpu = std::min(kept->cpu, now->cpu);
      kept->identical = kept->identical && SameBits(kept->volume, now->volume);
    }
  }
  return t;
}

BakeRow MakeRow(const BenchScene& scene, const Config& config, const BakeJob& job, const Timed& t,
                const Reference& reference, const std::string& referenceName) {
  BakeRow row;
  row.scene = scene.name;
  row.config = config.id;
  row.label = config.label;
  row.group = config.group;
  row.reference = referenceName;
  const BakeSettings& s = job.settings;
  row.samplesPerProbe = s.samplesPerProbe;
  row.targetRelError = s.targetRelError;
  row.shOrder = s.shOrder;
  row.maxDepth = s.maxDepth;
  row.batches = s.batches;
  row.threads = t.volume.stats.threads;
  row.estimator = EstimatorName(s.estimator);
  row.sampler = s.sampler == SamplerKind::kSobol ? "SOBOL" : "INDEPENDENT";
  row.russianRoulette = s.russianRoulette;
  row.wallSeconds = t.wall;
  row.cpuSeconds = t.cpu;
  row.rays = t.volume.stats.rays;
  row.samples = t.volume.stats.samples;
  row.probes = t.volume.stats.probes;
  row.repeatsIdentical = t.identical;
  std::vector<ProbeErrors> errors = CompareWithReference(t.volume, reference);
  row.error = Summarise(errors);
  if (config.group == "adaptive" && !errors.empty()) {
    const double target = s.targetRelError;
    double stopped = 0, within = 0, within2 = 0, stoppedSq = 0;
    for (const ProbeErrors& e : errors) {
      // The target bounds std_error, the luminance irradiance error's estimate.
      if (e.stdError <= target) stoppedSq += e.irradianceLumRel * e.irradianceLumRel;
      stopped += e.stdError <= target ? 1 : 0;
      within += e.irradianceLumRel <= target ? 1 : 0;
      within2 += e.irradianceLumRel <= 2 * target ? 1 : 0;
    }
    const double n = double(errors.size());
    row.stoppedByTarget = stopped / n;
    row.measuredWithinTarget = within / n;
    row.measuredWithin2Target = within2 / n;
    row.stoppedRmsOverTarget = stopped > 0 ? std::sqrt(stoppedSq / stopped) / target : 0;
    row.probeErrors = std::move(errors);
  }
  return row;
}

v1::BakeSettings ReferenceSettings(int depth, int64_t samples) {
  v1::BakeSettings s = BaseSettings();
  s.set_sh_order(kReferenceOrder);
  s.set_max_depth(depth);
  s.set_samples_per_probe(samples);
  s.set_seed(kReferenceSeed);
  s.set_batches(kReferenceBatches);
  return s;
}

// ---- memory: a dense order-2 bake in a child process ----

int MemoryChild(const std::string& resultPath, int n, int64_t spp, const std::string& vdbPath,
                const std::string& source) {
  BenchScene scene;
  scene.name = "sky_sphere";
  scene.jobPath = source + "/tests/bench/scenes/sky_sphere.json";
  scene.counts = {n, n, n};
  const int64_t baseline = CurrentRssBytes();
  v1::BakeSettings settings = BaseSettings();
  settings.set_samples_per_probe(spp);
  settings.set_irradiance(true);
  absl::StatusOr<BakeJob> job = BuildSceneJob(scene, settings);
  if (!job.ok()) {
    std::fprintf(stderr, "memory child: %s\n", std::string(job.status().message()).c_str());
    return 1;
  }
  const bool reset = ResetPeakRss();
  BakeOptions options;
  const double t0 = WallSeconds();
  absl::StatusOr<ProbeVolume> volume = Bake(*job, options);
  const double bakeSeconds = WallSeconds() - t0;
  if (!volume.ok()) {
    std::fprintf(stderr, "memory child: %s\n", std::string(volume.status().message()).c_str());
    return 1;
  }
  const int64_t peakBake = PeakRssBytes();
  int64_t sh = 0, all = int64_t(volume->active.size());
  for (const auto& plane : volume->radiance) sh += int64_t(plane.size() * sizeof(float));
  for (const auto& plane : volume->irradiance) sh += int64_t(plane.size() * sizeof(float));
  all += sh + int64_t(sizeof(float)) * int64_t(volume->validity.size() + volume->stdError.size() +
                                               volume->sampleCount.size());
  VolumeMetadata meta;
  meta.samplesPerProbe = spp;
  meta.maxDepth = job->settings.maxDepth;
  meta.seed = job->settings.seed;
  meta.sceneDigest = job->sceneDigest;
  meta.settingsJson = job->settingsJson;
  const bool reset2 = ResetPeakRss();
  const int64_t before = CurrentRssBytes();
  const double w0 = WallSeconds();
  const absl::Status written = WriteProbeVolume(vdbPath, *volume, meta);
  const double writeSeconds = WallSeconds() - w0;
  const int64_t peakWrite = PeakRssBytes();
  if (!written.ok()) {
    std::fprintf(stderr, "memory child: %s\n", std::string(written.message()).c_str());
    return 1;
  }
  std::error_code ec;
  const int64_t vdbBytes = int64_t(std::filesystem::file_size(vdbPath, ec));
  std::filesystem::remove(vdbPath, ec);
  std::ofstream out(resultPath);
  out << "probes " << volume->stats.probes << "\n"
      << "bakeSeconds " << bakeSeconds << "\n"
      << "baselineRss " << baseline << "\n"
      << "peakBake " << (reset ? peakBake : -1) << "\n"
      << "shBytes " << sh << "\n"
      << "volumeBytes " << all << "\n"
      << "peakWriteExtra " << (reset2 ? peakWrite - before : -1) << "\n"
      << "vdbBytes " << vdbBytes << "\n"
      << "writeSeconds " << writeSeconds << "\n";
  return out ? 0 : 1;
}

MemoryInfo MeasureMemory(const Options& opt, int n, int64_t spp) {
  MemoryInfo info;
  info.shOrder = 2;
  info.samplesPerProbe = spp;
  const std::string result = opt.work + "/memory-result.txt";
  const std::string vdb = opt.work + "/memory-dense.vdb";
  std::filesystem::remove(result);
  const std::string nText = std::to_string(n), sppText = std::to_string(spp);
  const pid_t pid = fork();
  if (pid == 0) {
    const char* argv[] = {"probebake-bench", "--memory-child", result.c_str(),     nText.c_str(),
                          sppText.c_str(),   vdb.c_str(),      opt.source.c_str(), nullptr};
    execv("/proc/self/exe", const_cast<char* const*>(argv));
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    info.note = "the memory child failed (status " + std::to_string(status) + ")";
    return info;
  }
  std::ifstream in(result);
  std::map<std::string, double> kv;
  std::string key;
  double value;
  while (in >> key >> value) kv[key] = value;
  info.measured = true;
  info.probes = int64_t(kv["probes"]);
  info.bakeSeconds = kv["bakeSeconds"];
  info.baselineRss = int64_t(kv["baselineRss"]);
  info.peakBake = int64_t(kv["peakBake"]);
  info.shBytes = int64_t(kv["shBytes"]);
  info.volumeBytes = int64_t(kv["volumeBytes"]);
  info.peakWriteExtra = int64_t(kv["peakWriteExtra"]);
  info.vdbBytes = int64_t(kv["vdbBytes"]);
  info.writeSeconds = kv["writeSeconds"];
  return info;
}

// The tracer against raw Embree on its own rays (bench_ray_replay.h): `job` (the throughput
// bake's settings) baked at 1 thread once with a RayRecorder on a section of about
// kReplayProbes of its `activeProbes` probes, then `pairs` times a SectionTimer bake followed by
// the replay of the recorded rays, both on one CPU; then each kind's rates alone.
absl::Status MeasureReplay(const BakeJob& job, int64_t activeProbes, bool quick, int pairs,
                           ReplayInfo* out) {
  auto log = Logger("bench");
  BakeOptions options;
  options.threads = 1;
  BakeSection section{uint64_t(std::max<int64_t>(1, activeProbes / kReplayProbes))};
  std::unique_ptr<RayRecorder> recorder;
  for (;;) {
    recorder = std::make_unique<RayRecorder>(section);
    options.rayObserver = recorder.get();
    PB_RETURN_IF_ERROR(Bake(job, options).status());
    if (!recorder->rays().empty() || section.stride == 1) break;
    section.stride = 1;  // no probe's key fell in the section: take them all
  }
  out->stride = section.stride;
  out->calls = recorder->calls();
  for (int k = 0; k < kRayKinds; ++k) {
    out->rays[k] = recorder->Count(RayKind(k), false);
    out->cast[k] = recorder->Count(RayKind(k), true);
  }
  for (const ObservedRay& r : recorder->rays()) out->packed += r.cast && r.packed;
  PB_ASSIGN_OR_RETURN(const RayReplay replay, RayReplay::Build(job.scene, recorder->rays()));
  recorder.reset();
  const double minSeconds = quick ? 0.05 : 0.2;
  for (int k = 0; k < pairs; ++k) {
    const CpuPin pin;
    SectionTimer timer(section);
    options.rayObserver = &timer;
    PB_RETURN_IF_ERROR(Bake(job, options).status());
    const double tracer = double(out->CastRays()) / timer.cpuSeconds() * 1e-6;
    const ReplayRate single = replay.Measure("single", nullptr, minSeconds, 3);
    const ReplayRate packet = replay.Measure("packet8", nullptr, minSeconds, 3);
    const double best = std::max(single.cpuMraysPerSecond, packet.cpuMraysPerSecond);
    log->info(
        "replay pair {} on CPU {}: tracer {:.3g} Mrays/CPU-s ({} calls, {:.3f} s), replay single "
        "{:.3g}, packet8 {:.3g}: fraction {:.2f}",
        k, pin.cpu(), tracer, timer.calls(), timer.cpuSeconds(), single.cpuMraysPerSecond,
        packet.cpuMraysPerSecond, tracer / best);
    out->tracerMrays.push_back(tracer);
    out->singleMrays.push_back(single.cpuMraysPerSecond);
    out->packetMrays.push_back(packet.cpuMraysPerSecond);
    out->fractions.push_back(tracer / best);
    out->cpus.push_back(pin.cpu());
  }
  for (const char* api : {"single", "packet8"}) {
    for (int k = 0; k < kRayKinds; ++k) {
      const RayKind kind = RayKind(k);
      out->rates.push_back(replay.Measure(api, &kind, minSeconds, 3));
    }
  }
  out->measured = true;
  return absl::OkStatus();
}

// --replay-only: for every scene, the probe-ray pairs of the throughput section (today's
// coherent figure) and MeasureReplay, at the throughput bake's settings; written to
// <out>/replay.md (ReplayMarkdown).
absl::Status RunReplayOnly(const Options& opt) {
  auto log = Logger("bench");
  BenchResults results;
  results.quick = opt.quick;
  results.loadStart = LoadAverage1();
  PB_ASSIGN_OR_RETURN(const std::vector<BenchScene> scenes,
                      PrepareScenes(opt.source, opt.work, opt.quick));
  const int64_t spp = opt.quick ? 256 : 4096;  // the ladder's largest, as in Run
  for (const BenchScene& scene : scenes) {
    if (!opt.scenes.empty() &&
        std::find(opt.scenes.begin(), opt.scenes.end(), scene.name) == opt.scenes.end())
      continue;
    v1::BakeSettings s = BaseSettings();
    s.set_samples_per_probe(spp);
    PB_ASSIGN_OR_RETURN(const BakeJob job, BuildSceneJob(scene, s));
    ThroughputInfo tp;
    tp.scene = scene.name;
    PB_ASSIGN_OR_RETURN(const Timed t, TimedBake(job, 1, 1));
    tp.rays = t.volume.stats.rays;
    tp.samples = t.volume.stats.samples;
    std::vector<Vec3d> probes;
    for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
      if (!t.volume.active[p]) continue;
      int i, j, k;
      job.grid.Coords(p, &i, &j, &k);
      probes.push_back(job.grid.Position(i, j, k));
    }
    for (int k = 0; k < 3; ++k) {
      const CpuPin pin;
      PB_ASSIGN_OR_RETURN(const Timed b, TimedBake(job, 1, 1));
      PB_ASSIGN_OR_RETURN(const RawRate rate,
                          MeasureRawProbeRate(job, probes, opt.quick ? 0.05 : 0.25, 3));
      tp.pairedFractions.push_back(double(b.volume.stats.rays) / b.cpu * 1e-6 /
                                   rate.cpuMraysPerSecond);
      tp.pairedCpus.push_back(pin.cpu());
    }
    log->info("{}: replay of the tracer's own rays", scene.name);
    PB_RETURN_IF_ERROR(
        MeasureReplay(job, int64_t(probes.size()), opt.quick, kReplayPairs, &tp.replay));
    results.throughput.push_back(std::move(tp));
  }
  results.loadEnd = LoadAverage1();
  const std::string md = ReplayMarkdown(results);
  std::printf("%s", md.c_str());
  return WriteFileAtomic(opt.out + "/replay.md", md);
}

// ---- the run ----

std::string DefaultCacheDir() {
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg)
    return std::string(xdg) + "/probebake-bench";
  if (const char* home = std::getenv("HOME"); home && *home)
    return std::string(home) + "/.cache/probebake-bench";
  return std::string(PROBEBAKE_BINARY_DIR) + "/bench-cache";
}

absl::Status Run(const Options& opt) {
  auto log = Logger("bench");
  BenchResults results;
  results.quick = opt.quick;
  results.hardwareThreads = HardwareThreads();
  results.loadStart = LoadAverage1();
  results.generator = std::string(kGeneratorName) + " " + kVersion + " (baker version " +
                      std::to_string(kBakerVersion) + ")";
  // scripts/bench.sh passes the commit (and whether the tree had local changes).
  if (const char* commit = std::getenv("PROBEBAKE_BENCH_COMMIT"); commit && *commit)
    results.generator += std::string(", commit ") + commit;
  {
    char host[256] = {};
    gethostname(host, sizeof(host) - 1);
    results.host = host;
    const std::time_t now = std::time(nullptr);
    char date[64];
    std::strftime(date, sizeof(date), "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
    results.date = date;
  }
  const double runStart = WallSeconds();
  const int repeats = opt.repeats > 0 ? opt.repeats : (opt.quick ? 1 : 2);
  for (int64_t spp = 16; spp <= (opt.quick ? 256 : 4096); spp *= 2) results.ladder.push_back(spp);
  const int64_t ladderMax = results.ladder.back();
  const int64_t refSamples = kReferenceFactor * ladderMax;
  // The throughput comparison uses the longest ladder bake (~1 s of CPU in the full run), whose
  // timing noise is smallest; scaling uses 1024 samples (4096 in the full run).
  const int64_t throughputSpp = ladderMax;
  {
    const QualityPreset p = PresetFor(v1::BakeSettings::PREVIEW);
    const QualityPreset q = PresetFor(v1::BakeSettings::PRODUCTION);
    const QualityPreset r = PresetFor(v1::BakeSettings::REFERENCE);
    results.presetText = Format(
        "PREVIEW %lld samples / depth %d / target %g, PRODUCTION %lld / %d / %g, REFERENCE %lld / "
        "%d / %g",
        (long long)p.samplesPerProbe, p.maxDepth, p.targetRelError, (long long)q.samplesPerProbe,
        q.maxDepth, q.targetRelError, (long long)r.samplesPerProbe, r.maxDepth, r.targetRelError);
  }

  PB_ASSIGN_OR_RETURN(const std::vector<BenchScene> scenes,
                      PrepareScenes(opt.source, opt.work, opt.quick));
  for (const BenchScene& scene : scenes) {
    if (opt.scalingOnly) break;
    if (!opt.scenes.empty() &&
        std::find(opt.scenes.begin(), opt.scenes.end(), scene.name) == opt.scenes.end())
      continue;
    log->info("=== scene {}: {}", scene.name, scene.description);
    SceneInfo info;
    info.name = scene.name;
    info.description = scene.description;
    info.ladderDepth = kLadderDepth;
    info.deepDepth = kDeepDepth;

    // References: exact, or same-depth and deep bakes.
    Reference sameDepth, deep;
    if (scene.analytic) {
      v1::BakeSettings s = BaseSettings();
      PB_ASSIGN_OR_RETURN(const BakeJob job, BuildSceneJob(scene, s));
      PB_ASSIGN_OR_RETURN(sameDepth, AnalyticReference(job, kReferenceOrder));
      deep = sameDepth;
      info.referenceText = ReferenceText(sameDepth, ladderMax);
    } else {
      PB_ASSIGN_OR_RETURN(
          sameDepth,
          BakedReference(scene, ReferenceSettings(kLadderDepth, refSamples), opt.cache, 0));
      PB_ASSIGN_OR_RETURN(
          deep, BakedReference(scene, ReferenceSettings(kDeepDepth, refSamples), opt.cache, 0));
      info.referenceText = "same depth (" + std::to_string(kLadderDepth) +
                           "): " + ReferenceText(sameDepth, ladderMax) + ". Deep (" +
                           std::to_string(kDeepDepth) + "): " + ReferenceText(deep, ladderMax);
      info.depthBiasIrradiance = ReferenceDifference(sameDepth, deep, 2);
    }

    PB_ASSIGN_OR_RETURN(BakeJob job, BuildSceneJob(scene, BaseSettings()));
    info.gridProbes = job.grid.ProbeCount();
    for (const TriangleMesh& m : job.scene.meshes) info.triangles += int64_t(m.TriangleCount());

    // `settings` as `config` bakes them (the former default's switches included).
    auto settingsFor = [](const Config& config, const v1::BakeSettings& settings) {
      BakeSettings s = ResolveSettings(settings);
      s.distantLightTracing = !config.formerDefault;
      s.environmentGuide = !config.formerDefault;
      s.lightVisibilityFloor = config.formerDefault ? 0.125 : 0.0;
      s.shadowRoulette = !config.formerDefault;
      return s;
    };
    auto record = [&](const Config& config, const BakeJob& baked, const Timed& t,
                      const Reference& reference, const std::string& refName) {
      BakeRow row = MakeRow(scene, config, baked, t, reference, refName);
      log->info(
          "{} {} spp={}: cpu {:.3f} s, irradiance error {:.4g}, honesty {:.2f} (L0 {:.2f}, RGB "
          "{:.2f})",
          scene.name, config.id, baked.settings.samplesPerProbe, t.cpu, row.error.meanIrradianceRel,
          row.error.honesty, row.error.honestyL0, row.error.honestyIrradiance);
      info.bakedProbes = row.probes;
      results.rows.push_back(std::move(row));
    };
    auto bake = [&](const Config& config, const v1::BakeSettings& settings,
                    const Reference& reference, const std::string& refName) -> absl::Status {
      job.settings = settingsFor(config, settings);
      PB_ASSIGN_OR_RETURN(const Timed t, TimedBake(job, 1, repeats));
      record(config, job, t, reference, refName);
      return absl::OkStatus();
    };
    const std::string sameName = scene.analytic ? "exact" : "same depth";
    const std::string deepName = scene.analytic ? "exact" : "deep";
    const std::vector<Config> ladder = LadderConfigs();
    const auto former =
        std::find_if(ladder.begin(), ladder.end(), [](const Config& c) { return c.formerDefault; });
    for (const Config& config : ladder) {
      if (config.formerDefault) continue;  // baked in pairs with the default, below
      std::vector<int64_t> counts = results.ladder;
      if (config.id != "nee_mis_sobol" || former == ladder.end()) {
        for (int64_t spp : counts) {
          v1::BakeSettings s = config.settings;
          s.set_samples_per_probe(spp);
          PB_RETURN_IF_ERROR(bake(config, s, sameDepth, sameName));
        }
        continue;
      }
      // The default and the former default, in turn at each count (TimedPair), on to 8x the
      // ladder, so that their times to 2% and 1% are measured, not extrapolated.
      if (!opt.quick)
        for (int64_t spp = 2 * ladderMax; spp <= 8 * ladderMax; spp *= 2) counts.push_back(spp);
      for (int64_t spp : counts) {
        v1::BakeSettings s = config.settings;
        s.set_samples_per_probe(spp);
        BakeJob now = job, before = job;
        now.settings = settingsFor(config, s);
        before.settings = settingsFor(*former, s);
        PB_ASSIGN_OR_RETURN(const auto t, TimedPair(now, before, repeats));
        record(config, now, t.first, sameDepth, sameName);
        record(*former, before, t.second, sameDepth, sameName);
      }
    }
    for (const Config& config : AdaptiveConfigs(opt.quick, ladderMax))
      PB_RETURN_IF_ERROR(bake(config, config.settings, sameDepth, sameName));
    for (const Config& config : PresetConfigs())
      PB_RETURN_IF_ERROR(bake(config, config.settings, deep, deepName));
    // Depth: the largest ladder count at several depths against the deep reference.
    for (int depth : {2, 3, 4, 6, 8, 16}) {
      Config c{Format("depth_%d", depth), Format("depth %d", depth), "depth", BaseSettings()};
      c.settings.set_max_depth(depth);
      c.settings.set_samples_per_probe(ladderMax);
      PB_RETURN_IF_ERROR(bake(c, c.settings, deep, deepName));
    }
    results.scenes.push_back(info);

    // Throughput against raw Embree: the default configuration's rays, split into intersection
    // and shadow rays by a direction-sampling bake of the same seed and sampler (same paths, no
    // shadow rays).
    if (opt.embree) {
      ThroughputInfo tp;
      tp.scene = scene.name;
      const BakeRow* def = nullptr;
      for (const BakeRow& r : results.rows)
        if (r.scene == scene.name && r.config == "nee_mis_sobol" &&
            r.samplesPerProbe == throughputSpp)
          def = &r;
      PB_CHECK(def != nullptr);
      tp.rays = def->rays;
      tp.samples = def->samples;
      tp.bakeCpuSeconds = def->cpuSeconds;
      tp.tracerCpuMrays = double(def->rays) / def->cpuSeconds * 1e-6;
      tp.tracerWallMrays = double(def->rays) / def->wallSeconds * 1e-6;
      // Setup (BVH build, light tables, placement and validity rays): a bake of one sample.
      v1::BakeSettings one = BaseSettings();
      one.set_samples_per_probe(1);
      job.settings = ResolveSettings(one);
      PB_ASSIGN_OR_RETURN(const Timed setup, TimedBake(job, 1, 3));
      tp.setupCpuSeconds = setup.cpu;
      tp.setupRays = setup.volume.stats.rays;
      v1::BakeSettings s = BaseSettings();
      s.set_samples_per_probe(throughputSpp);
      s.set_estimator(v1::BakeSettings::DIRECTION_SAMPLING);
      job.settings = ResolveSettings(s);
      PB_ASSIGN_OR_RETURN(const Timed dir, TimedBake(job, 1, 1));
      tp.intersectRays = dir.volume.stats.rays;
      tp.shadowRays = tp.rays - tp.intersectRays;
      tp.validityRays = 128 * job.grid.ProbeCount();
      std::vector<Vec3d> probes;
      for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
        if (!dir.volume.active[p]) continue;
        int i, j, k;
        job.grid.Coords(p, &i, &j, &k);
        probes.push_back(job.grid.Position(i, j, k));
      }
      log->info("{}: raw Embree", scene.name);
      PB_ASSIGN_OR_RETURN(
          tp.raw, MeasureRawEmbree(job, probes, opt.quick ? 0.05 : 0.25, opt.quick ? 3 : 5, 2));
      const RawRate* probe = tp.raw.Find("probe random", "rtcIntersect1", 1);
      const RawRate* bounce = tp.raw.Find("bounce", "rtcIntersect1", 1);
      const RawRate* shadow = tp.raw.Find("shadow", "rtcOccluded1", 1);
      const double firstRays = double(tp.samples + tp.validityRays);
      const double bounceRays = double(tp.intersectRays) - firstRays;
      tp.embreeOnlySeconds = firstRays / (probe->cpuMraysPerSecond * 1e6) +
                             std::max(0.0, bounceRays) / (bounce->cpuMraysPerSecond * 1e6) +
                             double(tp.shadowRays) / (shadow->cpuMraysPerSecond * 1e6);
      tp.embreeOnlySamplingSeconds =
          tp.embreeOnlySeconds - double(tp.validityRays) / (probe->cpuMraysPerSecond * 1e6);
      // Paired readings of the fraction (ThroughputInfo::pairedFractions).
      v1::BakeSettings pairSettings = BaseSettings();
      pairSettings.set_samples_per_probe(throughputSpp);
      job.settings = ResolveSettings(pairSettings);
      for (int k = 0; k < (opt.quick ? 1 : kThroughputPairs); ++k) {
        const CpuPin pin;  // both halves on one CPU
        PB_ASSIGN_OR_RETURN(const Timed t, TimedBake(job, 1, 1));
        PB_ASSIGN_OR_RETURN(const RawRate rate,
                            MeasureRawProbeRate(job, probes, opt.quick ? 0.05 : 0.25, 3));
        const double tracerMrays = double(t.volume.stats.rays) / t.cpu * 1e-6;
        log->info(
            "{}: pair {} on CPU {}: bake {:.3f} CPU s, {:.2f} Mrays/CPU-s; raw {:.2f} "
            "Mrays/CPU-s",
            scene.name, k, pin.cpu(), t.cpu, tracerMrays, rate.cpuMraysPerSecond);
        tp.pairedFractions.push_back(tracerMrays / rate.cpuMraysPerSecond);
        tp.pairedCpus.push_back(pin.cpu());
      }
      log->info("{}: replay of the tracer's own rays", scene.name);
      PB_RETURN_IF_ERROR(MeasureReplay(job, int64_t(probes.size()), opt.quick,
                                       opt.quick ? 2 : kReplayPairs, &tp.replay));
      results.throughput.push_back(std::move(tp));
    }
  }

  // Scaling: probes/s at 1 and 2 threads on the demo scene, interleaved repeats.
  for (const BenchScene& scene : scenes) {
    if (scene.name != "demo") continue;
    if (!opt.scenes.empty() &&
        std::find(opt.scenes.begin(), opt.scenes.end(), "demo") == opt.scenes.end())
      break;
    // Long enough (~1 s of CPU) that thread start-up and the serial setup do not dominate.
    const int64_t scalingSpp = opt.quick ? ladderMax : 4096;
    v1::BakeSettings s = BaseSettings();
    s.set_samples_per_probe(scalingSpp);
    PB_ASSIGN_OR_RETURN(const BakeJob job, BuildSceneJob(scene, s));
    ScalingInfo& sc = results.scaling;
    sc.scene = scene.name;
    sc.samplesPerProbe = scalingSpp;
    sc.load = LoadAverage1();
    log->info("scaling: 1 vs 2 threads");
    for (int r = 0; r < (opt.quick ? 2 : 3); ++r) {
      PB_ASSIGN_OR_RETURN(const Timed one, TimedBake(job, 1, 1));
      PB_ASSIGN_OR_RETURN(const Timed two, TimedBake(job, 2, 1));
      if (!SameBits(one.volume, two.volume))
        return absl::InternalError("1-thread and 2-thread bakes differ: determinism is broken");
      sc.probes = one.volume.stats.probes;
      sc.wall1.push_back(one.wall);
      sc.cpu1.push_back(one.cpu);
      sc.wall2.push_back(two.wall);
      sc.cpu2.push_back(two.cpu);
    }
    // Control: raw Embree's own 2/1-thread ratio on the same probes, measured right after.
    std::vector<Vec3d> probes;
    for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
      int i, j, k;
      job.grid.Coords(p, &i, &j, &k);
      probes.push_back(job.grid.Position(i, j, k));
    }
    PB_ASSIGN_OR_RETURN(const RawEmbreeResult raw, MeasureRawEmbree(job, probes, 0.25, 3, 2));
    const RawRate* one = raw.Find("probe random", "rtcIntersect1", 1);
    const RawRate* two = raw.Find("probe random", "rtcIntersect1", 2);
    if (one && two) sc.rawRatio = two->wallMraysPerSecond / one->wallMraysPerSecond;
  }

  // Many lights in the demo room, instead of its ceiling light: N small lights scattered over the
  // ceiling with the ceiling light's total power ("ceiling"), or N mixed point, spot, rect and
  // sphere lights scattered through the room's volume ("volume").
  for (const BenchScene& scene : scenes) {
    if (scene.name != "demo" || opt.scalingOnly) continue;
    v1::BakeSettings s = BaseSettings();
    s.set_samples_per_probe(opt.quick ? 64 : 256);
    PB_ASSIGN_OR_RETURN(const BakeJob demo, BuildSceneJob(scene, s));
    const auto* ceiling =
        demo.scene.lights.empty() ? nullptr : std::get_if<RectLight>(&demo.scene.lights.front());
    if (!ceiling) return absl::InternalError("the demo's first light is not its ceiling rect");
    const double area = Length(Cross(ceiling->edge1, ceiling->edge2));
    // Deterministic uniform numbers for light i of n.
    const auto u = [](int n, int i, int k) { return U32ToUnit(uint32_t(Hash(n, i, k))); };
    const auto ceilingLights = [&](int n, std::vector<Light>* lights) {
      const double side = 0.1;
      for (int i = 0; i < n; ++i) {
        lights->push_back(RectLight{{-3.8 + 7.4 * u(n, i, 0), -2.8 + 5.4 * u(n, i, 1), 2.99},
                                    {0, side, 0},
                                    {side, 0, 0},
                                    ceiling->radiance * (area / (n * side * side)),
                                    false});
      }
    };
    const auto volumeLights = [&](int n, std::vector<Light>* lights) {
      // Each light's intensity (W/sr, along its strongest direction) is 1/n of the total.
      const Vec3d intensity = Vec3d{5, 4.5, 4} * (40.0 / n);
      const double side = 0.15, radius = 0.05;
      for (int i = 0; i < n; ++i) {
        const Vec3d p{-3.8 + 7.6 * u(n, i, 0), -2.8 + 5.6 * u(n, i, 1), 0.3 + 2.6 * u(n, i, 2)};
        switch (i % 4) {
          case 0:
            lights->push_back(PointLight{p, intensity});
            break;
          case 1:
            lights->push_back(SpotLight{p, Normalize(Vec3d{u(n, i, 3) - 0.5, u(n, i, 4) - 0.5, -1}),
                                        intensity, std::cos(25 * std::numbers::pi / 180),
                                        std::cos(40 * std::numbers::pi / 180)});
            break;
          case 2:
            lights->push_back(
                RectLight{p, {0, side, 0}, {side, 0, 0}, intensity / (side * side), false});
            break;
          default:
            lights->push_back(
                SphereLight{p, radius, intensity / (std::numbers::pi * radius * radius)});
            break;
        }
      }
    };
    const std::pair<const char*, std::vector<int>> layouts[] = {{"ceiling", {1, 16, 64, 256, 1024}},
                                                                {"volume", {24, 96, 384}}};
    for (const auto& [layout, counts] : layouts) {
      for (int n : counts) {
        BakeJob job = demo;
        job.scene.lights.erase(job.scene.lights.begin());
        if (std::string(layout) == "ceiling") {
          ceilingLights(n, &job.scene.lights);
        } else {
          volumeLights(n, &job.scene.lights);
        }
        ManyLightsRow row;
        row.layout = layout;
        row.lights = n;
        {
          PB_ASSIGN_OR_RETURN(const auto tracer,
                              TracerScene::Build(job.scene, LocalOrigin(job.scene)));
          row.treeLights = LightSet(job.scene, *tracer).TreeLightCount();
        }
        log->info("many lights, {}: {} lights ({} through a tree)", layout, n, row.treeLights);
        PB_ASSIGN_OR_RETURN(const Timed t, TimedBake(job, 1, 2));
        row.cpu = t.cpu;
        row.probes = t.volume.stats.probes;
        row.samplesPerProbe = job.settings.samplesPerProbe;
        double sum = 0;
        int64_t counted = 0;
        for (size_t p = 0; p < t.volume.stdError.size(); ++p) {
          if (!t.volume.active[p]) continue;
          sum += t.volume.stdError[p];
          ++counted;
        }
        row.meanStdError = counted ? sum / double(counted) : 0;
        results.manyLights.push_back(row);
      }
    }
  }

  if (opt.memory && !opt.scalingOnly) {
    const int n = opt.quick ? 64 : 128;
    log->info("memory: dense {}^3 order-2 bake in a child process", n);
    results.memory = MeasureMemory(opt, n, 8);
  } else {
    results.memory.note = "not measured (--no-memory)";
  }

  results.loadEnd = LoadAverage1();
  results.totalSeconds = WallSeconds() - runStart;
  PB_RETURN_IF_ERROR(WriteReports(results, opt.out));
  log->info("reports written to {} in {:.0f} s", opt.out, results.totalSeconds);
  if (opt.committedResults) {
    PB_RETURN_IF_ERROR(UpdateDocuments(results, opt.source));
    log->info("figures updated in README.md and docs/accuracy-and-speed.md");
  }
  return absl::OkStatus();
}

absl::Status UpdateDocumentsFromJson(const Options& opt) {
  PB_ASSIGN_OR_RETURN(const BenchResults results, ReadResultsJson(opt.out + "/results.json"));
  PB_RETURN_IF_ERROR(UpdateDocuments(results, opt.source));
  Logger("bench")->info(
      "figures of {}/results.json written into README.md and "
      "docs/accuracy-and-speed.md",
      opt.out);
  return absl::OkStatus();
}

int Usage() {
  std::fprintf(stderr,
               "usage: probebake-bench [--quick] [--out DIR] [--cache DIR] [--work DIR] "
               "[--source DIR] [--repeats N] [--scenes a,b] [--no-memory] [--no-embree] "
               "[--scaling-only] [--replay-only] [--docs-only]\n");
  return 2;
}

}  // namespace
}  // namespace probebake::bench

int main(int argc, char** argv) {
  using namespace probebake::bench;
  if (argc == 7 && std::strcmp(argv[1], "--memory-child") == 0) {
    probebake::SetLogLevel(spdlog::level::warn);
    return MemoryChild(argv[2], std::atoi(argv[3]), std::atoll(argv[4]), argv[5], argv[6]);
  }
  Options opt;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--quick") {
      opt.quick = true;
    } else if (a == "--out") {
      opt.out = next();
    } else if (a == "--cache") {
      opt.cache = next();
    } else if (a == "--work") {
      opt.work = next();
    } else if (a == "--source") {
      opt.source = next();
    } else if (a == "--repeats") {
      opt.repeats = std::atoi(next().c_str());
    } else if (a == "--scenes") {
      std::stringstream list(next());
      std::string name;
      while (std::getline(list, name, ',')) opt.scenes.push_back(name);
    } else if (a == "--no-memory") {
      opt.memory = false;
    } else if (a == "--no-embree") {
      opt.embree = false;
    } else if (a == "--scaling-only") {
      opt.scalingOnly = true;
    } else if (a == "--replay-only") {
      opt.replayOnly = true;
    } else if (a == "--docs-only") {
      opt.docsOnly = true;
    } else {
      return Usage();
    }
  }
  if (opt.work.empty()) opt.work = std::string(PROBEBAKE_BINARY_DIR) + "/bench-work";
  // Quick runs are smoke checks: their reports stay in the work folder, not in the committed
  // results.
  if (opt.out.empty() && opt.scalingOnly) opt.out = opt.work + "/scaling-results";
  if (opt.out.empty() && opt.replayOnly) opt.out = opt.work + "/replay-results";
  if (opt.out.empty()) {
    opt.committedResults = !opt.quick && !opt.scalingOnly;
    opt.out = opt.quick ? opt.work + "/quick-results" : opt.source + "/tests/bench/results";
  }
  if (opt.cache.empty()) opt.cache = DefaultCacheDir();
  std::filesystem::create_directories(opt.work);
  std::filesystem::create_directories(opt.cache);
  probebake::SetLogLevel(spdlog::level::info);
  // The baker logs every bake at info; the benchmark's own lines are what matter here.
  probebake::Logger("bake")->set_level(spdlog::level::warn);
  probebake::Logger("job")->set_level(spdlog::level::warn);
  const absl::Status status = opt.docsOnly     ? UpdateDocumentsFromJson(opt)
                              : opt.replayOnly ? RunReplayOnly(opt)
                                               : Run(opt);
  if (!status.ok()) {
    std::fprintf(stderr, "probebake-bench: %s\n", std::string(status.message()).c_str());
    return 1;
  }
  return 0;
}
