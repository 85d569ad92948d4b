// A job's assets imported first in a child process, so that a file that crashes or hangs an
// importer (assimp has both kinds of bug) costs a child, not the server (a server never dies on a
// client's input: docs/service.md) or the local CLI.
//
// The child builds the job exactly as its parent would (same limits, same code) and reports on
// stdout:
//   one line "asset <fieldPath>" as it starts reading each asset, then "status <code>" and the
//   status message to the end.
// The parent turns a child killed by a signal or past the time limit into INVALID_ARGUMENT naming
// the asset the child was reading; a clean report is returned as the child's status. Importing is
// deterministic, so a job the child built the parent builds the same way.
//
// Children: a local bake runs `probebake check-assets JOB.json` (RunLocalAssetCheckChild, which
// reads the job's files); the server runs itself over its blob store (server/asset_check.h).
#pragma once

#include <chrono>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/limits.h"
#include "probebake/v1/job.pb.h"

namespace probebake::runtime {

// The parent's side: runs the check command `argv` (a child writing the report above) and
// interprets its outcome as described above. INTERNAL when the child could not be run or ended
// without a report.
absl::Status RunAssetCheck(std::vector<std::string> argv, std::chrono::seconds timeout);

// The child's side: builds `spec` over `assets` with `limits`, announcing each asset as it is
// read, and writes the report to stdout. Returns the exit code: 0 (a report was written, whatever
// its status).
int ReportJobAssets(const v1::JobSpec& spec, const AssetSource& assets, const JobLimits& limits);

// The report of a child that failed before building (`status` not OK: its input unreadable).
// Returns the exit code, 0.
int ReportAssetCheck(const absl::Status& status);

// The local CLI's child: reads the job file at `jobPath` and reports its assets as a local bake
// reads them (the job's files). Returns the exit code (0 when a report was written).
int RunLocalAssetCheckChild(const std::string& jobPath, const JobLimits& limits);

}  // namespace probebake::runtime
