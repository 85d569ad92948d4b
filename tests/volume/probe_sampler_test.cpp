// The reference sampler (probebake/volume/probe_sampler.h) on baked volumes: light does not leak
// through a thin wall, relocation and visibility doing what plain trilinear interpolation cannot.
#include "probebake/volume/probe_sampler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "bake/bake_test_util.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/volume/sample_points.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {
namespace {

using namespace probebake::testing;

constexpr double kSpacing = 0.5;
constexpr double kWall = 0.04;  // thinner than a tenth of the spacing

// Two closed rooms, x in [-2, 0] (lit by a point light) and [kWall, 2] (dark), divided by a wall
// x in [0, kWall] that pokes through the shell, so no ray passes round it. The probe layers sit at
// x = firstX + kSpacing i.
BakeJob TwoRooms(double firstX) {
  BakeJob job = MakeJob(2, 512, {firstX, -0.75, 0.25});
  job.grid.counts[0] = 8;
  job.grid.counts[1] = 4;
  job.grid.counts[2] = 4;
  job.grid.spacing = {kSpacing, kSpacing, kSpacing};
  job.settings.batches = 4;
  job.settings.maxDepth = 4;
  job.settings.visibility = true;
  job.settings.relocationMaxOffset = 0.4;
  const uint32_t white = AddMaterial(&job.scene, {0.7, 0.7, 0.7});
  AddBox(&job.scene, {-2, -1, 0}, {2, 1, 2}, white, /*inward=*/true);
  AddBox(&job.scene, {0, -1.01, -0.01}, {kWall, 1.01, 2.01}, white, /*inward=*/false);
  job.scene.lights.push_back(PointLight{{-1, 0, 1.2}, {4, 4, 4}});
  return job;
}

double Luminance(const Vec3d& e) {
  return 0.2126 * e.x + 0.7152 * e.y + 0.0722 * e.z;
}

// The largest dark-room irradiance over the lit room's mean, per kind of normal.
struct Leak {
  double worst = 0;   // over every point
  double away = 0;    // normals pointing away from the wall, into the dark room
  double facing = 0;  // normals facing the wall
  double up = 0;      // floor-like points, down to the floor at the wall's foot
  double side = 0;    // normals along the wall (+-y, -z)
  double litMean = 0;
};

// Irradiance at points of the dark room within a quarter spacing of the wall (distances 0.04 to
// 0.25 spacings), with normals away from the wall, toward it, up (floor points, down to the
// floor's surface at the wall's foot) and sideways, against the lit room's at the mirrored points.
Leak MeasureLeak(const ProbeVolume& volume, const ProbeSamplerOptions& options) {
  const ProbeSampler sampler(volume, options);
  const Vec3d normals[] = {{1, 0, 0}, {-1, 0, 0}, {0, 0, 1}, {0, 1, 0}, {0, -1, 0}, {0, 0, -1}};
  double litSum = 0;
  int litCount = 0;
  Leak leak;
  for (double delta : {0.02, 0.05, 0.09, 0.125}) {
    for (double y : {-0.6, -0.1, 0.35}) {
      for (double z : {0.0, 0.05, 0.3, 0.9, 1.6}) {
        for (const Vec3d& n : normals) {
          if (z == 0 && n.z != 1) continue;  // on the floor: facing up only
          const Vec3d dark{kWall + delta, y, z};
          const Vec3d lit{-delta, y, z};
          const Vec3d mirrored{-n.x, n.y, n.z};
          const double e = Luminance(sampler.Sample(dark, n).irradiance);
          double& kind = n.x > 0   ? leak.away
                         : n.x < 0 ? leak.facing
                         : n.z > 0 ? leak.up
                                   : leak.side;
          kind = std::max(kind, e);
          leak.worst = std::max(leak.worst, e);
          litSum += Luminance(sampler.Sample(lit, mirrored).irradiance);
          ++litCount;
        }
      }
    }
  }
  leak.litMean = litSum / litCount;
  for (double* x : {&leak.worst, &leak.away, &leak.facing, &leak.up, &leak.side})
    *x /= leak.litMean;
  return leak;
}

// The issue's criterion: below 2% everywhere. Returns the figures (printed) so that callers can
// state what holds.
Leak MeasureTwoRooms(double firstX, Leak* trilinearOut = nullptr) {
  const BakeJob job = TwoRooms(firstX);
  const ProbeVolume volume = BakeOrDie(job);
  const Leak with = MeasureLeak(volume, {});
  ProbeSamplerOptions plain;
  plain.visibility = false;
  plain.backfaceWeight = false;
  plain.normalBias = 0;
  const Leak trilinear = MeasureLeak(volume, plain);
  std::printf(
      "probe layers from x = %g: dark/lit irradiance with visibility %.4f%% (normals "
      "away %.4f%%, facing the wall %.4f%%, up %.4f%%, along %.4f%%); plain trilinear "
      "%.2f%%\n",
      firstX, 100 * with.worst, 100 * with.away, 100 * with.facing, 100 * with.up, 100 * with.side,
      100 * trilinear.worst);
  EXPECT_GT(with.litMean, 0);
  if (trilinearOut) *trilinearOut = trilinear;
  return with;
}

// NOT MET YET (issue 32): disabled until it holds. Measured with this sampler (nearest texel, 8x8
// moments, 512 samples, normal bias 0.05 spacing), worst dark/lit ratio: straddling probes 105%
// (normals away from the wall 3.7%, facing it 105%, up 34%), a layer inside the wall (relocated
// to the lit side) 159%, 1 cm behind it 160%, 1 cm in front 0%; plain trilinear 111%, 150%,
// 143%, 0%. The texel's mean depth, over a ~25 degree footprint, does not resolve a point 2 to
// 12 cm beyond a wall: see README, "Light leaks".
void ExpectNoLeak(double firstX) {
  const Leak with = MeasureTwoRooms(firstX);
  EXPECT_LT(with.worst, 0.02);
}

TEST(Leak, DISABLED_ProbesStraddlingAThinWall) {
  ExpectNoLeak(-1.75);
}

TEST(Leak, DISABLED_AProbeLayerInsideAThinWall) {
  // Layers at x = 0.02, inside the wall: relocation moves them out, never through it.
  ExpectNoLeak(-1.98);
}

TEST(Leak, DISABLED_AProbeLayerJustInFrontOfAThinWall) {
  // Layers 1 cm from the wall on the dark side (x = 0.05) and on the lit side (x = -0.01 in the
  // next test): relocation keeps them on their side, clear of it.
  ExpectNoLeak(-1.95);
}

TEST(Leak, DISABLED_AProbeLayerJustBehindAThinWall) {
  ExpectNoLeak(-1.51);
}

// The irradiance probe p of `volume` gives a surface facing n: sum_i A_l c_i Y_i(n).
Vec3d ProbeIrradiance(const ProbeVolume& volume, int64_t p, const Vec3d& n) {
  std::vector<double> y(size_t(volume.CoeffCount()));
  EvalShBasis<double>(volume.shOrder, Normalize(n), y.data());
  Vec3d e{0, 0, 0};
  for (int l = 0, i = 0; l <= volume.shOrder; ++l)
    for (int m = -l; m <= l; ++m, ++i)
      for (int ch = 0; ch < 3; ++ch)
        e[ch] += IrradianceBandFactor(l) * volume.radiance[size_t(i)][3 * size_t(p) + size_t(ch)] *
                 y[size_t(i)];
  return e;
}

TEST(Sampler, AtAProbeItReadsThatProbeAndBetweenProbesABlendOfThem) {
  BakeJob job = MakeJob(2, 64, {0, 0, 0});
  job.grid.counts[0] = job.grid.counts[1] = job.grid.counts[2] = 2;
  job.settings.batches = 2;
  job.settings.visibility = true;
  job.scene.environment = {Environment::Kind::kUniform, {0.5, 1, 2}, nullptr};
  const ProbeVolume volume = BakeOrDie(job);
  ProbeSamplerOptions noBias;
  noBias.normalBias = 0;
  const ProbeSampler sampler(volume, noBias);
  const Vec3d n{0.2, -1, 0.4};
  for (int64_t p : {0, 7}) {
    int i, j, k;
    job.grid.Coords(p, &i, &j, &k);
    const ProbeSample s = sampler.Sample(job.grid.Position(i, j, k), n);
    EXPECT_EQ(s.probes, 1);
    const Vec3d e = ProbeIrradiance(volume, p, n);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(s.irradiance[ch], e[ch], 1e-6 * e[ch]);
  }
  const ProbeSample mid = ProbeSampler(volume).Sample({0.3, 0.6, 0.2}, n);
  EXPECT_EQ(mid.probes, 8);
  double lo = 1e30, hi = 0;
  for (int64_t p = 0; p < 8; ++p) {
    lo = std::min(lo, ProbeIrradiance(volume, p, n).z);
    hi = std::max(hi, ProbeIrradiance(volume, p, n).z);
  }
  EXPECT_GE(mid.irradiance.z, lo * (1 - 1e-9));
  EXPECT_LE(mid.irradiance.z, hi * (1 + 1e-9));
}

TEST(SamplePoints, ParsesPointsAndNamesTheBadField) {
  const auto ok = ParseSamplePoints(R"([{"position": [1, 2, 3], "normal": [0, 0, 2]}])");
  ASSERT_TRUE(ok.ok()) << ok.status();
  ASSERT_EQ(ok->size(), 1u);
  EXPECT_EQ((*ok)[0].position.y, 2);
  const auto missing = ParseSamplePoints(R"([{"position": [1, 2, 3]}])");
  EXPECT_EQ(missing.status().message(), "points[0].normal: missing");
  const auto zero = ParseSamplePoints(R"([{"position": [1, 2, 3], "normal": [0, 0, 0]}])");
  EXPECT_EQ(zero.status().message(), "points[0].normal: must be non-zero");
  const auto shortVec = ParseSamplePoints(
      R"([{"position": [0, 0, 0], "normal": [0, 0, 1]}, {"position": [1, 2], "normal": [0, 0, 1]}])");
  EXPECT_EQ(shortVec.status().message(), "points[1].position: must be an array of 3 numbers");
  const auto unknown =
      ParseSamplePoints(R"([{"position": [1, 2, 3], "normal": [0, 0, 1], "colour": 1}])");
  EXPECT_EQ(unknown.status().message(), "points[0].colour: unknown field");
  EXPECT_FALSE(ParseSamplePoints(R"({"position": [1, 2, 3]})").ok());
}

}  // namespace
}  // namespace probebake
