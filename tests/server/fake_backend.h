// A deterministic stand-in for the path tracer, for service tests: each probe's values are a hash
// of (seed, probe index), baking a probe takes `probeDelay` and traces samplesPerProbe samples
// and twice as many rays, and the BakeOptions hooks (progress, cancel, checkpoint, resume) behave
// as Bake's: counters cover the current call only, a progress report precedes every checkpoint,
// and a cancelled bake reports and checkpoints once more. Resumed and uninterrupted bakes give the
// same values, so restart tests compare them. The volume is written in the checkpoint format (no
// OpenVDB needed); its stats.wallSeconds is 0, plus what the server adds for earlier attempts.
#pragma once

#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <string>

#include "server/bake_backend.h"

namespace probebake::testing {

struct FakeBakeStats {
  std::mutex mutex;
  std::map<std::string, int> active;  // job digest -> bakes running now
  int maxActivePerJob = 0;            // the most bakes of one job seen at once
  std::atomic<int> bakes{0};          // Bake calls
  std::atomic<int> resumed{0};        // Bake calls that resumed from a checkpoint
  std::atomic<int64_t> probesBaked{0};
};

// The tag the fake writer stores volumes under (they are written in the checkpoint format).
inline constexpr const char* kFakeVolumeTag = "fake-volume";

// `build`: probebake::BuildBakeJob over the blob store (the real one).
server::BakeBackend FakeBackend(const server::BlobStore* blobs, const JobLimits& limits,
                                std::chrono::microseconds probeDelay, FakeBakeStats* stats);

// The value the fake baker stores for (seed, probe, coefficient, channel).
float FakeProbeValue(uint64_t seed, int64_t probe, int coefficient, int channel);

}  // namespace probebake::testing
