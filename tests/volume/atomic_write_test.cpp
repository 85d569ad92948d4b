// The volume is written atomically: a failed write leaves neither a partial file under the final
// name nor a temporary file; a successful one replaces an existing file whole.
#include <signal.h>
#include <sys/resource.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "probebake/volume/irradiance_slice.h"
#include "probebake/volume/vdb_io.h"
#include "volume/test_volumes.h"

namespace probebake {
namespace {

using testing::MakeTestMetadata;
using testing::MakeTestVolume;
using testing::TempDir;
using testing::TestVolumeSpec;

bool Contains(const absl::Status& status, const std::string& text) {
  return std::string(status.message()).find(text) != std::string::npos;
}

TEST(AtomicWrite, MissingDirectoryFailsNamingThePathAndLeavesNothing) {
  TempDir dir;
  const std::string path = dir.File("no/such/dir/out.vdb");
  const absl::Status status = WriteProbeVolume(path, MakeTestVolume({}), MakeTestMetadata());
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound) << status;
  EXPECT_TRUE(Contains(status, path)) << status;
  EXPECT_TRUE(dir.List().empty());
}

TEST(AtomicWrite, OverwritingReplacesTheFileWhole) {
  TempDir dir;
  const std::string path = dir.File("out.vdb");
  TestVolumeSpec big;
  big.counts[0] = 20;
  big.shOrder = 4;
  PB_ASSERT_OK(WriteProbeVolume(path, MakeTestVolume(big), MakeTestMetadata()));
  const auto bigSize = std::filesystem::file_size(path);

  TestVolumeSpec small;
  small.seed = 99;
  const ProbeVolume smallVolume = MakeTestVolume(small);
  PB_ASSERT_OK(WriteProbeVolume(path, smallVolume, MakeTestMetadata()));
  EXPECT_LT(std::filesystem::file_size(path), bigSize);
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->volume.shOrder, 2);
  EXPECT_EQ(read->volume.grid.counts[0], 3);
  EXPECT_EQ(read->volume.radiance, smallVolume.radiance);
  EXPECT_EQ(dir.List(), std::vector<std::string>{"out.vdb"});
}

// RLIMIT_FSIZE makes writes past a size fail with EFBIG, as a full disk fails them with ENOSPC.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &saved_);
    oldHandler_ = signal(SIGXFSZ, SIG_IGN);  // else the process is killed
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    ok_ = setrlimit(RLIMIT_FSIZE, &limit) == 0;
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &saved_);
    signal(SIGXFSZ, oldHandler_);
  }
  bool ok() const { return ok_; }

 private:
  rlimit saved_{};
  sighandler_t oldHandler_ = SIG_DFL;
  bool ok_ = false;
};

TEST(AtomicWrite, FailedWriteKeepsThePreviousFileAndRemovesTheTemporary) {
  TempDir dir;
  const std::string path = dir.File("out.vdb");
  const ProbeVolume first = MakeTestVolume({});
  PB_ASSERT_OK(WriteProbeVolume(path, first, MakeTestMetadata()));

  TestVolumeSpec bigSpec;
  bigSpec.counts[0] = bigSpec.counts[1] = bigSpec.counts[2] = 24;
  bigSpec.awkwardValues = false;
  const ProbeVolume big = MakeTestVolume(bigSpec);  // ~1 MB of incompressible floats
  absl::Status status;
  {
    FileSizeLimit limit(64 * 1024);
    ASSERT_TRUE(limit.ok());
    status = WriteProbeVolume(path, big, MakeTestMetadata());
  }
  EXPECT_EQ(status.code(), absl::StatusCode::kResourceExhausted) << status;
  EXPECT_TRUE(Contains(status, path)) << status;
  EXPECT_EQ(dir.List(), std::vector<std::string>{"out.vdb"});
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->volume.radiance, first.radiance);
}

TEST(AtomicWrite, FailedPngWriteLeavesNothing) {
  TempDir dir;
  const std::string path = dir.File("slice.png");
  TestVolumeSpec spec;
  spec.counts[0] = spec.counts[1] = 64;
  spec.counts[2] = 2;
  SliceOptions options;
  options.axis = 2;
  options.value = spec.origin.z;
  absl::Status status;
  {
    FileSizeLimit limit(4 * 1024);
    ASSERT_TRUE(limit.ok());
    status = WriteIrradianceSlice(MakeTestVolume(spec), options, path);
  }
  EXPECT_EQ(status.code(), absl::StatusCode::kResourceExhausted) << status;
  EXPECT_TRUE(Contains(status, path)) << status;
  EXPECT_TRUE(dir.List().empty());
}

TEST(AtomicWrite, RenameOverADirectoryFailsAndRemovesTheTemporary) {
  TempDir dir;
  const std::string path = dir.File("taken");
  std::filesystem::create_directory(path);
  std::ofstream(path + "/keep") << "x";
  const absl::Status status = WriteProbeVolume(path, MakeTestVolume({}), MakeTestMetadata());
  EXPECT_FALSE(status.ok());
  EXPECT_TRUE(Contains(status, path)) << status;
  EXPECT_EQ(dir.List(), std::vector<std::string>{"taken"});
  EXPECT_TRUE(std::filesystem::exists(path + "/keep"));
}

TEST(AtomicWrite, TrailingSlashIsNotAFilePath) {
  TempDir dir;
  const absl::Status status =
      WriteProbeVolume(dir.path() + "/", MakeTestVolume({}), MakeTestMetadata());
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  EXPECT_TRUE(dir.List().empty());
}

}  // namespace
}  // namespace probebake
