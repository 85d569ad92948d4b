// The reference sampler (probebake/volume/probe_sampler.h) on baked volumes: light does not leak
// through a thin wall, relocation and visibility doing what plain trilinear interpolation cannot.
#include "probebake/volume/probe_sampler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>

#include "bake/bake_test_util.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/volume/sample_points.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {
namespace {

using namespace probebake::testing;

constexpr double kSpacing = kTwoRoomsSpacing;
constexpr double kWall = kTwoRoomsWall;

double Luminance(const Vec3d& e) {
  return 0.2126 * e.x + 0.7152 * e.y + 0.0722 * e.z;
}

// The distances from the wall's dark face of the points MeasureLeak looks at: 2 cm to a quarter
// spacing.
constexpr double kDeltas[] = {0.02, 0.05, 0.09, 0.125};
constexpr int kDeltaCount = 4;

// The largest dark-room irradiance over the lit room's mean, by distance from the wall.
struct Leak {
  double worst[kDeltaCount] = {};  // at kDeltas[i], over every point and normal
  double litMean = 0;
  double litLeast = 0;  // the darkest lit-room point over the lit room's mean
  double Worst() const { return *std::max_element(worst, worst + kDeltaCount); }
};

// Irradiance at points of the dark room within a quarter spacing of the wall (kDeltas), on a
// lattice of `step` (5 cm by default) over the wall's height and width (down to the floor and up
// to the ceiling), each facing 26 directions (the axes, the cube's edge and corner diagonals;
// floor points facing up only), against the lit room's at the mirrored points.
Leak MeasureLeak(const ProbeVolume& volume, const ProbeSamplerOptions& options, int step = 1) {
  const ProbeSampler sampler(volume, options);
  const std::vector<Vec3d> normals = CubeDirections();
  double litSum = 0, litLeast = 0;
  int64_t litCount = 0;
  Leak leak;
  for (int i = 0; i < kDeltaCount; ++i) {
    const double delta = kDeltas[i];
    for (int iy = 0; iy <= 38; iy += step) {
      const double y = -0.95 + 0.05 * iy;
      for (int iz = 0; iz <= 40; iz += step) {
        const double z = std::min(0.05 * iz, 1.99);
        for (const Vec3d& n : normals) {
          if (z == 0 && !(n.z == 1)) continue;  // on the floor: facing up only
          const Vec3d dark{kWall + delta, y, z};
          const Vec3d lit{-delta, y, z};
          const Vec3d mirrored{-n.x, n.y, n.z};
          leak.worst[i] = std::max(leak.worst[i], Luminance(sampler.Sample(dark, n).irradiance));
          const double e = Luminance(sampler.Sample(lit, mirrored).irradiance);
          litLeast = litCount ? std::min(litLeast, e) : e;
          litSum += e;
          ++litCount;
        }
      }
    }
  }
  leak.litMean = litSum / double(litCount);
  leak.litLeast = litLeast / leak.litMean;
  for (double& w : leak.worst) w /= leak.litMean;
  return leak;
}

std::string Figures(const Leak& leak) {
  std::string out;
  char buffer[64];
  for (int i = 0; i < kDeltaCount; ++i) {
    std::snprintf(buffer, sizeof buffer, "%s%.1f cm %.4f%%", i ? ", " : "", 100 * kDeltas[i],
                  100 * leak.worst[i]);
    out += buffer;
  }
  return out;
}

// The issue's criterion: dark/lit irradiance below 2% with the sampler's defaults at every
// point within a quarter spacing of the wall. Printed beside it: Chebyshev visibility without
// the cell's connectivity (DDGI's weights) and plain trilinear interpolation (the issue asks for
// the latter's figure; where a layer lies against the wall on the dark side it leaks nothing).
// The lit room must stay lit (its mean, and its darkest point against Chebyshev alone's), so a
// sampler that darkens everything cannot pass.
void ExpectNoLeak(double firstX) {
  const BakeJob job = TwoRoomsWithThinWall(firstX);
  const ProbeVolume volume = BakeOrDie(job);
  const Leak with = MeasureLeak(volume, {});
  ProbeSamplerOptions chebyshevOnly;
  chebyshevOnly.connectivity = false;
  const Leak ddgi = MeasureLeak(volume, chebyshevOnly);
  ProbeSamplerOptions plain;
  plain.visibility = false;
  plain.backfaceWeight = false;
  plain.normalBias = 0;
  const Leak trilinear = MeasureLeak(volume, plain);
  std::printf(
      "probe layers from x = %g, worst dark/lit irradiance by distance behind the wall:\n"
      "  defaults (visibility and connectivity): %s\n  visibility without connectivity: %s\n"
      "  plain trilinear: %s\n  darkest lit point / lit mean: %.3g, %.3g, %.3g\n",
      firstX, Figures(with).c_str(), Figures(ddgi).c_str(), Figures(trilinear).c_str(),
      with.litLeast, ddgi.litLeast, trilinear.litLeast);
  ASSERT_GT(with.litMean, 0);
  // Visibility must not darken the lit room: its mean stays within 5% of plain trilinear's or
  // above it (trilinear loses light into the dark room).
  EXPECT_GT(with.litMean, 0.95 * trilinear.litMean);
  // Nor may the connectivity black out a lit point that Chebyshev alone lights: where every
  // probe sees the point poorly (a corner of wall and ceiling beyond the grid's last layer) the
  // two sides' support is alike and both count.
  EXPECT_GE(with.litLeast, 0.5 * ddgi.litLeast);
  for (int i = 0; i < kDeltaCount; ++i)
    EXPECT_LT(with.worst[i], 0.02) << kDeltas[i] << " m behind the wall";
}

// Measured (512 samples): 0.0000% at every distance with the defaults; Chebyshev alone 87%,
// 11%, 0.008%, 0%; plain trilinear 132%, 111%, 83%, 59% (README, "Light leaks"). Chebyshev alone
// fails at 2 cm for points facing the wall: their backface weight favours the lit probes, which
// see them at a grazing angle through the wall, in a texel whose spread of 1/t leaves the bound
// about 0.5. The cell's edges across the wall are blocked, and each probe with a blocked edge
// claims only the points before the wall along it, so the dark probes alone claim these.
TEST(Leak, ProbesStraddlingAThinWall) {
  ExpectNoLeak(-1.75);
}

TEST(Leak, AProbeLayerInsideAThinWall) {
  // Layers at x = 0.02, inside the wall: relocation moves them out, never through it.
  ExpectNoLeak(-1.98);
}

TEST(Leak, AProbeLayerJustInFrontOfAThinWall) {
  // Layers 1 cm from the wall on the dark side (x = 0.05): relocation keeps them on their side.
  ExpectNoLeak(-1.95);
}

// Layers 1 cm in front of the wall on the lit side (x = -0.01, relocated away from it) and 0.49
// behind it.
TEST(Leak, AProbeLayerJustBehindAThinWall) {
  ExpectNoLeak(-1.51);
}

// The wall at every place between two probe layers, from 1 cm behind the lit layer to 1 cm in
// front of the dark one, at 256 and 1024 samples a probe (4 and 16 rays a texel; at 256 some
// texels hold no ray): below 2% with the defaults at every point 2 to 12.5 cm behind the wall on
// a 10 cm lattice, and no lit point darker than half what Chebyshev alone gives. Chebyshev alone
// fails most of them (printed). At 128 samples (2 rays a texel) the moments are too sparse: up to
// 159% at 2 cm (the bake warns below 256; README, "Light leaks").
TEST(Leak, EveryWallPlaceAndSampleCount) {
  for (const int samples : {256, 1024}) {
    for (const double firstX : {-1.52, -1.56, -1.6, -1.65, -1.7, -1.8, -1.85, -1.9, -1.93, -1.97}) {
      BakeJob job = TwoRoomsWithThinWall(firstX);
      job.settings.samplesPerProbe = samples;
      const ProbeVolume volume = BakeOrDie(job);
      const Leak with = MeasureLeak(volume, {}, /*step=*/2);
      ProbeSamplerOptions chebyshevOnly;
      chebyshevOnly.connectivity = false;
      const Leak ddgi = MeasureLeak(volume, chebyshevOnly, /*step=*/2);
      std::printf("%4d samples, layers from x = %g: defaults %s; Chebyshev alone %s\n", samples,
                  firstX, Figures(with).c_str(), Figures(ddgi).c_str());
      for (int i = 0; i < kDeltaCount; ++i)
        EXPECT_LT(with.worst[i], 0.02)
            << samples << " samples, layers from " << firstX << ", " << kDeltas[i] << " m";
      EXPECT_GE(with.litLeast, 0.5 * ddgi.litLeast)
          << samples << " samples, layers from " << firstX;
    }
  }
}

// One probe 0.25 in front of a wall kWall thick under a sky: Chebyshev's weight for points
// 4 to 16 cm beyond the wall, at angles up to 60 degrees from the wall's normal, is below 0.04
// (at 60 degrees from 10 cm on: 4 cm beyond, 1.32 times as far as the wall at that grazing
// angle, one azimuth measured 0.12), and 1 for
// points in front of it. Why 0.04: a probe facing a point (backface weight 1.2) with visibility
// V weighs (1.2 V)^3 / 0.2^2 once crushed, and must weigh less than 2% of a probe behind the
// point's surface that sees it (0.2, the backface floor) at the same trilinear weight:
// (1.2 V)^3 / 0.04 < 0.004 gives V < 0.043.
TEST(Visibility, APointBehindAThinWallIsHiddenFromAProbeInFrontOfIt) {
  BakeJob job = MakeJob(2, 512, {0, 0, 0});
  job.settings.batches = 4;
  job.settings.visibility = true;
  job.grid.spacing = {kSpacing, kSpacing, kSpacing};
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddBox(&job.scene, {0.25, -3, -3}, {0.25 + kWall, 3, 3}, grey, /*inward=*/false);
  const ProbeVolume volume = BakeOrDie(job);
  const Vec3d probe{0, 0, 0};
  double worstHidden = 0;
  for (double angle : {0.0, 20.0, 40.0, 60.0}) {
    for (double azimuth : {0.0, 45.0, 90.0, 160.0, 250.0}) {
      const double a = angle * kPi / 180, b = azimuth * kPi / 180;
      const Vec3d w{std::cos(a), std::sin(a) * std::cos(b), std::sin(a) * std::sin(b)};
      const double wall = 0.25 / w.x;  // distance to the wall's lit face along w
      for (double beyond : {0.04, 0.1, 0.16}) {
        if (angle > 45 && beyond < 0.1) continue;
        const Vec3d x = w * ((0.25 + kWall + beyond) / w.x);
        worstHidden = std::max(worstHidden, ProbeVisibility(volume, 0, probe, x));
        EXPECT_LT(ProbeVisibility(volume, 0, probe, x), 0.04)
            << "angle " << angle << " azimuth " << azimuth << " beyond " << beyond;
      }
      for (double fraction : {0.5, 0.9}) {
        EXPECT_EQ(ProbeVisibility(volume, 0, probe, w * (fraction * wall)), 1.0)
            << "angle " << angle << " azimuth " << azimuth << " fraction " << fraction;
      }
    }
  }
  std::printf("largest visibility of a point beyond the wall: %.3g (must be < 0.04)\n",
              worstHidden);
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
