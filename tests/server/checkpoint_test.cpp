#include "server/checkpoint.h"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include "probebake/job/digest.h"
#include "temp_dir.h"

namespace probebake::server {
namespace {

using probebake::testing::TempDir;

ProbeVolume SmallVolume() {
  ProbeVolume v;
  v.grid.origin = {1.5, -2, 0.25};
  v.grid.spacing = {0.5, 0.5, 1};
  v.grid.counts[0] = 3;
  v.grid.counts[1] = 2;
  v.grid.counts[2] = 2;
  v.grid.placement = Placement::kNearSurfaces;
  v.grid.surfaceDistance = 0.75;
  v.shOrder = 1;
  const size_t n = size_t(v.grid.ProbeCount());
  v.active.assign(n, 1);
  v.active[3] = 0;
  v.radiance.assign(4, std::vector<float>(3 * n));
  v.irradiance.assign(4, std::vector<float>(3 * n));
  for (size_t c = 0; c < 4; ++c)
    for (size_t i = 0; i < 3 * n; ++i) {
      v.radiance[c][i] = float(c) * 0.1f + float(i) * 1e-3f;
      v.irradiance[c][i] = -float(i);
    }
  v.radiance[2][5] = std::numeric_limits<float>::denorm_min();  // exact bits, not values
  v.validity.assign(n, 1.f);
  v.stdError.assign(n, 0.02f);
  v.stdErrorL0.assign(n, 0.01f);
  v.sampleCount.assign(n, 256.f);
  v.window = "HANNING";
  v.stats.probes = 11;
  v.stats.samples = 2816;
  return v;
}

TEST(Checkpoint, RoundTripIsBitExact) {
  TempDir dir;
  ProbeVolume v = SmallVolume();
  std::vector<uint8_t> done(v.active.begin(), v.active.end());
  auto path = dir.path() / "j.ckpt";
  BakeWork work;
  work.wallSeconds = 1.25;
  work.samples = (int64_t(1) << 40) + 3;  // past 32 bits
  work.rays = 987654321;
  ASSERT_TRUE(WriteCheckpoint(path, "digest1", v, done, work).ok());
  auto read = ReadCheckpoint(path, "digest1");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->work.wallSeconds, 1.25);
  EXPECT_EQ(read->work.samples, (int64_t(1) << 40) + 3);
  EXPECT_EQ(read->work.rays, 987654321);
  EXPECT_EQ(read->done, done);
  EXPECT_EQ(read->DoneCount(), int64_t(done.size()) - 1);
  const ProbeVolume& r = read->volume;
  EXPECT_EQ(r.grid.origin, v.grid.origin);
  EXPECT_EQ(r.grid.spacing, v.grid.spacing);
  EXPECT_EQ(r.grid.ProbeCount(), v.grid.ProbeCount());
  EXPECT_EQ(r.grid.placement, v.grid.placement);
  EXPECT_EQ(r.shOrder, 1);
  EXPECT_EQ(r.active, v.active);
  ASSERT_EQ(r.radiance.size(), v.radiance.size());
  for (size_t c = 0; c < v.radiance.size(); ++c) {
    ASSERT_EQ(r.radiance[c].size(), v.radiance[c].size());
    EXPECT_EQ(std::memcmp(r.radiance[c].data(), v.radiance[c].data(), 4 * v.radiance[c].size()), 0);
    EXPECT_EQ(r.irradiance[c], v.irradiance[c]);
  }
  EXPECT_EQ(r.stdError, v.stdError);
  EXPECT_EQ(r.stdErrorL0, v.stdErrorL0);
  EXPECT_EQ(r.window, "HANNING");
  EXPECT_EQ(r.stats.samples, 2816);
}

// A resumed bake copies finished probes from the checkpoint: their relocation offsets, visibility
// moments, filled flags, window parameters and sky transfer must come back with their radiance, bit
// for bit (format 04 did not hold them, so a probe resumed after a restart lost them).
TEST(Checkpoint, RelocationVisibilityFilledWindowAndSkyTransferPlanesRoundTrip) {
  TempDir dir;
  ProbeVolume v = SmallVolume();
  const size_t n = size_t(v.grid.ProbeCount());
  for (size_t i = 0; i < 3 * n; ++i) v.offset.push_back(float(i) * 0.01f - 0.1f);
  for (size_t i = 0; i < n; ++i) v.filled.push_back(float(i % 2));
  for (size_t i = 0; i < n; ++i) v.autoWindowT.push_back(1.0f / float(i + 1));
  v.visibility.assign(64, std::vector<float>(3 * n));
  for (size_t t = 0; t < 64; ++t)
    for (size_t i = 0; i < 3 * n; ++i) v.visibility[t][i] = float(t) + float(i) * 0.125f;
  v.skyTransferOrder = 1;
  v.skyTransfer.assign(4 * 4, std::vector<float>(3 * n));
  for (size_t e = 0; e < 16; ++e)
    for (size_t i = 0; i < 3 * n; ++i) v.skyTransfer[e][i] = float(e) - float(i) * 0.5f;
  const std::vector<uint8_t> done(n, 1);
  const auto path = dir.path() / "j.ckpt";
  ASSERT_TRUE(WriteCheckpoint(path, "d", v, done).ok());
  const auto read = ReadCheckpoint(path, "d");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->volume.offset, v.offset);
  EXPECT_EQ(read->volume.filled, v.filled);
  EXPECT_EQ(read->volume.autoWindowT, v.autoWindowT);
  EXPECT_EQ(read->volume.visibility, v.visibility);
  EXPECT_EQ(read->volume.skyTransferOrder, 1);
  EXPECT_EQ(read->volume.skyTransfer, v.skyTransfer);
  // Without those features the planes stay empty.
  ASSERT_TRUE(WriteCheckpoint(path, "d", SmallVolume(), done).ok());
  const auto plain = ReadCheckpoint(path, "d");
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_TRUE(plain->volume.offset.empty() && plain->volume.visibility.empty() &&
              plain->volume.filled.empty() && plain->volume.autoWindowT.empty());
}

TEST(Checkpoint, ReadsTheFormerFormatWithZeroWork) {
  TempDir dir;
  ProbeVolume v = SmallVolume();
  std::vector<uint8_t> done(v.active.begin(), v.active.end());
  auto path = dir.path() / "j.ckpt";
  BakeWork work;
  work.samples = 5;
  ASSERT_TRUE(WriteCheckpoint(path, "digest1", v, done, work).ok());
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  // PBCKPT04 is 05 without the empty planes of offsets, filled flags, window parameters,
  // visibility and sky transfer (five 8-byte counts and the 4-byte order) before the hash; PBCKPT02
  // is 04 without the work (3 x 8 bytes) and the L0 standard errors (a count and a float per
  // probe).
  ASSERT_EQ(bytes.substr(0, 8), "PBCKPT05");
  const size_t planesBytes = 5 * 8 + 4;
  std::string v04 = "PBCKPT04" + bytes.substr(8, bytes.size() - 8 - planesBytes - 64);
  v04 += Sha256Hex(v04);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << v04;
  const auto read04 = ReadCheckpoint(path, "digest1");
  ASSERT_TRUE(read04.ok()) << read04.status();
  EXPECT_EQ(read04->work.samples, 5);
  EXPECT_EQ(read04->volume.stdErrorL0, v.stdErrorL0);
  EXPECT_TRUE(read04->volume.visibility.empty());
  const size_t l0Bytes = 8 + 4 * v.stdErrorL0.size();
  std::string old =
      "PBCKPT02" + bytes.substr(8, bytes.size() - 8 - planesBytes - l0Bytes - 24 - 64);
  old += Sha256Hex(old);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << old;
  auto read = ReadCheckpoint(path, "digest1");
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->done, done);
  EXPECT_EQ(read->work.samples, 0);
  EXPECT_EQ(read->volume.stats.samples, 2816);
  EXPECT_EQ(read->volume.stdErrorL0, v.stdError);  // the L0 figure then
}

TEST(Checkpoint, RejectsOtherDigestsAndDamage) {
  TempDir dir;
  ProbeVolume v = SmallVolume();
  std::vector<uint8_t> done(v.active.begin(), v.active.end());
  auto path = dir.path() / "j.ckpt";
  EXPECT_EQ(ReadCheckpoint(path, "d").status().code(), absl::StatusCode::kNotFound);
  ASSERT_TRUE(WriteCheckpoint(path, "digest1", v, done).ok());
  EXPECT_EQ(ReadCheckpoint(path, "digest2").status().code(), absl::StatusCode::kDataLoss);
  // Without an expected digest (tests reading what a server left): any digest, same checks.
  auto any = ReadCheckpointOfAnyJob(path);
  ASSERT_TRUE(any.ok()) << any.status();
  EXPECT_EQ(any->jobDigest, "digest1");
  EXPECT_EQ(any->DoneCount(), int64_t(v.grid.ProbeCount()) - 1);
  // A flipped byte and a torn (truncated) file are both caught by the checksum.
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  std::string flipped = bytes;
  flipped[flipped.size() / 2] ^= 0x10;
  std::ofstream(path, std::ios::binary | std::ios::trunc) << flipped;
  EXPECT_EQ(ReadCheckpoint(path, "digest1").status().code(), absl::StatusCode::kDataLoss);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes.substr(0, bytes.size() - 100);
  EXPECT_EQ(ReadCheckpoint(path, "digest1").status().code(), absl::StatusCode::kDataLoss);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << "garbage";
  EXPECT_EQ(ReadCheckpoint(path, "digest1").status().code(), absl::StatusCode::kDataLoss);
  EXPECT_EQ(ReadCheckpointOfAnyJob(path).status().code(), absl::StatusCode::kDataLoss);
}

TEST(Checkpoint, FilePathIsTheJobIdUnderCheckpoints) {
  EXPECT_EQ(CheckpointFilePath("/data", "bakeJobs/0123456789abcdef"),
            std::filesystem::path("/data/checkpoints/0123456789abcdef.ckpt"));
}

}  // namespace
}  // namespace probebake::server
