// Probe-level checkpoints of a running bake (DATA/checkpoints/<job id>.ckpt): the partial volume
// and the per-probe done flags that BakeOptions.checkpoint hands over, so a job requeued after a
// restart resumes (BakeOptions.resumeFrom / resumeDone) instead of starting over. Resuming gives
// the same bits as an uninterrupted bake because finished probes are stored exactly (floats as
// their bytes) and the baker derives every probe's samples from (seed, probe, sample) alone.
//
// File format (little-endian, this machine's float layout): "PBCKPT02", the job digest, the
// volume (grid, order, active flags, every plane (radiance, irradiance, radiance standard
// errors), window, stats), the done flags, then the SHA-256 of everything before it. Written
// atomically (temporary file, fsync, rename, fsync of the folder); a file that is short, corrupt or
// for another job digest is rejected on load.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/bake/probe_volume.h"

namespace probebake::server {

struct Checkpoint {
  std::string jobDigest;
  ProbeVolume volume;
  std::vector<uint8_t> done;  // per probe (ProbeGrid linear index): 1 when finished

  int64_t DoneCount() const;
};

absl::Status WriteCheckpoint(const std::filesystem::path& path, const std::string& jobDigest,
                             const ProbeVolume& volume, const std::vector<uint8_t>& done);

// NOT_FOUND when there is no file; DATA_LOSS when it is unreadable or its digest differs from
// `expectedJobDigest`.
absl::StatusOr<Checkpoint> ReadCheckpoint(const std::filesystem::path& path,
                                          const std::string& expectedJobDigest);

}  // namespace probebake::server
