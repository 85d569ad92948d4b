#include "fake_backend.h"

#include <thread>

#include "probebake/job/job.h"
#include "server/checkpoint.h"

namespace probebake::testing {

float FakeProbeValue(uint64_t seed, int64_t probe, int coefficient, int channel) {
  // splitmix64 of the inputs, mapped to [0, 1).
  uint64_t x = seed * 0x9E3779B97F4A7C15ull + uint64_t(probe) * 0xBF58476D1CE4E5B9ull +
               uint64_t(coefficient) * 0x94D049BB133111EBull + uint64_t(channel);
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBull;
  x ^= x >> 31;
  return float(x >> 40) / float(1 << 24);
}

namespace {

absl::StatusOr<ProbeVolume> FakeBake(const BakeJob& job, const BakeOptions& options,
                                     std::chrono::microseconds probeDelay, FakeBakeStats* stats) {
  {
    std::lock_guard lock(stats->mutex);
    int now = ++stats->active[job.jobDigest];
    stats->maxActivePerJob = std::max(stats->maxActivePerJob, now);
  }
  stats->bakes++;
  struct Leave {
    FakeBakeStats* stats;
    std::string digest;
    ~Leave() {
      std::lock_guard lock(stats->mutex);
      --stats->active[digest];
    }
  } leave{stats, job.jobDigest};

  auto start = std::chrono::steady_clock::now();
  const int64_t probes = job.grid.ProbeCount();
  ProbeVolume v;
  v.grid = job.grid;
  v.shOrder = job.settings.shOrder;
  v.active.assign(size_t(probes), 0);
  v.radiance.assign(size_t(v.CoeffCount()), std::vector<float>(size_t(3 * probes), 0.f));
  v.validity.assign(size_t(probes), 0.f);
  v.stdError.assign(size_t(probes), 0.f);
  v.stdErrorL0.assign(size_t(probes), 0.f);
  v.sampleCount.assign(size_t(probes), 0.f);
  std::vector<uint8_t> done(size_t(probes), 0);
  if (options.resumeFrom && options.resumeDone) {
    v = *options.resumeFrom;
    done = *options.resumeDone;
    stats->resumed++;
  }
  auto elapsed = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  auto lastProgress = start, lastCheckpoint = start;
  // Like Bake, the counters cover this call only (probes resumed from a checkpoint are not
  // counted again): the server must carry earlier attempts' counts itself.
  int64_t bakedNow = 0;
  auto report = [&](int64_t doneCount) {
    if (!options.progress) return;
    BakeProgress p;
    p.probesDone = doneCount;
    p.probesTotal = probes;
    p.samples = bakedNow * job.settings.samplesPerProbe;
    p.rays = 2 * p.samples;
    p.elapsedSeconds = elapsed();
    p.etaSeconds = double(probes - doneCount) * std::chrono::duration<double>(probeDelay).count();
    p.errorEstimate = 0.01;
    p.probesErrorUnknown = doneCount / 8;  // one probe in 8 "black so far"
    options.progress(p);
  };
  int64_t doneCount = 0;
  for (uint8_t d : done) doneCount += d;
  for (int64_t probe = 0; probe < probes; ++probe) {
    if (done[size_t(probe)]) continue;
    if (options.cancel && options.cancel->load()) {
      // Bake's contract: a last progress report, then a last checkpoint.
      report(doneCount);
      if (options.checkpoint) options.checkpoint(v, done);
      return absl::CancelledError("bake cancelled");
    }
    std::this_thread::sleep_for(probeDelay);
    for (int c = 0; c < v.CoeffCount(); ++c)
      for (int ch = 0; ch < 3; ++ch)
        v.radiance[size_t(c)][size_t(3 * probe + ch)] =
            FakeProbeValue(job.settings.seed, probe, c, ch);
    v.active[size_t(probe)] = 1;
    v.validity[size_t(probe)] = 1.f;
    v.stdError[size_t(probe)] = 0.01f;
    v.stdErrorL0[size_t(probe)] = 0.005f;
    v.sampleCount[size_t(probe)] = float(job.settings.samplesPerProbe);
    done[size_t(probe)] = 1;
    ++doneCount;
    ++bakedNow;
    stats->probesBaked++;
    auto now = std::chrono::steady_clock::now();
    // As Bake's reporter: checkpoints are taken on progress ticks, right after the report.
    if (now - lastProgress >= std::chrono::duration<double>(options.progressIntervalSeconds)) {
      report(doneCount);
      lastProgress = now;
      if (options.checkpoint && now - lastCheckpoint >= std::chrono::duration<double>(
                                                            options.checkpointIntervalSeconds)) {
        options.checkpoint(v, done);
        lastCheckpoint = now;
      }
    }
  }
  report(doneCount);
  v.stats.wallSeconds = 0;  // fixed: uninterrupted bakes of a job give the same bytes
  v.stats.threads = 1;
  v.stats.probes = probes;
  v.stats.samples = bakedNow * job.settings.samplesPerProbe;  // this call's, as Bake counts
  v.stats.rays = 2 * v.stats.samples;
  return v;
}

}  // namespace

server::BakeBackend FakeBackend(const server::BlobStore* blobs, const JobLimits& limits,
                                std::chrono::microseconds probeDelay, FakeBakeStats* stats) {
  server::BakeBackend backend;
  backend.build = [blobs, limits](const v1::JobSpec& spec) {
    server::BlobAssetSource assets(blobs, limits.maxAssetBytes);
    return BuildBakeJob(spec, assets, limits);
  };
  backend.bake = [probeDelay, stats](const server::BakeRun&, const BakeJob& job,
                                     const BakeOptions& options) {
    return FakeBake(job, options, probeDelay, stats);
  };
  backend.writeVolume = [](const std::string& path, const ProbeVolume& volume,
                           const VolumeMetadata& /*meta*/) {
    std::vector<uint8_t> done(volume.active.begin(), volume.active.end());
    return server::WriteCheckpoint(path, kFakeVolumeTag, volume, done);
  };
  return backend;
}

}  // namespace probebake::testing
