// The parent side of the asset check (asset_check.h), with stand-in children: a shell that
// reports, crashes, hangs or exits without a report. The real child runs in the e2e tests.
#include "server/asset_check.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

#include "server/blob_store.h"

namespace probebake::server {
namespace {

using std::chrono::seconds;

// A job with one uploaded mesh: the check runs only when a job has asset blobs.
v1::JobSpec JobWithAMeshBlob() {
  v1::JobSpec spec;
  v1::Mesh* mesh = spec.mutable_scene()->add_meshes();
  mesh->mutable_blob()->set_hash(std::string(64, 'a'));
  mesh->mutable_blob()->set_size_bytes(10);
  mesh->set_format("ply");
  return spec;
}

// The stand-in child: `script` run by sh; the arguments the check appends become $0 and $1.
AssetCheck Child(const std::string& script, seconds timeout = seconds(30)) {
  return AssetCheck({"/bin/sh", "-c", script}, std::filesystem::temp_directory_path(), timeout);
}

int ReadLines(const std::filesystem::path& path) {
  std::ifstream in(path);
  int lines = 0;
  for (std::string line; std::getline(in, line);) ++lines;
  return lines;
}

TEST(AssetCheck, AJobWithoutAssetsRunsNoChild) {
  v1::JobSpec spec;
  spec.mutable_scene()->add_meshes()->add_positions(0);
  EXPECT_TRUE(Child("exit 9").Check(spec).ok());
}

TEST(AssetCheck, TheChildsReportIsTheResult) {
  EXPECT_TRUE(Child("echo asset scene.meshes[0].blob; printf 'status 0\\n'")
                  .Check(JobWithAMeshBlob())
                  .ok());
  const absl::Status refused =
      Child(
          "echo asset scene.meshes[0].blob; printf 'status 3\\nscene.meshes[0].blob: bad\\nand "
          "more'")
          .Check(JobWithAMeshBlob());
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument) << refused;
  EXPECT_EQ(refused.message(), "scene.meshes[0].blob: bad\nand more");
}

TEST(AssetCheck, APassedSpecIsNotCheckedAgainAFailedOneIs) {
  const std::filesystem::path runs =
      std::filesystem::temp_directory_path() / ("asset-check-runs-" + std::to_string(getpid()));
  std::filesystem::remove(runs);
  const AssetCheck good = Child("echo run >> " + runs.string() + "; printf 'status 0\\n'");
  EXPECT_TRUE(good.Check(JobWithAMeshBlob()).ok());
  EXPECT_TRUE(good.Check(JobWithAMeshBlob()).ok());
  v1::JobSpec other = JobWithAMeshBlob();
  other.mutable_scene()->mutable_meshes(0)->set_format("obj");
  EXPECT_TRUE(good.Check(other).ok());
  EXPECT_EQ(ReadLines(runs), 2);  // the first spec once, the other once
  const AssetCheck bad = Child("echo run >> " + runs.string() + "; printf 'status 3\\nno'");
  EXPECT_FALSE(bad.Check(JobWithAMeshBlob()).ok());
  EXPECT_FALSE(bad.Check(JobWithAMeshBlob()).ok());
  EXPECT_EQ(ReadLines(runs), 4);
  std::filesystem::remove(runs);
}

TEST(AssetCheck, ACrashNamesTheAssetBeingRead) {
  const absl::Status crashed =
      Child("echo asset scene.meshes[0].blob; echo asset scene.environment.map.blob; kill -SEGV $$")
          .Check(JobWithAMeshBlob());
  EXPECT_EQ(crashed.code(), absl::StatusCode::kInvalidArgument) << crashed;
  EXPECT_EQ(crashed.message(),
            "scene.environment.map.blob: the importer crashed on this file (signal 11); the file "
            "is malformed");
}

TEST(AssetCheck, AHangIsKilledAtTheTimeLimit) {
  const auto start = std::chrono::steady_clock::now();
  const absl::Status hung =
      Child("echo asset scene.meshes[0].blob; exec sleep 30", seconds(1)).Check(JobWithAMeshBlob());
  EXPECT_LT(std::chrono::steady_clock::now() - start, seconds(20));
  EXPECT_EQ(hung.code(), absl::StatusCode::kInvalidArgument) << hung;
  EXPECT_EQ(hung.message(),
            "scene.meshes[0].blob: importing this file took longer than the limit of 1 s "
            "(the file is malformed or too large)");
}

TEST(AssetCheck, ResourceLimitsNameTheAssetAndTheLimit) {
  // The child's reports of its limits (runtime/asset_check.h): an allocation past the memory
  // limit, and SIGXCPU past the CPU limit.
  const absl::Status memory =
      Child("echo asset scene.meshes[0].blob; echo memory 268435456; exit 86")
          .Check(JobWithAMeshBlob());
  EXPECT_EQ(memory.code(), absl::StatusCode::kInvalidArgument) << memory;
  EXPECT_EQ(memory.message(),
            "scene.meshes[0].blob: importing this file needs more memory than the limit of 256 "
            "MiB (the file is malformed or too large)");
  const absl::Status cpu =
      Child("echo asset scene.meshes[0].blob; kill -XCPU $$").Check(JobWithAMeshBlob());
  EXPECT_EQ(cpu.code(), absl::StatusCode::kInvalidArgument) << cpu;
  EXPECT_EQ(cpu.message(),
            "scene.meshes[0].blob: importing this file took more CPU time than the limit (the "
            "file is malformed or too large)");
  // Exit code 86 without the memory line is no such report.
  EXPECT_EQ(Child("exit 86").Check(JobWithAMeshBlob()).code(), absl::StatusCode::kInternal);
}

TEST(AssetCheck, AnAllocationPastTheMemoryLimitEndsTheChildWithItsReport) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "AddressSanitizer's allocator aborts when the data limit refuses its mmap, "
                  "before operator new can throw: the limit is tested in the plain build";
#endif
  // The real limit in a forked child: RLIMIT_DATA of 256 MiB, then 2 GiB asked for.
  int out[2];
  ASSERT_EQ(pipe(out), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    dup2(out[1], STDOUT_FILENO);
    runtime::ApplyAssetCheckLimits({int64_t(256) << 20, 0});
    char* volatile block = new char[size_t(2) << 30];
    block[0] = 1;
    _exit(0);  // not reached
  }
  close(out[1]);
  std::string report;
  char buffer[256];
  for (ssize_t n; (n = read(out[0], buffer, sizeof buffer)) > 0;) report.append(buffer, size_t(n));
  close(out[0]);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << status;
  EXPECT_EQ(WEXITSTATUS(status), 86);
  EXPECT_EQ(report, "memory 268435456\n");
}

TEST(AssetCheck, NoReportIsAnInternalError) {
  const absl::Status silent = Child("exit 5").Check(JobWithAMeshBlob());
  EXPECT_EQ(silent.code(), absl::StatusCode::kInternal) << silent;
  EXPECT_NE(silent.message().find("exited with code 5"), absl::string_view::npos) << silent;
  const absl::Status missing =
      AssetCheck({"/nonexistent/checker"}, std::filesystem::temp_directory_path(), seconds(5))
          .Check(JobWithAMeshBlob());
  EXPECT_EQ(missing.code(), absl::StatusCode::kInternal) << missing;
}

TEST(AssetCheck, TheChildLeavesTheServersScratchFilesAlone) {
  // The child reads the running server's store: DATA/tmp holds that server's files in use
  // (other checks' spec files, running jobs' volumes), which it once cleared as a server does at
  // start-up, failing parallel submits and jobs writing their volumes.
  const std::filesystem::path data =
      std::filesystem::temp_directory_path() / ("asset-check-data-" + std::to_string(getpid()));
  std::filesystem::remove_all(data);
  ASSERT_TRUE(BlobStore::Open(data, 1 << 20).ok());
  const std::filesystem::path inUse = data / "tmp" / "job.vdb", spec = data / "tmp" / "spec.pb";
  std::ofstream(inUse) << "volume being written";
  std::ofstream(spec, std::ios::binary) << JobWithAMeshBlob().SerializeAsString();
  EXPECT_EQ(RunAssetCheckChild(spec, data, 1 << 20, JobLimits(), {0, 0}),
            0);  // reports the missing blob
  EXPECT_TRUE(std::filesystem::exists(inUse));
  EXPECT_TRUE(std::filesystem::exists(spec));
  EXPECT_EQ(BlobStore::OpenForReading(data / "absent", 1 << 20).status().code(),
            absl::StatusCode::kNotFound);
  std::filesystem::remove_all(data);
}

}  // namespace
}  // namespace probebake::server
