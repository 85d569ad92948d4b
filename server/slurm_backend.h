// probebake-server --backend slurm (docs/cluster.md): a job's grid split into shards
// (runtime/shard_plan.h), baked as one Slurm array by the `probebake` CLI on the cluster's nodes,
// followed, retried, merged and stored like a local bake. Every RPC is unchanged: the job manager
// runs the job as always and this backend's `bake` stands for probebake::Bake.
//
// The shared folder (SHARED, POSIX, at the same path on the server and on every node) holds one
// folder per job, SHARED/<job id>: job.json (the spec, assets by blob), blobs/<sha256> (the
// assets), shard.sh (the array's batch script), parts/part-<i>.vdb (shard i's volume, written
// atomically), progress/shard-<i>.json (runtime/shard_progress.h) and logs/shard-<i>.log (Slurm's
// output, every attempt appended).
//
// A run, stage by stage:
//   - the first time: plan (the work pre-pass on the server), fill SHARED/<job id>, store the run
//     (cluster_run.proto) in the job store, then sbatch --array=0-(N-1);
//   - follow: every poll interval, squeue for the tasks' states and the progress files for the
//     job's progress. A shard is done when its part exists; a task that ended without its part
//     (FAILED, TIMEOUT, NODE_FAIL, killed..., or COMPLETED or forgotten by slurmctld with no part
//     after a grace period for the shared folder's caches) failed, and is submitted again (one
//     sbatch --array=<the failed shards>) until it has run 1 + retries times; then the job
//     FAILED, naming the shard, its state and the end of its log, and its other tasks are
//     cancelled;
//   - merge: every part read and checked against the plan (its sub-grid, the job's scene and
//     settings), merged (MergeProbeVolumes) and returned; the job manager writes and stores it.
// A client's CancelBakeJob scancels every array of the run and returns once squeue shows none of
// them. At the server's shutdown the arrays keep running.
//
// Exactly once: every sbatch is stored before it is made (its unique --job-name) and its array id
// right after, each in one job store commit. A restarted server runs the job again (the job
// manager requeues RUNNING jobs); the run found in the store re-attaches to its arrays, adopting
// an array submitted just before the crash by its name, and submits only shards that have neither
// a part nor a live task. A part present is never baked again, and the result is merged and stored
// once the job manager stores the job's end; the run and its folder are removed after that
// (BakeBackend::release), or at the next start when the server died in between.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/bake_backend.h"

namespace probebake::server {

struct SlurmConfig {
  std::filesystem::path sharedDir;  // SHARED: absolute, the same path on every node
  std::string partition;            // empty: the cluster's default partition
  // Shards per job: `shards` when > 0, else one per `probesPerShard` expected probes (at least
  // one; never more than the grid's points).
  int shards = 0;
  int64_t probesPerShard = 0;
  int retries = 2;                      // submissions of a failed shard after its first
  std::filesystem::path probebake;      // the CLI on the nodes
  int cpusPerTask = 0;                  // sbatch --cpus-per-task (0: Slurm's default)
  std::vector<std::string> sbatchArgs;  // more sbatch arguments, e.g. --time=4:00:00
  std::filesystem::path binDir;         // where sbatch, squeue and scancel are (empty: $PATH)
  double pollSeconds = 2;
  // How long a task that ended (or that slurmctld forgot) may lack its part before it counts as
  // failed: the server may see a file written on a node late through the shared folder's caches.
  double missingPartGraceSeconds = 30;
};

// INVALID_ARGUMENT naming the flag for a config that cannot work (a relative or missing shared
// folder, no shard count nor probes per shard, a CLI that is not executable); NOT_FOUND without
// Slurm's commands. Removes the runs (and folders) of jobs that ended or were deleted while the
// server was down.
absl::StatusOr<BakeBackend> SlurmBackend(const BackendContext& context, const SlurmConfig& config);

}  // namespace probebake::server
