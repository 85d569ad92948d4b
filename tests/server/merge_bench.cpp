// What the merge of a sharded bake costs per million probes (docs/cluster.md): synthetic parts of
// an order-2 volume with irradiance (the demo's planes), slabs tiling an n x n x n grid, written
// to files; then what probebake-server's Slurm backend and `probebake merge` do with them: read
// every part, merge, write the merged volume. Wall time of one run per size (not in ctest):
//   probebake_merge_bench [n ...]   (default: 100, 126 and 159: 1, 2 and 4 million probes)
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "probebake/volume/vdb_io.h"
#include "probebake/volume/volume_merge.h"
#include "volume/test_volumes.h"

namespace probebake {
namespace {

using Clock = std::chrono::steady_clock;
constexpr int kParts = 8;

double Since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

int Run(int n) {
  testing::TempDir dir;
  const VolumeMetadata meta = testing::MakeTestMetadata();
  std::vector<std::string> paths;
  const Vec3d origin{-3.5, -1.0, -10.25}, spacing{0.5, 1.25, 2.0};
  for (int p = 0, z = 0; p < kParts; ++p) {
    const int slab = (n - z) / (kParts - p);
    testing::TestVolumeSpec spec;
    spec.counts[0] = n;
    spec.counts[1] = n;
    spec.counts[2] = slab;
    spec.origin = {origin.x, origin.y, z == 0 ? origin.z : origin.z + spacing.z * z};
    spec.spacing = spacing;
    spec.irradiance = true;
    spec.awkwardValues = false;
    spec.seed = uint64_t(p + 1);
    paths.push_back(dir.File("part-" + std::to_string(p) + ".vdb"));
    if (!WriteProbeVolume(paths.back(), testing::MakeTestVolume(spec), meta).ok()) return 1;
    z += slab;
  }
  const auto start = Clock::now();
  std::vector<VolumePart> parts;
  for (const std::string& path : paths) {
    absl::StatusOr<ProbeVolumeFile> file = ReadProbeVolume(path);
    if (!file.ok()) return std::fprintf(stderr, "%s\n", file.status().ToString().c_str()), 1;
    parts.push_back({path, std::move(*file)});
  }
  const double read = Since(start);
  const auto mergeStart = Clock::now();
  absl::StatusOr<ProbeVolumeFile> merged = MergeProbeVolumes(std::move(parts));
  if (!merged.ok()) return std::fprintf(stderr, "%s\n", merged.status().ToString().c_str()), 1;
  const double merge = Since(mergeStart);
  const auto writeStart = Clock::now();
  if (!WriteProbeVolume(dir.File("merged.vdb"), std::move(merged->volume), merged->meta).ok())
    return 1;
  const double write = Since(writeStart), total = Since(start);
  const double millions = double(n) * n * n / 1e6;
  std::printf(
      "%d^3 = %.2f M grid points (%lld active) in %d parts: read %.2f s, merge %.2f s, write "
      "%.2f s, total %.2f s = %.2f s per million grid points\n",
      n, millions, (long long)merged->volume.stats.probes, kParts, read, merge, write, total,
      total / millions);
  return 0;
}

}  // namespace
}  // namespace probebake

int main(int argc, char** argv) {
  std::vector<int> sizes;
  for (int i = 1; i < argc; ++i) sizes.push_back(std::atoi(argv[i]));
  if (sizes.empty()) sizes = {100, 126, 159};
  for (int n : sizes)
    if (int code = probebake::Run(n); code != 0) return code;
  return 0;
}
