#include "server/asset_check.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <random>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/job/digest.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"
#include "server/bake_backend.h"
#include "server/blob_store.h"
#include "server/file_util.h"

extern char** environ;

namespace probebake::server {
namespace {

bool HasAssetBlobs(const v1::JobSpec& spec) {
  for (const v1::Mesh& mesh : spec.scene().meshes())
    if (mesh.has_blob()) return true;
  return spec.scene().environment().has_map() && spec.scene().environment().map().has_blob();
}

// Announces each asset on stdout before it is read, so that the parent can name the file a crash
// happened in.
class AnnouncingAssetSource final : public AssetSource {
 public:
  explicit AnnouncingAssetSource(const AssetSource& inner) : inner_(inner) {}
  absl::StatusOr<std::string> ReadFile(const std::string& relativePath,
                                       const std::string& fieldPath) const override {
    std::printf("asset %s\n", fieldPath.c_str());
    std::fflush(stdout);
    return inner_.ReadFile(relativePath, fieldPath);
  }
  absl::StatusOr<std::string> ReadBlob(const v1::Digest& digest,
                                       const std::string& fieldPath) const override {
    std::printf("asset %s\n", fieldPath.c_str());
    std::fflush(stdout);
    return inner_.ReadBlob(digest, fieldPath);
  }

 private:
  const AssetSource& inner_;
};

// The child's report: the assets it started and its final status, if it got that far.
struct Report {
  std::string lastAsset;
  bool finished = false;
  absl::Status status;
};

Report ParseReport(const std::string& out) {
  Report report;
  size_t at = 0;
  while (at < out.size()) {
    const size_t end = out.find('\n', at);
    const std::string line =
        out.substr(at, end == std::string::npos ? std::string::npos : end - at);
    if (line.rfind("asset ", 0) == 0) {
      report.lastAsset = line.substr(6);
    } else if (line.rfind("status ", 0) == 0 && end != std::string::npos) {
      int code = 0;
      if (absl::SimpleAtoi(line.substr(7), &code)) {
        report.finished = true;
        report.status = absl::Status(static_cast<absl::StatusCode>(code), out.substr(end + 1));
      }
      break;
    }
    if (end == std::string::npos) break;
    at = end + 1;
  }
  return report;
}

}  // namespace

AssetCheck::AssetCheck(std::vector<std::string> argv, std::filesystem::path tmpDir,
                       std::chrono::seconds timeout)
    : argv_(std::move(argv)), tmpDir_(std::move(tmpDir)), timeout_(timeout) {}

absl::Status AssetCheck::Check(const v1::JobSpec& spec) const {
  if (!HasAssetBlobs(spec)) return absl::OkStatus();
  const std::string specBytes = spec.SerializeAsString();
  const std::string key = Sha256Hex(specBytes);
  {
    std::lock_guard lock(mutex_);
    if (passed_.count(key)) return absl::OkStatus();
  }
  absl::Status status = CheckInChild(specBytes);
  if (status.ok()) {
    std::lock_guard lock(mutex_);
    passed_.insert(key);
  }
  return status;
}

absl::Status AssetCheck::CheckInChild(const std::string& specBytes) const {
  // A name no other check uses at the same time.
  const std::filesystem::path specFile =
      tmpDir_ / absl::StrCat("asset-check-", getpid(), "-", std::random_device{}(), ".pb");
  PB_RETURN_IF_ERROR(WriteFileAtomic(specFile, specBytes));
  struct RemoveFile {
    std::filesystem::path path;
    ~RemoveFile() {
      std::error_code ignored;
      std::filesystem::remove(path, ignored);
    }
  } removeSpec{specFile};
  std::vector<std::string> args = argv_;
  args.push_back("--check-job-assets");
  args.push_back(specFile.string());
  return RunAssetCheck(std::move(args), timeout_);
}

absl::Status RunAssetCheck(std::vector<std::string> args, std::chrono::seconds timeout) {
  const auto log = Logger("assets");
  int out[2];
  if (pipe2(out, O_CLOEXEC) != 0)
    return absl::InternalError(absl::StrCat("asset check: pipe: ", std::strerror(errno)));
  std::vector<char*> argvPointers;
  for (std::string& a : args) argvPointers.push_back(a.data());
  argvPointers.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  // The server blocks SIGTERM and SIGINT in every thread for its sigwait; the child must not.
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attributes, &none);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK);
  pid_t pid = 0;
  const int spawned =
      posix_spawn(&pid, args[0].c_str(), &actions, &attributes, argvPointers.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  close(out[1]);
  if (spawned != 0) {
    close(out[0]);
    return absl::InternalError(
        absl::StrCat("asset check: cannot run ", args[0], ": ", std::strerror(spawned)));
  }

  // Read the report until the child closes stdout or the time runs out.
  std::string report;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  bool timedOut = false;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timedOut = true;
      break;
    }
    pollfd p{out[0], POLLIN, 0};
    const int ready = poll(&p, 1, int(std::min<int64_t>(left.count(), 1000)));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) continue;
    char buffer[4096];
    const ssize_t n = read(out[0], buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    report.append(buffer, size_t(n));
  }
  close(out[0]);
  if (timedOut) kill(pid, SIGKILL);
  int waitStatus = 0;
  while (waitpid(pid, &waitStatus, 0) < 0 && errno == EINTR) {
  }

  const Report parsed = ParseReport(report);
  const std::string field = parsed.lastAsset.empty() ? "scene" : parsed.lastAsset;
  if (timedOut) {
    log->warn("asset check of {} ran past {} s: killed", field, timeout.count());
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": importing this file took longer than the limit of ", timeout.count(),
                     " s (the file is malformed or too large)"));
  }
  if (WIFSIGNALED(waitStatus)) {
    log->warn("asset check of {} crashed (signal {})", field, WTERMSIG(waitStatus));
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": the importer crashed on this file (signal ", WTERMSIG(waitStatus),
                     "); the file is malformed"));
  }
  if (!parsed.finished) {
    return absl::InternalError(absl::StrCat("asset check: the checker exited with code ",
                                            WIFEXITED(waitStatus) ? WEXITSTATUS(waitStatus) : -1,
                                            " without a report"));
  }
  return parsed.status;
}

int ReportAssetCheck(const absl::Status& status) {
  std::printf("status %d\n%s", int(status.code()), std::string(status.message()).c_str());
  std::fflush(stdout);
  return 0;
}

int RunLocalAssetCheckChild(const std::string& jobPath, const JobLimits& limits) {
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(jobPath);
  if (!spec.ok()) return ReportAssetCheck(spec.status());
  const LocalAssetSource files(JobFileDir(jobPath), "", limits.maxAssetBytes);
  const AnnouncingAssetSource assets(files);
  return ReportAssetCheck(BuildBakeJob(*spec, assets, limits).status());
}

int RunAssetCheckChild(const std::filesystem::path& specFile, const std::filesystem::path& dataDir,
                       int64_t maxBlobBytes, const JobLimits& limits) {
  absl::StatusOr<std::string> bytes = ReadWholeFile(specFile);
  if (!bytes.ok()) return ReportAssetCheck(absl::InternalError(bytes.status().message()));
  v1::JobSpec spec;
  if (!spec.ParseFromString(*bytes))
    return ReportAssetCheck(absl::InternalError("asset check: unreadable spec file"));
  // The parent server's store, in use: read it, never clean it (its DATA/tmp holds other
  // checks' spec files and running jobs' volumes).
  absl::StatusOr<std::unique_ptr<BlobStore>> blobs =
      BlobStore::OpenForReading(dataDir, maxBlobBytes);
  if (!blobs.ok()) return ReportAssetCheck(blobs.status());
  const BlobAssetSource store(blobs->get(), limits.maxAssetBytes);
  const AnnouncingAssetSource assets(store);
  return ReportAssetCheck(BuildBakeJob(spec, assets, limits).status());
}

}  // namespace probebake::server
