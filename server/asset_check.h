// A job's assets imported first in a child process, so that a file that crashes or hangs an
// importer (assimp has both kinds of bug) costs a child, not the server (SPEC 6: a server never
// dies on a client's input) or the local CLI.
//
// The server runs the check before it builds a job in process: the child
// (`probebake-server <the server's own flags> --check-job-assets SPEC_FILE`) opens the blob store,
// builds the job exactly as the server would (same limits, same code) and reports on stdout:
//   one line "asset <fieldPath>" as it starts reading each asset, then "status <code>" and the
//   status message to the end.
// A local bake does the same with `probebake check-assets JOB.json`, which reads the job's files.
// The parent turns a child killed by a signal or past the time limit into INVALID_ARGUMENT naming
// the asset the child was reading; a clean report is returned as the child's status. Importing is
// deterministic, so a job the child built the parent builds the same way.
#pragma once

#include <chrono>
#include <filesystem>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "probebake/job/limits.h"
#include "probebake/v1/job.pb.h"

namespace probebake::server {

class AssetCheck {
 public:
  // `argv`: the child's command line without the --check-job-assets argument (the server's own
  // executable and flags). `tmpDir`: where the spec file for the child is written.
  AssetCheck(std::vector<std::string> argv, std::filesystem::path tmpDir,
             std::chrono::seconds timeout);

  // OK when `spec` has no mesh or map blob, or the child built it; the child's error otherwise,
  // or INVALID_ARGUMENT "<field>: ..." when importing crashed or ran past the time limit.
  // INTERNAL when the child could not be run at all. A spec that passed once passes again without
  // a child (a job is built when it is created and again when it starts). Thread-safe.
  absl::Status Check(const v1::JobSpec& spec) const;

 private:
  absl::Status CheckInChild(const std::string& specBytes) const;

  std::vector<std::string> argv_;
  std::filesystem::path tmpDir_;
  std::chrono::seconds timeout_;
  mutable std::mutex mutex_;
  mutable std::set<std::string> passed_;  // SHA-256 of the specs that passed
};

// Runs the check command `argv` (the child prints the report above) and interprets its outcome
// as AssetCheck::Check describes; what the local CLI uses, with its own child.
absl::Status RunAssetCheck(std::vector<std::string> argv, std::chrono::seconds timeout);

// The local CLI's child: builds the job file at `jobPath` with its files (as a local bake reads
// them) and writes the report to stdout. Returns the exit code (0 when a report was written).
int RunLocalAssetCheckChild(const std::string& jobPath, const JobLimits& limits);

// The server's child: reads the JobSpec (binary protobuf) at `specFile`, builds it over the blob
// store under `dataDir` with `limits`, and writes the report above to stdout. Returns the process
// exit code (0 when a report was written, whatever its status).
int RunAssetCheckChild(const std::filesystem::path& specFile, const std::filesystem::path& dataDir,
                       int64_t maxBlobBytes, const JobLimits& limits);

}  // namespace probebake::server
