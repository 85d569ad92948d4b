// Splitting a job's probe grid into N sub-grids for a sharded bake (docs/cluster.md): each shard
// bakes one sub-grid on its own (another machine, another cluster task) and MergeProbeVolumes
// (`probebake merge`) joins the parts into the volume of the whole grid, bit for bit, since a
// probe's values depend on the scene, the settings and its position only (docs/job-format.md,
// `grid`).
//
// Work, not grid points: a grid point the placement leaves out (inside geometry, or far from
// surfaces with NEAR_SURFACES) costs its placement test only, a baked probe its samples on top.
// The work of a grid point, in rays, is counted as kPlacementRays, plus samplesPerProbe when the
// placement bakes it (at least one ray per sample; the cap under adaptive sampling). A pre-pass
// (EstimateWork) runs the bake's own placement over a sub-lattice of the grid: every stride-th
// point per axis, at most kMaxEstimatePoints points, so every point of a grid that small. Each
// sampled point stands for the block of grid points from it to the next sampled one.
//
// The split (PlanShards) is a recursive bisection: a box of n shards is cut across one axis into
// a box of n1 and one of n - n1 shards (n1 = n / 2, rounded either way, or any count that leaves
// each box at least a grid point per shard when neither does). Among every axis, cut plane and n1
// it takes the cut with the least expected work per shard in the heavier box (what bounds the
// wall time when every shard runs at once), ties to the lowest axis, then the lowest plane, then
// the lowest n1. Each shard gets at least one grid point.
//
// Deterministic: a plan depends on the job (scene, grid, settings) and N alone, never on the
// thread count or the machine (the placement traces the same rays everywhere: tracer_scene.h), so
// every shard of a cluster computes the same plan as the server or the user that split the job.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/scene/scene.h"

namespace probebake::runtime {

// The rays of a grid point's placement test (docs/job-format.md, `grid`: 128 rays).
inline constexpr int64_t kPlacementRays = 128;
// Most grid points the pre-pass places.
inline constexpr int64_t kMaxEstimatePoints = 32768;

// The pre-pass's result: the placement of a sub-lattice of the grid.
struct WorkEstimate {
  std::array<int, 3> stride{1, 1, 1};   // every stride[a]-th grid point along axis a is sampled
  std::array<int, 3> samples{1, 1, 1};  // sampled points per axis: ceil(counts / stride)
  // Per sampled point (x fastest, as ProbeGrid::LinearIndex): 1 when the placement bakes it.
  std::vector<uint8_t> active;
  int64_t samplesPerProbe = 0;  // the job's settings.samplesPerProbe
  double seconds = 0;           // wall time of the pre-pass

  bool Exact() const { return stride[0] == 1 && stride[1] == 1 && stride[2] == 1; }
};

// Runs the placement of `job` over its sub-lattice (probebake::Bake with one sample per probe,
// direct light only, order 0: the same placement as the real bake, which needs the tracer and
// the scene's lights built once). `threads`: as BakeOptions::threads. Errors: Bake's.
absl::StatusOr<WorkEstimate> EstimateWork(const BakeJob& job, int threads = 0);

// One shard: the box of grid points [first, first + counts) per axis.
struct ShardBox {
  std::array<int, 3> first{0, 0, 0};
  std::array<int, 3> counts{1, 1, 1};
  int64_t expectedProbes = 0;  // grid points the estimate expects the placement to bake
  int64_t expectedWork = 0;    // rays, as counted above

  int64_t GridPoints() const { return int64_t(counts[0]) * counts[1] * counts[2]; }
};

struct ShardPlan {
  std::array<int, 3> gridCounts{1, 1, 1};
  WorkEstimate estimate;         // `active` cleared
  std::vector<ShardBox> shards;  // shard i bakes shards[i]
  int64_t expectedProbes = 0;
  int64_t expectedWork = 0;

  // The heaviest shard's expected work over the mean (1: perfectly balanced).
  double Imbalance() const;
};

// Splits `grid` into `shards` boxes as above. INVALID_ARGUMENT "shards: ..." when shards < 1 or
// the grid has fewer points than shards. `estimate` must be EstimateWork's for a job on `grid`.
absl::StatusOr<ShardPlan> PlanShards(const ProbeGrid& grid, const WorkEstimate& estimate,
                                     int shards);

// EstimateWork, then PlanShards.
absl::StatusOr<ShardPlan> PlanShards(const BakeJob& job, int shards, int threads = 0);

// The sub-grid of `whole` that `box` covers: the same spacing, placement and surface distance,
// origin whole.origin + spacing * first (exactly whole.origin on an axis where first is 0, so the
// parts' merge keeps the whole grid's min bit for bit).
ProbeGrid ShardGrid(const ProbeGrid& whole, const ShardBox& box);

// Parses "I/N" (0 <= I < N, N >= 1) for `flag`'s messages: INVALID_ARGUMENT "<flag>: ...".
absl::Status ParseShardSpec(const std::string& text, const std::string& flag, int* index,
                            int* count);

// The plan as one JSON object (docs/cluster.md, `probebake plan --json`).
std::string ShardPlanJson(const ShardPlan& plan, const ProbeGrid& grid);
// The plan as a table for people.
std::string FormatShardPlan(const ShardPlan& plan, const ProbeGrid& grid);

}  // namespace probebake::runtime
