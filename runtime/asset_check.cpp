#include "runtime/asset_check.h"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <new>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"
#include "runtime/files.h"
#include "runtime/subprocess.h"

namespace probebake::runtime {
namespace {

// Announces each asset on stdout before it is read, so that the parent can name the file a crash
// happened in.
class AnnouncingAssetSource final : public AssetSource {
 public:
  explicit AnnouncingAssetSource(const AssetSource& inner) : inner_(inner) {}
  absl::StatusOr<std::string> ReadFile(const std::string& relativePath,
                                       const std::string& fieldPath) const override {
    Announce(fieldPath);
    return inner_.ReadFile(relativePath, fieldPath);
  }
  absl::StatusOr<std::string> ReadBlob(const v1::Digest& digest,
                                       const std::string& fieldPath) const override {
    Announce(fieldPath);
    return inner_.ReadBlob(digest, fieldPath);
  }
  absl::StatusOr<std::string> ReadReferencedFile(const std::string& modelFile,
                                                 const std::string& modelPath,
                                                 const std::string& fieldPath) const override {
    Announce(fieldPath);
    return inner_.ReadReferencedFile(modelFile, modelPath, fieldPath);
  }

 private:
  static void Announce(const std::string& fieldPath) {
    std::printf("asset %s\n", fieldPath.c_str());
    std::fflush(stdout);
  }

  const AssetSource& inner_;
};

// The child's report: the assets it started and its final status, if it got that far.
struct Report {
  std::string lastAsset;
  bool finished = false;
  absl::Status status;
  int64_t outOfMemoryAt = 0;  // the memory limit an allocation ran past, bytes
};

// The exit code of a child whose allocation failed under its memory limit.
constexpr int kExitOutOfMemory = 86;

// The report line and exit of a child out of memory, from operator new's handler: no allocation,
// only async-signal-safe calls.
char gOutOfMemoryLine[64] = "memory 0\n";

[[noreturn]] void OnOutOfMemory() {
  const ssize_t ignored = ::write(STDOUT_FILENO, gOutOfMemoryLine, std::strlen(gOutOfMemoryLine));
  (void)ignored;
  ::_exit(kExitOutOfMemory);
}

Report ParseReport(const std::string& out) {
  Report report;
  size_t at = 0;
  while (at < out.size()) {
    const size_t end = out.find('\n', at);
    const std::string line =
        out.substr(at, end == std::string::npos ? std::string::npos : end - at);
    if (line.rfind("asset ", 0) == 0) {
      report.lastAsset = line.substr(6);
    } else if (line.rfind("memory ", 0) == 0) {
      if (!absl::SimpleAtoi(line.substr(7), &report.outOfMemoryAt)) report.outOfMemoryAt = -1;
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

// The child's outcome, as RunAssetCheck describes it.
absl::Status CheckInChild(std::vector<std::string> argv, std::chrono::seconds timeout);

}  // namespace

absl::StatusOr<MeshImports> RunAssetCheck(std::vector<std::string> argv,
                                          std::chrono::seconds timeout,
                                          const std::filesystem::path& importsFile) {
  struct RemoveFile {
    const std::filesystem::path& path;
    ~RemoveFile() {
      std::error_code ignored;
      std::filesystem::remove(path, ignored);
    }
  } removeImports{importsFile};
  PB_RETURN_IF_ERROR(CheckInChild(std::move(argv), timeout));
  absl::StatusOr<std::string> bytes = ReadWholeFile(importsFile);
  if (!bytes.ok()) {
    return absl::InternalError(
        absl::StrCat("asset check: the checker reported success without its mesh imports (",
                     bytes.status().message(), ")"));
  }
  return MeshImports::Parse(*bytes);
}

namespace {

absl::Status CheckInChild(std::vector<std::string> argv, std::chrono::seconds timeout) {
  const auto log = Logger("assets");
  absl::StatusOr<ChildExit> child = RunChild(std::move(argv), timeout, "asset check");
  if (!child.ok()) return child.status();
  const Report parsed = ParseReport(child->out);
  const std::string field = parsed.lastAsset.empty() ? "scene" : parsed.lastAsset;
  if (child->timedOut) {
    log->warn("asset check of {} ran past {} s: killed", field, timeout.count());
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": importing this file took longer than the limit of ", timeout.count(),
                     " s (the file is malformed or too large)"));
  }
  const int waitStatus = child->waitStatus;
  if (parsed.outOfMemoryAt != 0 && WIFEXITED(waitStatus) &&
      WEXITSTATUS(waitStatus) == kExitOutOfMemory) {
    log->warn("asset check of {} ran out of its memory limit", field);
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": importing this file needs more memory than the limit of ",
                     parsed.outOfMemoryAt >> 20, " MiB (the file is malformed or too large)"));
  }
  if (WIFSIGNALED(waitStatus) && (WTERMSIG(waitStatus) == SIGXCPU)) {
    log->warn("asset check of {} ran out of its CPU time limit", field);
    return absl::InvalidArgumentError(absl::StrCat(
        field,
        ": importing this file took more CPU time than the limit (the file is malformed or "
        "too large)"));
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

}  // namespace

void ApplyAssetCheckLimits(const AssetCheckLimits& limits) {
  const auto apply = [](int resource, int64_t value, rlim_t hard, const char* name) {
    if (value <= 0) return;
    const rlimit limit{rlim_t(value), hard};
    if (::setrlimit(resource, &limit) != 0)
      Logger("assets")->warn("setrlimit {}: {}", name, std::strerror(errno));
  };
#ifdef __SANITIZE_ADDRESS__
  // AddressSanitizer's shadow memory is a writable private mapping of terabytes, which
  // RLIMIT_DATA counts: under any limit every later mapping fails and the child dies at its first
  // allocation. A sanitizer build is a test build; the limit is tested in the plain one.
  if (limits.memoryBytes > 0)
    Logger("assets")->info("the memory limit is not applied under AddressSanitizer");
#else
  if (limits.memoryBytes > 0) {
    std::snprintf(gOutOfMemoryLine, sizeof gOutOfMemoryLine, "memory %lld\n",
                  static_cast<long long>(limits.memoryBytes));
    std::set_new_handler(OnOutOfMemory);
  }
  apply(RLIMIT_DATA, limits.memoryBytes, rlim_t(limits.memoryBytes), "RLIMIT_DATA");
#endif
  // A soft CPU limit sends SIGXCPU, the hard one a second later SIGKILL.
  apply(RLIMIT_CPU, limits.cpuSeconds, rlim_t(limits.cpuSeconds + 1), "RLIMIT_CPU");
}

int ReportAssetCheck(const absl::Status& status) {
  std::printf("status %d\n%s", int(status.code()), std::string(status.message()).c_str());
  std::fflush(stdout);
  return 0;
}

int ReportJobAssets(const v1::JobSpec& spec, const AssetSource& assets, const JobLimits& limits,
                    const std::filesystem::path& importsFile) {
  const AnnouncingAssetSource announcing(assets);
  MeshImports imports;
  absl::Status built = BuildBakeJob(spec, announcing, limits, {&imports, nullptr}).status();
  if (built.ok()) built = WriteFileAtomic(importsFile, imports.Serialize());
  return ReportAssetCheck(built);
}

int RunLocalAssetCheckChild(const std::string& jobPath, const std::string& blobDir,
                            const std::filesystem::path& importsFile, const JobLimits& limits,
                            const AssetCheckLimits& resources) {
  ApplyAssetCheckLimits(resources);
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(jobPath);
  if (!spec.ok()) return ReportAssetCheck(spec.status());
  const LocalAssetSource files(JobFileDir(jobPath), blobDir, limits.maxAssetBytes);
  return ReportJobAssets(*spec, files, limits, importsFile);
}

}  // namespace probebake::runtime
