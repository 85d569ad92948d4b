// Sharded bakes (runtime/shard_plan.h): the plan tiles the grid, balances expected work rather than
// grid points, does not depend on the thread count, and the parts of N = 1, 3 and 7 shards, each
// baked on its own, merge into the volume of the whole grid bit for bit.
#include "runtime/shard_plan.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "probebake/bake/bake.h"
#include "probebake/volume/vdb_io.h"
#include "probebake/volume/volume_merge.h"
#include "runtime/shard_progress.h"
#include "temp_dir.h"
#include "tests/bake/bake_test_util.h"
#include "volume_compare.h"

namespace probebake::testing {
namespace {

#define PB_ASSERT_OK(expr)                      \
  do {                                          \
    const ::absl::Status pb_status_ = (expr);   \
    ASSERT_TRUE(pb_status_.ok()) << pb_status_; \
  } while (false)

using runtime::PlanShards;
using runtime::ShardBox;
using runtime::ShardGrid;
using runtime::ShardPlan;
using runtime::WorkEstimate;

// A floor, a slab of solid boxes filling most of the grid's +x half (so placement leaves many of
// its points out), a rect light and a sun (whose light is also traced from it: light paths that
// every shard traces again from the scene alone) under a sky; a 9 x 7 x 5 grid with non-binary
// spacings.
BakeJob WholeJob() {
  BakeJob job = MakeJob(2, 32, {-1.7, -1.3, 0.3});
  job.grid.counts[0] = 9;
  job.grid.counts[1] = 7;
  job.grid.counts[2] = 5;
  job.grid.spacing = {0.4, 0.45, 0.35};
  job.grid.placement = Placement::kOutsideGeometry;
  job.settings.batches = 4;
  job.settings.maxDepth = 3;
  job.settings.seed = 5;
  job.settings.irradiance = true;
  job.scene.environment = {Environment::Kind::kUniform, {0.3, 0.4, 0.6}, nullptr};
  const uint32_t white = AddMaterial(&job.scene, {0.7, 0.7, 0.7});
  AddQuad(&job.scene, {-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}, white);
  AddBox(&job.scene, {0.15, -1.5, 0.1}, {2.0, 1.5, 1.6}, white, false);
  job.scene.lights.push_back(RectLight{{-0.5, -0.5, 2.5}, {0, 1, 0}, {1, 0, 0}, {5, 5, 5}, false});
  job.scene.lights.push_back(
      DirectionalLight{Normalize(Vec3d{0.3, 0.2, -1}), {3, 3, 3}, std::cos(0.005)});
  return job;
}

// Every grid point lies in exactly one box.
void ExpectTiles(const ShardPlan& plan, const int counts[3]) {
  const size_t points = size_t(counts[0]) * size_t(counts[1]) * size_t(counts[2]);
  std::vector<int> owner(points, -1);
  for (size_t s = 0; s < plan.shards.size(); ++s) {
    const ShardBox& b = plan.shards[s];
    ASSERT_GE(b.GridPoints(), 1) << "shard " << s;
    for (int z = b.first[2]; z < b.first[2] + b.counts[2]; ++z)
      for (int y = b.first[1]; y < b.first[1] + b.counts[1]; ++y)
        for (int x = b.first[0]; x < b.first[0] + b.counts[0]; ++x) {
          ASSERT_TRUE(x < counts[0] && y < counts[1] && z < counts[2]) << "shard " << s;
          int& o = owner[x + size_t(counts[0]) * (y + size_t(counts[1]) * z)];
          ASSERT_EQ(o, -1) << "(" << x << ", " << y << ", " << z << ") in shards " << o << ", "
                           << s;
          o = int(s);
        }
  }
  EXPECT_EQ(std::count(owner.begin(), owner.end(), -1), 0);
}

bool SamePlan(const ShardPlan& a, const ShardPlan& b) {
  if (a.shards.size() != b.shards.size()) return false;
  for (size_t i = 0; i < a.shards.size(); ++i) {
    if (a.shards[i].first != b.shards[i].first || a.shards[i].counts != b.shards[i].counts ||
        a.shards[i].expectedWork != b.shards[i].expectedWork)
      return false;
  }
  return true;
}

TEST(ShardPlan, PartsOfOneThreeAndSevenShardsMergeIntoTheWholeGridBitForBit) {
  const BakeJob whole = WholeJob();
  TempDir dir;
  const ProbeVolume all = BakeOrDie(whole, 2);
  ASSERT_LT(all.stats.probes, whole.grid.ProbeCount()) << "the placement left no point out";
  ASSERT_GT(all.stats.probes, 0);
  PB_ASSERT_OK(
      WriteProbeVolume((dir.path() / "whole.vdb").string(), all, VolumeMetadataFor(whole)));
  for (int n : {1, 3, 7}) {
    SCOPED_TRACE(::testing::Message() << n << " shards");
    absl::StatusOr<ShardPlan> plan = PlanShards(whole, n, 2);
    ASSERT_TRUE(plan.ok()) << plan.status();
    ASSERT_EQ(plan->shards.size(), size_t(n));
    ExpectTiles(*plan, whole.grid.counts);
    // Every grid point is placed by the pre-pass of a grid this small: it expects exactly the
    // probes the bake bakes.
    EXPECT_TRUE(plan->estimate.Exact());
    EXPECT_EQ(plan->expectedProbes, all.stats.probes);
    std::vector<VolumePart> parts;
    for (int i = n - 1; i >= 0; --i) {  // in reverse: the merge must not need them in order
      BakeJob shard = whole;
      shard.grid = ShardGrid(whole.grid, plan->shards[size_t(i)]);
      const ProbeVolume part = BakeOrDie(shard, 1);
      EXPECT_EQ(part.stats.probes, plan->shards[size_t(i)].expectedProbes) << "shard " << i;
      const std::string path = (dir.path() / ("part" + std::to_string(i) + ".vdb")).string();
      PB_ASSERT_OK(WriteProbeVolume(path, part, VolumeMetadataFor(shard)));
      absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
      ASSERT_TRUE(read.ok()) << read.status();
      parts.push_back({path, std::move(*read)});
    }
    absl::StatusOr<ProbeVolumeFile> merged = MergeProbeVolumes(std::move(parts));
    ASSERT_TRUE(merged.ok()) << merged.status();
    EXPECT_EQ(merged->volume.stats.probes, all.stats.probes);
    const std::filesystem::path out = dir.path() / ("merged" + std::to_string(n) + ".vdb");
    PB_ASSERT_OK(WriteProbeVolume(out.string(), merged->volume, merged->meta));
    ExpectSameVolume(dir.path() / "whole.vdb", out);
  }
}

TEST(ShardPlan, BalancesExpectedProbesNotGridPoints) {
  // Two shards: the +x half of the grid is mostly inside the boxes, so a split by grid points
  // (4 or 5 of 9 columns) would give one shard most of the probes.
  const BakeJob whole = WholeJob();
  absl::StatusOr<ShardPlan> plan = PlanShards(whole, 2, 1);
  ASSERT_TRUE(plan.ok()) << plan.status();
  const ShardBox &a = plan->shards[0], &b = plan->shards[1];
  EXPECT_NE(a.GridPoints(), b.GridPoints());
  // The work of one grid plane (at most 9 x 7 points' samples) is the granularity of the cut.
  const int64_t plane = int64_t(9) * 7 * (runtime::kPlacementRays + whole.settings.samplesPerProbe);
  EXPECT_LE(std::abs(a.expectedWork - b.expectedWork), plane);
  EXPECT_LT(plan->Imbalance(), 1.2);
}

TEST(ShardPlan, DependsOnTheJobAloneNotOnThreads) {
  const BakeJob whole = WholeJob();
  for (int n : {2, 5, 7}) {
    absl::StatusOr<ShardPlan> one = PlanShards(whole, n, 1), two = PlanShards(whole, n, 2);
    ASSERT_TRUE(one.ok() && two.ok());
    EXPECT_TRUE(SamePlan(*one, *two)) << n << " shards";
  }
}

// A synthetic estimate (no tracing): points with x < activeBelow are baked.
WorkEstimate Estimate(const int counts[3], int stride, int activeBelow, int64_t samples) {
  WorkEstimate e;
  e.samplesPerProbe = samples;
  for (int a = 0; a < 3; ++a) {
    e.stride[a] = stride;
    e.samples[a] = (counts[a] + stride - 1) / stride;
  }
  for (int z = 0; z < e.samples[2]; ++z)
    for (int y = 0; y < e.samples[1]; ++y)
      for (int x = 0; x < e.samples[0]; ++x) e.active.push_back(x * stride < activeBelow ? 1 : 0);
  return e;
}

TEST(ShardPlan, SubLatticeEstimateTilesAndBalancesLargeGrids) {
  ProbeGrid grid;
  grid.counts[0] = 200;
  grid.counts[1] = 90;
  grid.counts[2] = 40;
  const WorkEstimate e = Estimate(grid.counts, 4, 120, 1024);
  for (int n : {2, 13, 100, 257}) {
    SCOPED_TRACE(::testing::Message() << n << " shards");
    absl::StatusOr<ShardPlan> plan = PlanShards(grid, e, n);
    ASSERT_TRUE(plan.ok()) << plan.status();
    ASSERT_EQ(plan->shards.size(), size_t(n));
    ExpectTiles(*plan, grid.counts);
    EXPECT_EQ(plan->expectedProbes, int64_t(120) * 90 * 40);
    EXPECT_LT(plan->Imbalance(), 1.1);
  }
}

TEST(ShardPlan, AsManyShardsAsGridPointsAndNoMore) {
  ProbeGrid grid;
  grid.counts[0] = 3;
  grid.counts[1] = 3;
  grid.counts[2] = 1;
  const WorkEstimate e = Estimate(grid.counts, 1, 2, 64);
  for (int n = 1; n <= 9; ++n) {
    absl::StatusOr<ShardPlan> plan = PlanShards(grid, e, n);
    ASSERT_TRUE(plan.ok()) << n << ": " << plan.status();
    ExpectTiles(*plan, grid.counts);
  }
  absl::StatusOr<ShardPlan> tooMany = PlanShards(grid, e, 10);
  EXPECT_TRUE(absl::IsInvalidArgument(tooMany.status()));
  EXPECT_EQ(tooMany.status().message(),
            "shards: 10 shards for a grid of 9 points: at most one shard per grid point");
  EXPECT_TRUE(absl::IsInvalidArgument(PlanShards(grid, e, 0).status()));
}

TEST(ShardPlan, ShardGridKeepsTheWholeGridsMinOnItsFirstShards) {
  ProbeGrid whole;
  whole.origin = {-0.0, 0.3, 1e5 + 0.1};
  whole.spacing = {0.8, 2.0 / 3.0, 0.1};
  whole.counts[0] = whole.counts[1] = whole.counts[2] = 10;
  ShardBox box;
  box.first = {0, 3, 0};
  box.counts = {5, 7, 10};
  const ProbeGrid g = ShardGrid(whole, box);
  EXPECT_TRUE(std::signbit(g.origin.x)) << "the min -0 stays -0";
  EXPECT_EQ(g.origin.y, 0.3 + (2.0 / 3.0) * 3);
  EXPECT_EQ(g.origin.z, whole.origin.z);
  EXPECT_EQ(g.counts[0], 5);
  EXPECT_EQ(g.spacing, whole.spacing);
}

TEST(ShardPlan, ParsesShardSpecs) {
  int i = -1, n = -1;
  PB_ASSERT_OK(runtime::ParseShardSpec("3/7", "--shard", &i, &n));
  EXPECT_EQ(i, 3);
  EXPECT_EQ(n, 7);
  for (const char* bad : {"7/7", "-1/3", "1/0", "1", "a/3", "1/3/4", ""})
    EXPECT_TRUE(absl::IsInvalidArgument(runtime::ParseShardSpec(bad, "--shard", &i, &n))) << bad;
  EXPECT_EQ(runtime::ParseShardSpec("4/2", "--shard", &i, &n).message(),
            "--shard: I must be in [0, 1], got 4");
}

TEST(ShardProgress, RoundTripsThroughJson) {
  runtime::ShardProgress p;
  p.shard = 2;
  p.shards = 4;
  p.host = "node\"7";
  p.pid = 1234;
  p.stage = "baking";
  p.probesDone = 10;
  p.probesTotal = 288;
  p.samples = int64_t(1) << 40;
  p.rays = 51234;
  p.elapsedSeconds = 3.5;
  absl::StatusOr<runtime::ShardProgress> q =
      runtime::ParseShardProgress(runtime::ShardProgressJson(p));
  ASSERT_TRUE(q.ok()) << q.status();
  EXPECT_EQ(q->host, p.host);
  EXPECT_EQ(q->samples, p.samples);
  EXPECT_EQ(q->probesTotal, 288);
  EXPECT_EQ(q->stage, "baking");
  EXPECT_FALSE(runtime::ParseShardProgress("{\"shard\":1}").ok());
  EXPECT_FALSE(runtime::ParseShardProgress("not json").ok());
}

}  // namespace
}  // namespace probebake::testing
