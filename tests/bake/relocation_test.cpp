// Relocation (core/src/bake/probe_relocation.h) and visibility moments
// (probebake/volume/visibility_map.h): probes inside or against geometry move out, never through
// a wall, and bake exactly as a probe placed where they went; the moments measure the distances
// the probe's rays travel.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "bake_test_util.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// A wall x in [0, 0.2] (a box, outward faces) under a sky and a sun, and a grey floor.
BakeJob WallScene(Vec3d probe) {
  BakeJob job = MakeJob(2, 512, probe);
  job.settings.batches = 4;
  job.settings.relocationMaxOffset = 0.4;
  job.scene.environment = {Environment::Kind::kUniform, {0.3, 0.4, 0.6}, nullptr};
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddBox(&job.scene, {0, -3, -3}, {0.2, 3, 3}, grey, /*inward=*/false);
  job.scene.lights.push_back(DirectionalLight{Normalize(Vec3d{-0.6, 0.2, -1}), {2, 2, 2}, 1.0});
  return job;
}

Vec3d OffsetOf(const ProbeVolume& v, int64_t probe) {
  return {v.offset[3 * probe], v.offset[3 * probe + 1], v.offset[3 * probe + 2]};
}

TEST(Relocation, AProbeOneCentimetreInsideAWallMovesOutAndBakesAsAProbePlacedThere) {
  const BakeJob job = WallScene({0.01, 0.3, 0.4});
  const ProbeVolume v = BakeOrDie(job);
  ASSERT_EQ(v.offset.size(), 3u);
  EXPECT_EQ(v.validity[0], 1.0f);
  const Vec3d offset = OffsetOf(v, 0);
  const Vec3d moved = job.grid.Position(0, 0, 0) + offset;
  // Out of the wall, by no more than the stated 0.4 spacing, and at least the clearance (0.1)
  // from it: on the side nearer the start (x < 0), the wall being 0.2 thick.
  EXPECT_LE(Length(offset), 0.4 + 1e-6);
  EXPECT_LT(moved.x, -0.1 + 1e-6);
  EXPECT_GT(MaxComponent(Abs(Vec3d(v.radiance[0][0], v.radiance[0][1], v.radiance[0][2]))), 0);

  BakeJob there = job;
  there.grid.origin = moved;
  const ProbeVolume w = BakeOrDie(there);
  EXPECT_EQ(OffsetOf(w, 0).x, 0.0);  // a free point stays
  EXPECT_EQ(w.validity[0], 1.0f);
  for (int c = 0; c < v.CoeffCount(); ++c)
    EXPECT_EQ(0, std::memcmp(v.radiance[c].data(), w.radiance[c].data(), 3 * sizeof(float)))
        << "coefficient " << c;
  EXPECT_EQ(v.stdError[0], w.stdError[0]);
}

TEST(Relocation, WithoutRelocationTheSameProbeIsInvalidAndBlack) {
  BakeJob job = WallScene({0.01, 0.3, 0.4});
  job.settings.relocationMaxOffset = 0;
  const ProbeVolume v = BakeOrDie(job);
  EXPECT_TRUE(v.offset.empty());
  EXPECT_EQ(v.validity[0], 0.0f);
}

TEST(Relocation, AProbeTooCloseToAThinWallMovesAwayAndNeverThroughIt) {
  // A wall 0.05 thick; probes 5 mm either side of it. Spacing 0.06 along x: R = 0.03 and the
  // clearance 0.0075, so both are too close and move, each on its own side.
  BakeJob job = MakeJob(1, 64, {-0.005, 0, 0});
  job.grid.counts[0] = 2;
  job.grid.spacing = {0.06, 1, 1};  // probes at x = -0.005 and 0.055
  job.settings.batches = 2;
  job.settings.relocationMaxOffset = 0.5;
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddBox(&job.scene, {0, -3, -3}, {0.05, 3, 3}, grey, /*inward=*/false);
  const ProbeVolume v = BakeOrDie(job);
  EXPECT_EQ(v.validity[0], 1.0f);
  EXPECT_EQ(v.validity[1], 1.0f);
  EXPECT_LT(OffsetOf(v, 0).x, 0.0);
  EXPECT_GT(OffsetOf(v, 1).x, 0.0);
  EXPECT_LE(job.grid.Position(0, 0, 0).x + OffsetOf(v, 0).x, -0.0075 + 1e-9);
  EXPECT_GE(job.grid.Position(1, 0, 0).x + OffsetOf(v, 1).x, 0.05 + 0.0075 - 1e-9);
}

TEST(Relocation, AProbeInsideAThinWallLeavesItOnOneSideOnly) {
  // A grid point inside a wall a tenth of the spacing thick leaves it; the move crosses one back
  // face and no front face, so it ends in free space on one side.
  BakeJob job = WallScene({0.1, 0.3, 0.4});
  job.scene.meshes.clear();
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddBox(&job.scene, {0.05, -3, -3}, {0.15, 3, 3}, grey, /*inward=*/false);
  const ProbeVolume v = BakeOrDie(job);
  EXPECT_EQ(v.validity[0], 1.0f);
  const double x = 0.1 + OffsetOf(v, 0).x;
  EXPECT_TRUE(x <= 0.05 - 0.1 + 1e-6 || x >= 0.15 + 0.1 - 1e-6) << x;
}

TEST(Relocation, AProbeDeepInsideASolidStaysInvalid) {
  BakeJob job = WallScene({0, 0, 0});
  job.scene.meshes.clear();
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddBox(&job.scene, {-2, -2, -2}, {2, 2, 2}, grey, /*inward=*/false);
  const ProbeVolume v = BakeOrDie(job);
  EXPECT_EQ(v.validity[0], 0.0f);
  EXPECT_EQ(OffsetOf(v, 0).x, 0.0);
  EXPECT_EQ(v.stats.invalidProbes, 1);
}

TEST(Visibility, MomentsMeasureTheInverseDistanceToAWall) {
  // A probe 0.3 in front of a large wall (the plane x = 0.3, facing -x) under a sky. Rays toward
  // +x hit it at 0.3 / cos(angle to +x), adding s = cos / 0.3; the others miss and add 0.
  BakeJob job = MakeJob(1, 4096, {0, 0, 0});
  job.settings.batches = 4;
  job.settings.visibility = true;
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddQuad(&job.scene, {0.3, -100, -100}, {0.3, -100, 100}, {0.3, 100, 100}, {0.3, 100, -100}, grey);
  const ProbeVolume v = BakeOrDie(job);
  ASSERT_EQ(v.visibility.size(), size_t(kVisibilityTexels));
  double rays = 0;
  for (int t = 0; t < kVisibilityTexels; ++t) rays += v.visibility[t][2];
  EXPECT_EQ(rays, 4096);
  // The texel around +x holds directions at most ~35 degrees from it: s in [cos 35deg, 1] / 0.3,
  // so its mean too; its mean square is at least the mean's square.
  const float* m = &v.visibility[VisibilityTexel({1, 0, 0})][0];
  EXPECT_LE(m[0], float(1 / 0.3) * (1 + 1e-6f));
  EXPECT_GE(m[0], float(std::cos(35 * kPi / 180) / 0.3));
  EXPECT_GE(m[1], m[0] * m[0] * (1 - 1e-6f));
  const float* away = &v.visibility[VisibilityTexel({-1, 0, 0})][0];
  EXPECT_EQ(away[0], 0.0f);
  EXPECT_EQ(away[1], 0.0f);
  EXPECT_GT(away[2], 0.0f);
}

}  // namespace
}  // namespace probebake
