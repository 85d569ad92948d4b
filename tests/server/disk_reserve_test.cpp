#include "server/disk_reserve.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "temp_dir.h"

namespace probebake::server {
namespace {

using probebake::testing::TempDir;

int64_t AllocatedBytes(const std::filesystem::path& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 ? int64_t(st.st_blocks) * 512 : -1;
}

TEST(DiskReserve, HoldsAllocatedSpaceGivesItBackAndTakesItAgain) {
  TempDir dir;
  const auto path = dir.path() / "reserve";
  DiskReserve reserve(path, 1 << 20);
  EXPECT_FALSE(reserve.held());
  ASSERT_TRUE(reserve.Restore());
  EXPECT_TRUE(reserve.held());
  EXPECT_GE(AllocatedBytes(path), 1 << 20);  // real blocks, not a sparse file
  EXPECT_TRUE(reserve.Restore());            // already held: unchanged
  EXPECT_TRUE(reserve.Release());
  EXPECT_FALSE(reserve.held());
  EXPECT_EQ(AllocatedBytes(path), -1);
  EXPECT_FALSE(reserve.Release());  // nothing left to give
  EXPECT_TRUE(reserve.Restore());
  EXPECT_GE(AllocatedBytes(path), 1 << 20);
}

TEST(DiskReserve, RetakeTakesBackWhatIsFreeAtOnce) {
  // Lent for a write and taken back right after it, without Restore's room to spare.
  TempDir dir;
  const auto path = dir.path() / "reserve";
  DiskReserve reserve(path, 2 << 20);
  ASSERT_TRUE(reserve.Restore());
  ASSERT_TRUE(reserve.Release());
  EXPECT_TRUE(reserve.Retake());
  EXPECT_TRUE(reserve.held());
  EXPECT_GE(AllocatedBytes(path), 2 << 20);
  EXPECT_TRUE(reserve.Retake());  // held already: unchanged
}

TEST(DiskReserve, ZeroBytesHoldsNothing) {
  TempDir dir;
  DiskReserve none(dir.path() / "reserve", 0);
  EXPECT_FALSE(none.Restore());
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "reserve"));
  EXPECT_FALSE(none.Release());
  EXPECT_FALSE(none.Retake());
}

TEST(DiskReserve, IsNotTakenWithoutRoomToSpare) {
  // More than the file system could give twice over: no reserve, and no partial file left.
  TempDir dir;
  DiskReserve huge(dir.path() / "reserve", int64_t(1) << 60);
  EXPECT_FALSE(huge.Restore());
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "reserve"));
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "reserve.tmp"));
}

}  // namespace
}  // namespace probebake::server
