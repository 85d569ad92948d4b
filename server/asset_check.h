// The server's asset check (runtime/asset_check.h): before the server builds a job, a child
// (`probebake-server <the server's own flags> --check-job-assets SPEC_FILE --check-imports-out
// FILE`) opens the blob store, builds the job exactly as the server would (same limits, same
// code), hands its mesh imports back and reports; the server builds the job from those imports.
// A file that crashes or hangs the importer costs the child, and the server never imports one.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "probebake/job/limits.h"
#include "probebake/v1/job.pb.h"
#include "runtime/asset_check.h"

namespace probebake::server {

class AssetCheck {
 public:
  // `argv`: the child's command line without the --check-job-assets argument (the server's own
  // executable and flags). `tmpDir`: where the spec file for the child is written.
  AssetCheck(std::vector<std::string> argv, std::filesystem::path tmpDir,
             std::chrono::seconds timeout);

  // The child's mesh imports of `spec` (none, without a child, when `spec` has no mesh or map
  // blob); the child's error otherwise, or INVALID_ARGUMENT "<field>: ..." when importing crashed
  // or ran past a limit. INTERNAL when the child could not be run at all. Every call runs a child
  // (a job is built when it is created and again when it starts, each time from a child's
  // imports: holding them in between would hold every queued job's decoded textures).
  // Thread-safe.
  absl::StatusOr<MeshImports> Import(const v1::JobSpec& spec) const;

 private:
  std::vector<std::string> argv_;
  std::filesystem::path tmpDir_;
  std::chrono::seconds timeout_;
};

// The server's child: applies `resources`, reads the JobSpec (binary protobuf) at `specFile`,
// builds it over the blob store under `dataDir` with `limits`, writes its mesh imports to
// `importsFile` and the report (runtime/asset_check.h) to stdout. Returns the process exit code
// (0 when a report was written, whatever its status).
int RunAssetCheckChild(const std::filesystem::path& specFile,
                       const std::filesystem::path& importsFile,
                       const std::filesystem::path& dataDir, int64_t maxBlobBytes,
                       const JobLimits& limits, const runtime::AssetCheckLimits& resources);

}  // namespace probebake::server
