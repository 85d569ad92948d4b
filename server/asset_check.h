// The server's asset check (runtime/asset_check.h): before the server builds a job in process, a
// child (`probebake-server <the server's own flags> --check-job-assets SPEC_FILE`) opens the blob
// store, builds the job exactly as the server would (same limits, same code) and reports; a file
// that crashes or hangs the importer then costs the child, not the server.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <set>
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

// The server's child: applies `resources`, reads the JobSpec (binary protobuf) at `specFile`,
// builds it over the blob store under `dataDir` with `limits`, and writes the report
// (runtime/asset_check.h) to stdout. Returns the process exit code (0 when a report was written,
// whatever its status).
int RunAssetCheckChild(const std::filesystem::path& specFile, const std::filesystem::path& dataDir,
                       int64_t maxBlobBytes, const JobLimits& limits,
                       const runtime::AssetCheckLimits& resources);

}  // namespace probebake::server
