// Slurm's command-line clients as the Slurm backend uses them (sbatch, squeue, scancel), run as
// child processes with a time limit. Slurm's accounting (sacct) is not needed: states come from
// squeue while slurmctld keeps finished jobs (MinJobAge), and the backend judges a shard by its
// part file beyond that (slurm_backend.h).
#pragma once

#include <chrono>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"

namespace probebake::server {

// An array task as squeue shows it.
struct SlurmTask {
  std::string state;   // PENDING, RUNNING, COMPLETED, FAILED, CANCELLED, TIMEOUT, NODE_FAIL, ...
  std::string reason;  // why it is pending, or how it ended ("None" when there is nothing to say)
};

// SlurmTask::state values after which the task does nothing more.
bool IsEndedSlurmState(const std::string& state);

struct SbatchRequest {
  std::filesystem::path script;
  std::filesystem::path workDir;        // --chdir
  std::string jobName;                  // --job-name
  std::vector<int> tasks;               // --array
  std::filesystem::path outputPattern;  // --output (%a: the task id), appended to
  std::string partition;                // empty: the cluster's default
  int cpusPerTask = 0;                  // 0: Slurm's default
  std::vector<std::string> extraArgs;
};

class SlurmCommands {
 public:
  // `binDir`: the folder of sbatch, squeue and scancel; empty: found in $PATH. NOT_FOUND when one
  // is missing.
  static absl::StatusOr<SlurmCommands> Find(const std::filesystem::path& binDir);

  // Submits an array; its job id. UNAVAILABLE when slurmctld does not answer or refuses, with
  // sbatch's message.
  absl::StatusOr<std::string> Submit(const SbatchRequest& request) const;
  // Every task, any state, of the jobs named `names`, by (array job id, task id). Tasks of jobs
  // slurmctld has forgotten (older than MinJobAge) are absent.
  absl::StatusOr<std::map<std::pair<std::string, int>, SlurmTask>> Tasks(
      const std::vector<std::string>& names) const;
  // The array job id of the job named `name` in any state, if slurmctld knows one.
  absl::StatusOr<std::optional<std::string>> FindByName(const std::string& name) const;
  // True while a job named in `names` is pending, running or completing (what squeue shows by
  // default).
  absl::StatusOr<bool> AnyActive(const std::vector<std::string>& names) const;
  // scancel of the jobs `ids` (every task of each array).
  absl::Status Cancel(const std::vector<std::string>& ids) const;

 private:
  // Runs `argv` (argv[0] one of the tools' paths): its output (stdout and stderr), or UNAVAILABLE
  // naming the command when it fails or runs past kCommandTimeout.
  absl::StatusOr<std::string> Run(std::vector<std::string> argv) const;

  std::string sbatch_, squeue_, scancel_;
};

}  // namespace probebake::server
