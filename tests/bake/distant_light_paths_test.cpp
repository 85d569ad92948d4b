// Light traced from directional lights and joined to the probes' paths
// (core/src/bake/distant_light_paths.h): a closed form the light paths carry, agreement with the
// probes' own paths where there is none, and the bits' independence of threads.
#include <gtest/gtest.h>

#include <cmath>

#include "bake_test_util.h"
#include "core/src/bake/distant_light_paths.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/tracer_scene.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// Mean over probes of the reported relative standard error (std_error).
double MeanStdError(const ProbeVolume& v) {
  double sum = 0;
  int64_t n = 0;
  for (size_t p = 0; p < v.stdError.size(); ++p) {
    if (!v.active[p]) continue;
    sum += v.stdError[p];
    ++n;
  }
  return n ? sum / double(n) : 0.0;
}

// A white floor (albedo kRho) under a black ceiling at z = 2 with a 1 x 1 hole over the origin;
// a delta sun shines straight down through it. The floor is lit on the hole's square alone, with
// radiance kRho E / pi (one bounce: the ceiling absorbs), and the probe at p also sees the sun
// through the hole: c_i = E Y_i(+z) + kRho E / pi int_square Y_i.
constexpr double kRho = 0.6;
BakeJob SunThroughAHole(const Vec3d& p, const Vec3d& E) {
  BakeJob job = MakeJob(2, 4096, p);
  const uint32_t white = AddMaterial(&job.scene, {kRho, kRho, kRho});
  const uint32_t black = AddMaterial(&job.scene, {0, 0, 0});
  AddQuad(&job.scene, {-5, -5, 0}, {5, -5, 0}, {5, 5, 0}, {-5, 5, 0}, white);
  const double h = 0.5, z = 2;
  AddQuad(&job.scene, {-5, -5, z}, {-h, -5, z}, {-h, 5, z}, {-5, 5, z}, black);
  AddQuad(&job.scene, {h, -5, z}, {5, -5, z}, {5, 5, z}, {h, 5, z}, black);
  AddQuad(&job.scene, {-h, -5, z}, {h, -5, z}, {h, -h, z}, {-h, -h, z}, black);
  AddQuad(&job.scene, {-h, h, z}, {h, h, z}, {h, 5, z}, {-h, 5, z}, black);
  job.scene.lights.push_back(DirectionalLight{{0, 0, -1}, E, 1.0});
  return job;
}

TEST(DistantLightPaths, SunThroughAHoleLightsASquareOfFloor) {
  const Vec3d p{0.3, 0.2, 1}, E{2, 2, 2};
  BakeJob job = SunThroughAHole(p, E);
  const ProbeVolume traced = BakeOrDie(job);
  std::vector<double> exact = ParallelogramProjection(2, p, {-0.5, -0.5, 0}, {1, 0, 0}, {0, 1, 0});
  std::vector<double> sun(exact.size());
  EvalShBasis(2, Vec3d{0, 0, 1}, sun.data());
  for (size_t c = 0; c < exact.size(); ++c) exact[c] = sun[c] + kRho / kPi * exact[c];
  ExpectProjection(Probe(traced, 0), exact, E, "sun through a hole, light traced");

  // The probe's own paths alone find the square by chance: the light paths, which land on it by
  // construction, must make the estimate much more precise (and the closed form holds there too).
  job.settings.distantLightTracing = false;
  const ProbeVolume alone = BakeOrDie(job);
  ExpectProjection(Probe(alone, 0), exact, E, "sun through a hole, probe paths alone");
  const double ratio = traced.stdError[0] / alone.stdError[0];
  std::printf("[measured] std_error with light traced %.3g, without %.3g (ratio %.3f)\n",
              double(traced.stdError[0]), double(alone.stdError[0]), ratio);
  // Each std_error, from 64 batches, is itself uncertain by about 1 / sqrt(2 x 63) = 9%: a ratio
  // below 0.5 is a real gain (measured 0.22), and 1 (the light paths unused) fails it by far.
  EXPECT_LT(ratio, 0.5);
}

// RoomWithOpening (a sun through the roof's opening, a ceiling light, a sky) with 3 x ny x 2
// probes across it, y spacing dy.
BakeJob RoomJob(int64_t samples, int ny, double dy) {
  BakeJob job = MakeJob(2, samples, {-3, -2, 0.5});
  job.scene = RoomWithOpening();
  job.grid.counts[0] = 3, job.grid.counts[1] = ny, job.grid.counts[2] = 2;
  job.grid.spacing = {3, dy, 1.5};
  return job;
}

TEST(DistantLightPaths, AgreeWithTheProbesOwnPathsInARoom) {
  // The room with a sun through its roof's opening, a ceiling light and a sky: no closed form,
  // so the bake with light tracing is held against the bake without it. Each coefficient's
  // difference over the two bakes' combined standard error, z, is near Student's t with 63
  // degrees of freedom per bake: E[z^2] ~ 1.03, Var[z^2] ~ 2.24. Over 18 probes x 9
  // coefficients (one channel: the three share their paths), taken as independent, the mean of
  // z^2 has a standard error of sqrt(2.24 / 162) = 0.118: accepted within 4 of them of 1.03. A
  // weight that counted a path twice or not at all (the sun's light is most of these probes')
  // moves every z the same way and fails it.
  BakeJob job = RoomJob(2048, 3, 2);
  job.settings.maxDepth = 4;
  const ProbeVolume traced = BakeOrDie(job);
  // Numbers of their own: the same seed would share the probes' paths, and the two estimates'
  // errors with them.
  job.settings.distantLightTracing = false;
  job.settings.seed = 2;
  const ProbeVolume alone = BakeOrDie(job);
  for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) ASSERT_TRUE(traced.active[p]) << p;
  const Agreement z = CompareBakes(traced, alone, job.grid.ProbeCount());
  std::printf(
      "[measured] light traced against probe paths alone: mean z^2 %.3f over %d coefficients "
      "(max |z| %.2f); mean std_error %.4f against %.4f\n",
      z.meanZ2, z.count, z.maxZ, MeanStdError(traced), MeanStdError(alone));
  EXPECT_NEAR(z.meanZ2, 1.03, 4 * 0.118);
  EXPECT_LT(z.maxZ, kSigmas);
}

TEST(DistantLightPaths, SameBitsOnOneThreadAndMany) {
  // The light paths are traced in parallel per batch, and the probes join them from any thread.
  BakeJob job = RoomJob(512, 2, 4);
  job.settings.batches = 4;
  const ProbeVolume one = BakeOrDie(job, 1), many = BakeOrDie(job, 4);
  ASSERT_EQ(one.radiance.size(), many.radiance.size());
  for (size_t c = 0; c < one.radiance.size(); ++c) EXPECT_EQ(one.radiance[c], many.radiance[c]);
  EXPECT_EQ(one.stdError, many.stdError);
  // And the light paths changed the bits: the same job without them differs.
  job.settings.distantLightTracing = false;
  const ProbeVolume without = BakeOrDie(job, 1);
  EXPECT_NE(one.radiance[0], without.radiance[0]);
}

// A white floor with a box on it, open to the sky: most of a sun's rays land inside.
Scene OpenFloor() {
  Scene scene;
  const uint32_t white = AddMaterial(&scene, {0.7, 0.7, 0.7});
  AddQuad(&scene, {-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}, white);
  AddBox(&scene, {-0.5, -0.5, 0}, {0.5, 0.5, 1}, white, /*inward=*/false);
  return scene;
}

TEST(DistantLightPaths, HoldAboutKMaxKeptPathsAtMostWhateverTheSampleCount) {
  // 4 batches of 2^22 samples (a probe of 16M samples, the job limit): lambda n_b would be
  // millions of kept paths; the cap keeps about kMaxKeptPaths over the batches. The kept count is
  // kMaxKeptPaths f / f_pilot: the pilot's f (about 0.6) from 4096 paths has a standard error of
  // sqrt(f (1 - f) / 4096) = 1.3% of f, so +-10% is more than 7 of them.
  Scene scene = OpenFloor();
  scene.lights.push_back(DirectionalLight{Normalize(Vec3d{0.2, 0.1, -1}), {3, 3, 3}, 1.0});
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  LightSet lights(scene, **tracer);
  BakeSettings settings;
  const std::vector<int64_t> batches(4, int64_t{1} << 22);
  const auto paths = DistantLightPaths::Build(scene, **tracer, &lights, settings, batches);
  ASSERT_NE(paths, nullptr);
  ASSERT_TRUE(paths->Traces(0));
  const int64_t kept = paths->KeptCount(0), traced = paths->PathCount(0);
  std::printf(
      "[measured] 2^24 samples: %lld light paths traced, %lld kept (lambda %d, kept %.3f)\n",
      (long long)traced, (long long)kept, paths->Lambda(0), paths->KeptFraction(0));
  // n_L per batch is ceil(kMaxKeptPaths / (4 f)), far below lambda n_b.
  EXPECT_LE(traced, 4 * int64_t(std::ceil(double(DistantLightPaths::kMaxKeptPaths) /
                                          (4 * paths->KeptFraction(0)))));
  EXPECT_LT(traced, int64_t(paths->Lambda(0)) * (int64_t{1} << 24) / 16);
  EXPECT_LE(double(kept), 1.1 * double(DistantLightPaths::kMaxKeptPaths));
  EXPECT_GE(double(kept), 0.9 * double(DistantLightPaths::kMaxKeptPaths));
}

TEST(DistantLightPaths, TraceTheBrightestDirectionalLightsOnly) {
  // Ten suns of irradiance 1 to 10: the kMaxSources brightest are traced, the others left to the
  // probes' paths (their weights untouched).
  Scene scene = OpenFloor();
  for (int i = 0; i < 10; ++i) {
    const double e = 1 + ((i * 7) % 10);  // 1..10, not in order
    scene.lights.push_back(DirectionalLight{Normalize(Vec3d{0.1 * i, 0.2, -1}), {e, e, e}, 1.0});
  }
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  LightSet lights(scene, **tracer);
  BakeSettings settings;
  const std::vector<int64_t> batches(4, 64);
  const auto paths = DistantLightPaths::Build(scene, **tracer, &lights, settings, batches);
  ASSERT_NE(paths, nullptr);
  int traced = 0;
  for (uint32_t i = 0; i < 10; ++i) {
    const double e = 1 + ((i * 7) % 10);
    EXPECT_EQ(paths->Traces(i), e > 10 - double(DistantLightPaths::kMaxSources)) << i;
    traced += paths->Traces(i);
  }
  EXPECT_EQ(traced, int(DistantLightPaths::kMaxSources));
}

}  // namespace
}  // namespace probebake
