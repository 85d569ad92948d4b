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

// The stand-in child: `script` run by sh; the arguments the check appends become $0 to $3
// (--check-job-assets SPEC --check-imports-out FILE).
AssetCheck Child(const std::string& script, seconds timeout = seconds(30),
                 const std::filesystem::path& tmpDir = std::filesystem::temp_directory_path()) {
  return AssetCheck({"/bin/sh", "-c", script}, tmpDir, timeout);
}

// What a stand-in that built the job writes before its report: a hand-over without entries
// (the magic, then a count of 0 in 8 bytes).
const std::string kWriteNoImports =
    "printf 'PBIMPORTS1\\000\\000\\000\\000\\000\\000\\000\\000' > \"$3\"; ";

int ReadLines(const std::filesystem::path& path) {
  std::ifstream in(path);
  int lines = 0;
  for (std::string line; std::getline(in, line);) ++lines;
  return lines;
}

TEST(AssetCheck, AJobWithoutAssetsRunsNoChild) {
  v1::JobSpec spec;
  spec.mutable_scene()->add_meshes()->add_positions(0);
  EXPECT_TRUE(Child("exit 9").Import(spec).ok());
}

TEST(AssetCheck, TheChildsReportIsTheResult) {
  absl::StatusOr<MeshImports> imported =
      Child(kWriteNoImports + "echo asset scene.meshes[0].blob; printf 'status 0\\n'")
          .Import(JobWithAMeshBlob());
  ASSERT_TRUE(imported.ok()) << imported.status();
  EXPECT_EQ(imported->size(), 0u);
  const absl::Status refused =
      Child(
          "echo asset scene.meshes[0].blob; printf 'status 3\\nscene.meshes[0].blob: bad\\nand "
          "more'")
          .Import(JobWithAMeshBlob())
          .status();
  EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument) << refused;
  EXPECT_EQ(refused.message(), "scene.meshes[0].blob: bad\nand more");
}

TEST(AssetCheck, SuccessWithoutReadableImportsIsTheCheckersFault) {
  const absl::Status none = Child("printf 'status 0\\n'").Import(JobWithAMeshBlob()).status();
  EXPECT_EQ(none.code(), absl::StatusCode::kInternal) << none;
  EXPECT_NE(none.message().find("without its mesh imports"), absl::string_view::npos) << none;
  const absl::Status damaged = Child("printf 'PBIMPORTS1\\001' > \"$3\"; printf 'status 0\\n'")
                                   .Import(JobWithAMeshBlob())
                                   .status();
  EXPECT_EQ(damaged.code(), absl::StatusCode::kInternal) << damaged;
  EXPECT_NE(damaged.message().find("mesh imports: cut short"), absl::string_view::npos) << damaged;
}

TEST(AssetCheck, EveryImportRunsAChildAndLeavesNoFile) {
  // Each build takes its meshes from a child of its own (nothing is held between a job's builds),
  // and the spec and imports files go whatever the outcome.
  const std::filesystem::path tmp =
      std::filesystem::temp_directory_path() / ("asset-check-tmp-" + std::to_string(getpid()));
  std::filesystem::remove_all(tmp);
  std::filesystem::create_directories(tmp);
  const std::filesystem::path runs = tmp.string() + "-runs";
  std::filesystem::remove(runs);
  const std::string countRun = "echo run >> " + runs.string() + "; ";
  const AssetCheck good =
      Child(kWriteNoImports + countRun + "printf 'status 0\\n'", seconds(30), tmp);
  EXPECT_TRUE(good.Import(JobWithAMeshBlob()).ok());
  EXPECT_TRUE(good.Import(JobWithAMeshBlob()).ok());
  EXPECT_EQ(ReadLines(runs), 2);
  const AssetCheck bad =
      Child(kWriteNoImports + countRun + "printf 'status 3\\nno'", seconds(30), tmp);
  EXPECT_FALSE(bad.Import(JobWithAMeshBlob()).ok());
  EXPECT_FALSE(Child(kWriteNoImports + countRun + "kill -SEGV $$", seconds(30), tmp)
                   .Import(JobWithAMeshBlob())
                   .ok());
  EXPECT_EQ(ReadLines(runs), 4);
  EXPECT_TRUE(std::filesystem::is_empty(tmp));
  std::filesystem::remove(runs);
  std::filesystem::remove_all(tmp);
}

TEST(AssetCheck, ACrashNamesTheAssetBeingRead) {
  const absl::Status crashed =
      Child("echo asset scene.meshes[0].blob; echo asset scene.environment.map.blob; kill -SEGV $$")
          .Import(JobWithAMeshBlob())
          .status();
  EXPECT_EQ(crashed.code(), absl::StatusCode::kInvalidArgument) << crashed;
  EXPECT_EQ(crashed.message(),
            "scene.environment.map.blob: the importer crashed on this file (signal 11); the file "
            "is malformed");
}

TEST(AssetCheck, AHangIsKilledAtTheTimeLimit) {
  const auto start = std::chrono::steady_clock::now();
  const absl::Status hung = Child("echo asset scene.meshes[0].blob; exec sleep 30", seconds(1))
                                .Import(JobWithAMeshBlob())
                                .status();
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
          .Import(JobWithAMeshBlob())
          .status();
  EXPECT_EQ(memory.code(), absl::StatusCode::kInvalidArgument) << memory;
  EXPECT_EQ(memory.message(),
            "scene.meshes[0].blob: importing this file needs more memory than the limit of 256 "
            "MiB (the file is malformed or too large)");
  const absl::Status cpu =
      Child("echo asset scene.meshes[0].blob; kill -XCPU $$").Import(JobWithAMeshBlob()).status();
  EXPECT_EQ(cpu.code(), absl::StatusCode::kInvalidArgument) << cpu;
  EXPECT_EQ(cpu.message(),
            "scene.meshes[0].blob: importing this file took more CPU time than the limit (the "
            "file is malformed or too large)");
  // Exit code 86 without the memory line is no such report.
  EXPECT_EQ(Child("exit 86").Import(JobWithAMeshBlob()).status().code(),
            absl::StatusCode::kInternal);
}

TEST(AssetCheck, AnAllocationPastTheMemoryLimitEndsTheChildWithItsReport) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "AddressSanitizer's shadow memory counts against RLIMIT_DATA, so the limit is "
                  "not applied in a sanitizer build (runtime/asset_check.cpp): it is tested in "
                  "the plain build";
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
  const absl::Status silent = Child("exit 5").Import(JobWithAMeshBlob()).status();
  EXPECT_EQ(silent.code(), absl::StatusCode::kInternal) << silent;
  EXPECT_NE(silent.message().find("exited with code 5"), absl::string_view::npos) << silent;
  const absl::Status missing =
      AssetCheck({"/nonexistent/checker"}, std::filesystem::temp_directory_path(), seconds(5))
          .Import(JobWithAMeshBlob())
          .status();
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
  const std::filesystem::path imports = data / "tmp" / "imports";
  EXPECT_EQ(RunAssetCheckChild(spec, imports, data, 1 << 20, JobLimits(), {0, 0}),
            0);                                    // reports the missing blob
  EXPECT_FALSE(std::filesystem::exists(imports));  // only a job that built hands imports over
  EXPECT_TRUE(std::filesystem::exists(inUse));
  EXPECT_TRUE(std::filesystem::exists(spec));
  EXPECT_EQ(BlobStore::OpenForReading(data / "absent", 1 << 20).status().code(),
            absl::StatusCode::kNotFound);
  std::filesystem::remove_all(data);
}

}  // namespace
}  // namespace probebake::server
