// Probe-level checkpoints of a running bake (DATA/checkpoints/<job id>.ckpt): the partial volume
// and the per-probe done flags that BakeOptions.checkpoint hands over, so a job requeued after a
// restart resumes (BakeOptions.resumeFrom / resumeDone) instead of starting over. Resuming gives
// the same bits as an uninterrupted bake because finished probes are stored exactly (floats as
// their bytes) and the baker derives every probe's samples from (seed, probe, sample) alone.
//
// File format (little-endian, this machine's float layout): "PBCKPT05", the job digest, the
// volume (grid, order, active flags, every plane (radiance, irradiance, radiance standard
// errors), window, stats), the done flags, the work of the attempts so far (BakeWork), the
// volume's L0 standard errors, its relocation offsets, filled flags, automatic-window parameters,
// visibility planes and sky transfer (order and planes; each empty when the bake has none), then
// the SHA-256 of everything before it. Written atomically
// (temporary file, fsync, rename, fsync of the folder); a file that is short, corrupt or for
// another job digest is rejected on load. "PBCKPT04" files (no offsets, filled flags, window
// parameters or visibility: read with those planes empty), "PBCKPT03" files (no L0 standard errors:
// their std_error was the L0 figure, copied there) and "PBCKPT02" files (no BakeWork either: zero
// work) are still read.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/bake/probe_volume.h"

namespace probebake::server {

// Work of a job's attempts: Bake's counters restart with every attempt, so the server carries
// these over restarts in the checkpoint and adds them to the next attempt's counts.
struct BakeWork {
  double wallSeconds = 0;  // seconds spent baking, >= 0
  int64_t samples = 0;     // sample paths traced
  int64_t rays = 0;        // rays traced, shadow rays included

  BakeWork& operator+=(const BakeWork& other) {
    wallSeconds += other.wallSeconds;
    samples += other.samples;
    rays += other.rays;
    return *this;
  }
};

struct Checkpoint {
  std::string jobDigest;
  ProbeVolume volume;
  std::vector<uint8_t> done;  // per probe (ProbeGrid linear index): 1 when finished
  // The work of every attempt up to this checkpoint (earlier attempts' included): what a resumed
  // attempt starts counting from.
  BakeWork work;

  int64_t DoneCount() const;
};

// Where the server keeps the checkpoint of job `jobName` ("bakeJobs/<id>"):
// DATA/checkpoints/<id>.ckpt.
std::filesystem::path CheckpointFilePath(const std::filesystem::path& dataDir,
                                         std::string_view jobName);

absl::Status WriteCheckpoint(const std::filesystem::path& path, const std::string& jobDigest,
                             const ProbeVolume& volume, const std::vector<uint8_t>& done,
                             const BakeWork& work = {});

// NOT_FOUND when there is no file; DATA_LOSS when it is unreadable or its digest differs from
// `expectedJobDigest`.
absl::StatusOr<Checkpoint> ReadCheckpoint(const std::filesystem::path& path,
                                          const std::string& expectedJobDigest);

// The same checks, whatever job digest the file was made for (tests and diagnostics, which read
// what a server left on disk without rebuilding the job).
absl::StatusOr<Checkpoint> ReadCheckpointOfAnyJob(const std::filesystem::path& path);

}  // namespace probebake::server
