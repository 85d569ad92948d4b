// Dilation (probebake/bake/probe_dilation.h): probes relocation could not move out of a solid get
// their neighbours' light, flagged filled, and sharded bakes still merge into the whole grid's
// bits.
#include "probebake/bake/probe_dilation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>

#include "bake/bake_test_util.h"
#include "probebake/volume/probe_sampler.h"
#include "probebake/volume/volume_merge.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// A 1.6 m solid cube under a uniform sky, a grid of spacing 0.4 through it: relocation moves
// probes at most 0.4 * 0.4 = 0.16, so the grid points deeper than that inside stay invalid.
BakeJob CubeUnderSky(bool visibility) {
  BakeJob job = MakeJob(2, 128, {-1.2, -1.2, -1.2});
  job.grid.counts[0] = job.grid.counts[1] = job.grid.counts[2] = 7;
  job.grid.spacing = {0.4, 0.4, 0.4};
  job.settings.batches = 2;
  job.settings.maxDepth = 2;
  job.settings.irradiance = true;
  job.settings.visibility = visibility;
  job.settings.relocationMaxOffset = 0.4;
  job.scene.environment = {Environment::Kind::kUniform, {0.4, 0.6, 1.0}, nullptr};
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddBox(&job.scene, {-0.8, -0.8, -0.8}, {0.8, 0.8, 0.8}, grey, /*inward=*/false);
  return job;
}

double L0Luminance(const ProbeVolume& v, int64_t p) {
  const float* c = &v.radiance[0][3 * size_t(p)];
  return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
}

TEST(Dilation, ProbesLeftInsideASolidAreFilledFromTheirNeighbours) {
  for (bool visibility : {false, true}) {
    const BakeJob job = CubeUnderSky(visibility);
    const ProbeVolume v = BakeOrDie(job);
    ASSERT_EQ(v.filled.size(), v.active.size());
    int filled = 0, read = 0;
    for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
      const bool isFilled = v.filled[p] == 1.0f;
      EXPECT_TRUE(isFilled || v.filled[p] == 0.0f) << p;
      // Only probes left invalid are filled, and every one of them is (the solid is 4 spacings
      // wide, so none is farther than 2 lattice steps from a valid probe).
      EXPECT_EQ(isFilled, v.validity[p] == 0.0f) << "probe " << p;
      filled += isFilled;
      // The sky lights every point outside the cube: no probe the sampler reads is black.
      if (v.active[p] && (v.validity[p] == 1.0f || isFilled)) {
        ++read;
        EXPECT_GT(L0Luminance(v, p), 0) << "probe " << p << (isFilled ? " (filled)" : "");
      }
    }
    EXPECT_GE(filled, 8) << "the cube's inner grid points (at least 2 x 2 x 2) were not filled";
    EXPECT_EQ(read, job.grid.ProbeCount());
    EXPECT_EQ(v.stats.invalidProbes, filled);  // still counted as invalid: measured nowhere
    // A filled probe's L0 is a convex blend of its sources: within their range.
    for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
      if (v.filled[p] != 1.0f) continue;
      int i, j, k;
      job.grid.Coords(p, &i, &j, &k);
      double lo = 1e30, hi = -1e30;
      for (int dk = -1; dk <= 1; ++dk)
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            const int64_t q = job.grid.LinearIndex(i + di, j + dj, k + dk);
            if (q == p) continue;
            lo = std::min(lo, L0Luminance(v, q));
            hi = std::max(hi, L0Luminance(v, q));
          }
      EXPECT_GE(L0Luminance(v, p), lo * (1 - 1e-6)) << "probe " << p;
      EXPECT_LE(L0Luminance(v, p), hi * (1 + 1e-6)) << "probe " << p;
    }
  }
}

TEST(Dilation, ShardsMergeIntoTheWholeGridsBits) {
  // Split through the cube's middle: a filled probe at the split has sources in both parts.
  const BakeJob whole = CubeUnderSky(/*visibility=*/true);
  const ProbeVolume all = BakeOrDie(whole);
  std::vector<VolumePart> parts;
  int differing = 0;
  for (int part = 0; part < 2; ++part) {
    BakeJob job = whole;
    job.grid.counts[0] = part == 0 ? 4 : 3;
    job.grid.origin.x = whole.grid.Position(part == 0 ? 0 : 4, 0, 0).x;
    ProbeVolumeFile file;
    file.volume = BakeOrDie(job);
    for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
      int i, j, k;
      job.grid.Coords(p, &i, &j, &k);
      const int64_t w = whole.grid.LinearIndex(i + (part == 0 ? 0 : 4), j, k);
      differing += file.volume.radiance[0][3 * p] != all.radiance[0][3 * w];
    }
    parts.push_back({"part" + std::to_string(part), std::move(file)});
  }
  // The parts alone fill the probes at the split differently (from one side only).
  EXPECT_GT(differing, 0) << "the split did not exercise dilation across parts";
  const absl::StatusOr<ProbeVolumeFile> merged = MergeProbeVolumes(std::move(parts));
  ASSERT_TRUE(merged.ok()) << merged.status();
  const ProbeVolume& m = merged->volume;
  ASSERT_EQ(m.active.size(), all.active.size());
  EXPECT_EQ(m.filled, all.filled);
  for (size_t c = 0; c < all.radiance.size(); ++c) {
    EXPECT_EQ(0, std::memcmp(m.radiance[c].data(), all.radiance[c].data(),
                             all.radiance[c].size() * sizeof(float)))
        << "radiance coefficient " << c;
    EXPECT_EQ(0, std::memcmp(m.irradiance[c].data(), all.irradiance[c].data(),
                             all.irradiance[c].size() * sizeof(float)))
        << "irradiance coefficient " << c;
  }
}

TEST(Dilation, WithoutRelocationNothingIsFilledAndNoFlagsAreStored) {
  BakeJob job = CubeUnderSky(/*visibility=*/false);
  job.settings.relocationMaxOffset = 0;
  const ProbeVolume v = BakeOrDie(job);
  EXPECT_TRUE(v.filled.empty());
}

}  // namespace
}  // namespace probebake
