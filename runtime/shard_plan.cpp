#include "runtime/shard_plan.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "probebake/bake/bake.h"
#include "probebake/base/status.h"

namespace probebake::runtime {
namespace {

using Counts = std::array<int, 3>;

int64_t CeilDiv(int64_t a, int64_t b) {
  return (a + b - 1) / b;
}

// A box of grid points [first, first + counts) per axis.
struct Box {
  Counts first{0, 0, 0};
  Counts counts{1, 1, 1};
  int64_t Points() const { return int64_t(counts[0]) * counts[1] * counts[2]; }
};

// The estimate seen per grid point: every point of a sampled point's block has its work.
class WorkField {
 public:
  WorkField(const Counts& gridCounts, const WorkEstimate& estimate)
      : grid_(gridCounts), e_(estimate) {}

  // Rays of one grid point of sampled point `s`'s block.
  int64_t PointWork(int64_t s) const {
    return kPlacementRays + (e_.active[s] ? e_.samplesPerProbe : 0);
  }

  // How many grid points of sampled point c's block along axis a lie in [first, first + count).
  int64_t Overlap(int a, int c, int first, int count) const {
    const int64_t lo = std::max<int64_t>(int64_t(c) * e_.stride[a], first);
    const int64_t hi = std::min<int64_t>(std::min<int64_t>(int64_t(c + 1) * e_.stride[a], grid_[a]),
                                         int64_t(first) + count);
    return std::max<int64_t>(0, hi - lo);
  }

  // The sampled points whose blocks meet [first, first + count) along axis a: [lo, hi).
  std::pair<int, int> Cells(int a, int first, int count) const {
    return {first / e_.stride[a], int(CeilDiv(int64_t(first) + count, e_.stride[a]))};
  }

  // Work of every plane of `box` across axis a, per plane (box.counts[a] entries).
  std::vector<double> PlaneWork(const Box& box, int a) const {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    const auto [aLo, aHi] = Cells(a, box.first[a], box.counts[a]);
    const auto [bLo, bHi] = Cells(b, box.first[b], box.counts[b]);
    const auto [cLo, cHi] = Cells(c, box.first[c], box.counts[c]);
    // Per sampled plane: the work of one grid plane of its block within the box.
    std::vector<int64_t> cellPlane(size_t(aHi - aLo), 0);
    for (int ia = aLo; ia < aHi; ++ia) {
      int64_t sum = 0;
      for (int ib = bLo; ib < bHi; ++ib) {
        const int64_t ob = Overlap(b, ib, box.first[b], box.counts[b]);
        for (int ic = cLo; ic < cHi; ++ic) {
          std::array<int, 3> at;
          at[a] = ia, at[b] = ib, at[c] = ic;
          sum += PointWork(Index(at)) * ob * Overlap(c, ic, box.first[c], box.counts[c]);
        }
      }
      cellPlane[size_t(ia - aLo)] = sum;
    }
    std::vector<double> planes(size_t(box.counts[a]));
    for (int p = 0; p < box.counts[a]; ++p)
      planes[size_t(p)] = double(cellPlane[size_t((box.first[a] + p) / e_.stride[a] - aLo)]);
    return planes;
  }

  // Expected probes and work of `box`.
  void Totals(const Box& box, int64_t* probes, int64_t* work) const {
    *probes = 0, *work = 0;
    const auto [xLo, xHi] = Cells(0, box.first[0], box.counts[0]);
    const auto [yLo, yHi] = Cells(1, box.first[1], box.counts[1]);
    const auto [zLo, zHi] = Cells(2, box.first[2], box.counts[2]);
    for (int z = zLo; z < zHi; ++z) {
      const int64_t oz = Overlap(2, z, box.first[2], box.counts[2]);
      for (int y = yLo; y < yHi; ++y) {
        const int64_t oyz = oz * Overlap(1, y, box.first[1], box.counts[1]);
        for (int x = xLo; x < xHi; ++x) {
          const int64_t points = oyz * Overlap(0, x, box.first[0], box.counts[0]);
          const int64_t s = Index({x, y, z});
          *probes += e_.active[s] ? points : 0;
          *work += PointWork(s) * points;
        }
      }
    }
  }

 private:
  int64_t Index(const std::array<int, 3>& at) const {
    return at[0] + int64_t(e_.samples[0]) * (at[1] + int64_t(e_.samples[1]) * at[2]);
  }

  Counts grid_;
  const WorkEstimate& e_;
};

// The best cut of `box` (n shards): axis, planes in the first box, shards in the first box.
struct Cut {
  int axis = -1, planes = 0, shards = 0;
  double cost = std::numeric_limits<double>::infinity();
};

// The cut of least cost with the first box's shard count taken from `candidates(planes)`.
template <typename Candidates>
Cut BestCut(const WorkField& field, const Box& box, int n, Candidates&& candidates) {
  Cut best;
  for (int a = 0; a < 3; ++a) {
    const int length = box.counts[a];
    if (length < 2) continue;
    const int64_t across = box.Points() / length;  // grid points per plane
    const std::vector<double> planes = field.PlaneWork(box, a);
    double total = 0;
    for (double w : planes) total += w;
    double left = 0;
    for (int c = 1; c < length; ++c) {
      left += planes[size_t(c - 1)];
      const double right = total - left;
      for (int n1 : candidates(c)) {
        const int n2 = n - n1;
        if (n1 < 1 || n2 < 1 || int64_t(c) * across < n1 || int64_t(length - c) * across < n2)
          continue;
        const double cost = std::max(left / n1, right / n2);
        if (cost < best.cost) best = {a, c, n1, cost};
      }
    }
  }
  return best;
}

void Split(const WorkField& field, const Box& box, int n, std::vector<Box>* out) {
  if (n == 1) {
    out->push_back(box);
    return;
  }
  Cut cut = BestCut(field, box, n, [n](int) { return std::array<int, 2>{n / 2, n - n / 2}; });
  if (cut.axis < 0) {
    // Too few grid points for halves on any axis: any split that leaves each box a point per
    // shard. The box holds at least n points, so one exists.
    cut = BestCut(field, box, n, [n](int) {
      std::vector<int> all;
      for (int n1 = 1; n1 < n; ++n1) all.push_back(n1);
      return all;
    });
  }
  Box first = box, second = box;
  first.counts[cut.axis] = cut.planes;
  second.first[cut.axis] += cut.planes;
  second.counts[cut.axis] -= cut.planes;
  Split(field, first, cut.shards, out);
  Split(field, second, n - cut.shards, out);
}

std::string Triple(const Counts& v) {
  return absl::StrCat("[", v[0], ",", v[1], ",", v[2], "]");
}

std::string Triple(const Vec3d& v) {
  return absl::StrFormat("[%.17g,%.17g,%.17g]", v.x, v.y, v.z);
}

}  // namespace

double ShardPlan::Imbalance() const {
  if (shards.empty() || expectedWork <= 0) return 1;
  int64_t heaviest = 0;
  for (const ShardBox& s : shards) heaviest = std::max(heaviest, s.expectedWork);
  return double(heaviest) * double(shards.size()) / double(expectedWork);
}

absl::StatusOr<WorkEstimate> EstimateWork(const BakeJob& job, int threads) {
  const auto start = std::chrono::steady_clock::now();
  WorkEstimate estimate;
  estimate.samplesPerProbe = job.settings.samplesPerProbe;
  const int* counts = job.grid.counts;
  auto sampled = [&](int stride) {
    return CeilDiv(counts[0], stride) * CeilDiv(counts[1], stride) * CeilDiv(counts[2], stride);
  };
  int stride = std::max(1, int(std::cbrt(double(job.grid.ProbeCount()) / kMaxEstimatePoints)));
  while (stride > 1 && sampled(stride - 1) <= kMaxEstimatePoints) --stride;
  while (sampled(stride) > kMaxEstimatePoints) ++stride;

  BakeJob lattice = job;
  for (int a = 0; a < 3; ++a) {
    estimate.stride[a] = stride;
    estimate.samples[a] = int(CeilDiv(counts[a], stride));
    lattice.grid.counts[a] = estimate.samples[a];
    lattice.grid.spacing[a] = job.grid.spacing[a] * stride;
  }
  // What the placement reads (seed, backfaceFraction, the grid's placement) is kept; what only
  // the baking of a probe reads is cut to its least.
  BakeSettings& s = lattice.settings;
  s.samplesPerProbe = 1;
  s.batches = 1;
  s.maxDepth = 1;
  s.shOrder = 0;
  s.irradiance = false;
  s.window = ShWindow::kNone;
  s.targetRelError = 0;
  BakeOptions options;
  options.threads = threads;
  options.lightVisibility = false;
  PB_ASSIGN_OR_RETURN(ProbeVolume placed, Bake(lattice, options));
  estimate.active = std::move(placed.active);
  estimate.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return estimate;
}

absl::StatusOr<ShardPlan> PlanShards(const ProbeGrid& grid, const WorkEstimate& estimate,
                                     int shards) {
  if (shards < 1) return FieldError("shards", absl::StrCat("must be >= 1, got ", shards));
  if (grid.ProbeCount() < shards)
    return FieldError("shards", absl::StrCat(shards, " shards for a grid of ", grid.ProbeCount(),
                                             " points: at most one shard per grid point"));
  ShardPlan plan;
  const Counts gridCounts{grid.counts[0], grid.counts[1], grid.counts[2]};
  plan.gridCounts = gridCounts;
  const WorkField field(gridCounts, estimate);
  Box whole;
  whole.counts = gridCounts;
  std::vector<Box> boxes;
  Split(field, whole, shards, &boxes);
  for (const Box& box : boxes) {
    ShardBox s;
    s.first = box.first;
    s.counts = box.counts;
    field.Totals(box, &s.expectedProbes, &s.expectedWork);
    plan.expectedProbes += s.expectedProbes;
    plan.expectedWork += s.expectedWork;
    plan.shards.push_back(s);
  }
  plan.estimate = estimate;
  plan.estimate.active.clear();
  return plan;
}

absl::StatusOr<ShardPlan> PlanShards(const BakeJob& job, int shards, int threads) {
  if (shards < 1) return FieldError("shards", absl::StrCat("must be >= 1, got ", shards));
  PB_ASSIGN_OR_RETURN(const WorkEstimate estimate, EstimateWork(job, threads));
  return PlanShards(job.grid, estimate, shards);
}

ProbeGrid ShardGrid(const ProbeGrid& whole, const ShardBox& box) {
  ProbeGrid grid = whole;
  for (int a = 0; a < 3; ++a) {
    grid.counts[a] = box.counts[a];
    // Adding 0 would turn a min of -0 into +0.
    if (box.first[a] != 0) grid.origin[a] = whole.origin[a] + whole.spacing[a] * box.first[a];
  }
  return grid;
}

absl::Status ParseShardSpec(const std::string& text, const std::string& flag, int* index,
                            int* count) {
  const std::vector<std::string> parts = absl::StrSplit(text, '/');
  int i = 0, n = 0;
  if (parts.size() != 2 || !absl::SimpleAtoi(parts[0], &i) || !absl::SimpleAtoi(parts[1], &n))
    return FieldError(flag,
                      absl::StrCat("expected I/N (shard I of N, from 0), got \"", text, "\""));
  if (n < 1) return FieldError(flag, absl::StrCat("N must be >= 1, got ", n));
  if (i < 0 || i >= n)
    return FieldError(flag, absl::StrCat("I must be in [0, ", n - 1, "], got ", i));
  *index = i;
  *count = n;
  return absl::OkStatus();
}

std::string ShardPlanJson(const ShardPlan& plan, const ProbeGrid& grid) {
  std::string json = absl::StrCat(
      "{\"shards\":", plan.shards.size(), ",\"gridCounts\":", Triple(plan.gridCounts),
      ",\"gridPoints\":", grid.ProbeCount(), ",\"expectedProbes\":", plan.expectedProbes,
      ",\"expectedWork\":", plan.expectedWork,
      absl::StrFormat(",\"imbalance\":%.6g", plan.Imbalance()),
      ",\"estimate\":{\"stride\":", Triple(plan.estimate.stride), ",\"points\":",
      int64_t(plan.estimate.samples[0]) * plan.estimate.samples[1] * plan.estimate.samples[2],
      ",\"exact\":", plan.estimate.Exact() ? "true" : "false",
      absl::StrFormat(",\"seconds\":%.6g", plan.estimate.seconds), "},\"parts\":[");
  for (size_t i = 0; i < plan.shards.size(); ++i) {
    const ShardBox& s = plan.shards[i];
    const ProbeGrid sub = ShardGrid(grid, s);
    absl::StrAppend(&json, i ? "," : "", "{\"shard\":", i, ",\"first\":", Triple(s.first),
                    ",\"counts\":", Triple(s.counts), ",\"min\":", Triple(sub.origin),
                    ",\"gridPoints\":", s.GridPoints(), ",\"expectedProbes\":", s.expectedProbes,
                    ",\"expectedWork\":", s.expectedWork, "}");
  }
  absl::StrAppend(&json, "]}");
  return json;
}

std::string FormatShardPlan(const ShardPlan& plan, const ProbeGrid& grid) {
  std::string text = absl::StrFormat(
      "%d shards of a %d x %d x %d grid (%d points), %d probes expected, imbalance %.3f\n"
      "estimate: %s (stride %d, %.2f s)\n"
      "shard  first            counts           points   probes  work share\n",
      plan.shards.size(), plan.gridCounts[0], plan.gridCounts[1], plan.gridCounts[2],
      grid.ProbeCount(), plan.expectedProbes, plan.Imbalance(),
      plan.estimate.Exact() ? "every grid point placed" : "a sub-lattice placed",
      plan.estimate.stride[0], plan.estimate.seconds);
  for (size_t i = 0; i < plan.shards.size(); ++i) {
    const ShardBox& s = plan.shards[i];
    absl::StrAppendFormat(
        &text, "%5d  %-15s  %-15s  %7d  %7d  %9.4f\n", i,
        absl::StrFormat("%d %d %d", s.first[0], s.first[1], s.first[2]),
        absl::StrFormat("%d %d %d", s.counts[0], s.counts[1], s.counts[2]), s.GridPoints(),
        s.expectedProbes,
        plan.expectedWork > 0 ? double(s.expectedWork) / double(plan.expectedWork) : 0.0);
  }
  return text;
}

}  // namespace probebake::runtime
