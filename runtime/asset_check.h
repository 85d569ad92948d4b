// A job's assets imported first in a child process, so that a file that crashes or hangs an
// importer (assimp has both kinds of bug) costs a child, not the server (a server never dies on a
// client's input: docs/service.md) or the local CLI.
//
// The child builds the job exactly as its parent would (same limits, same code), reports on
// stdout:
//   one line "asset <fieldPath>" as it starts reading each asset, then "status <code>" and the
//   status message to the end,
// and, when the job built, writes its mesh imports (probebake/job/mesh_imports.h) to the file its
// parent named before it reports. The parent builds the job from those imports: the child is the
// only process that runs an importer on a mesh file. (Environment maps are decoded again by the
// parent, behind the header walks of docs/hardening.md.)
// The parent turns a child killed by a signal, past the time limit or out of its memory limit into
// INVALID_ARGUMENT naming the asset the child was reading; a clean report is returned as the
// child's status.
//
// The child runs under resource limits (AssetCheckLimits), so that a file that makes the importer
// allocate without end (one of assimp's known failures) is refused instead of exhausting the
// machine: RLIMIT_DATA for memory (heap and anonymous mappings: what an importer allocates, and
// not the shared libraries an address-space limit would also count), RLIMIT_CPU for CPU time.
// An allocation past the limit makes the child report "memory <limit>" and exit. A build with
// AddressSanitizer does not apply the memory limit: its shadow memory counts against RLIMIT_DATA.
//
// Children: a local bake runs `probebake check-assets JOB.json --imports-out FILE`
// (RunLocalAssetCheckChild, which reads the job's files); the server runs itself over its blob
// store (server/asset_check.h).
#pragma once

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/limits.h"
#include "probebake/job/mesh_imports.h"
#include "probebake/v1/job.pb.h"

namespace probebake::runtime {

// Resource limits of an asset-check child; 0 means none.
struct AssetCheckLimits {
  // Data segment and anonymous memory, bytes (RLIMIT_DATA).
  int64_t memoryBytes = int64_t(8) << 30;
  // CPU seconds (RLIMIT_CPU; the child gets SIGXCPU past them, SIGKILL a second later).
  int64_t cpuSeconds = 0;
};

// The child's side: applies `limits` to this process and arranges for an allocation past the
// memory limit to be reported (see above). Call first thing in the child.
void ApplyAssetCheckLimits(const AssetCheckLimits& limits);

// The parent's side: runs the check command `argv` (a child writing the report above, and its
// mesh imports to `importsFile`, which `argv` names) and interprets its outcome as described
// above; on success returns the imports, and removes `importsFile` whatever the outcome. INTERNAL
// when the child could not be run, ended without a report, or reported success without readable
// imports.
absl::StatusOr<MeshImports> RunAssetCheck(std::vector<std::string> argv,
                                          std::chrono::seconds timeout,
                                          const std::filesystem::path& importsFile);

// The child's side: builds `spec` over `assets` with `limits`, announcing each asset as it is
// read, writes the mesh imports to `importsFile` when it built, and writes the report to stdout
// (a failure to write the imports is its status). Returns the exit code: 0 (a report was written,
// whatever its status).
int ReportJobAssets(const v1::JobSpec& spec, const AssetSource& assets, const JobLimits& limits,
                    const std::filesystem::path& importsFile);

// The report of a child that failed before building (`status` not OK: its input unreadable).
// Returns the exit code, 0.
int ReportAssetCheck(const absl::Status& status);

// The local CLI's child: applies `resources`, reads the job file at `jobPath` and reports its
// assets as a local bake reads them (the job's files and, with `blobDir`, the blobs there: a
// shard worker's), its imports to `importsFile`. Returns the exit code (0 when a report was
// written).
int RunLocalAssetCheckChild(const std::string& jobPath, const std::string& blobDir,
                            const std::filesystem::path& importsFile, const JobLimits& limits,
                            const AssetCheckLimits& resources = {});

}  // namespace probebake::runtime
