// Russian roulette on the paths' weak shadow rays (core/src/bake/shadow_roulette.h): unbiased
// weights, the pilot's threshold, and bakes that agree with the bake without it while tracing
// fewer rays.
#include "core/src/bake/shadow_roulette.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "bake_test_util.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/probe_integrator.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/sh/sh_basis.h"

namespace probebake {
namespace {

using testing::Agreement;
using testing::BakeOrDie;
using testing::CompareBakes;
using testing::kSigmas;
using testing::MakeJob;
using testing::RoomWithOpening;

TEST(ShadowRoulette, WeighsEachContributionByOneOnAverage) {
  // u at the midpoints of n equal cells: the count below q is n q within 1, so the mean weight
  // (1/q per survivor) is 1 within 1 / (n q).
  constexpr int n = 1 << 16;
  const double threshold = 0.8;
  for (double c : {1e-4, 0.01, 0.2, 0.5, 0.79, 0.8, 3.0}) {
    const double q = std::min(1.0, c / threshold);
    double sum = 0;
    for (int k = 0; k < n; ++k) {
      const double w = ShadowRouletteWeight(c, threshold, (k + 0.5) / n);
      // Never traced, traced as it is (at or above the threshold), or weighted by 1 / q.
      if (c >= threshold) {
        EXPECT_EQ(w, 1);
      } else {
        EXPECT_TRUE(w == 0 || w == 1 / q) << c << " " << w;
      }
      sum += w;
    }
    EXPECT_NEAR(sum / n, 1.0, 1.0 / (n * q) + 1e-12) << c;
  }
  // No threshold: every ray traced as it is, a zero contribution included.
  EXPECT_EQ(ShadowRouletteWeight(0.3, 0, 0.99), 1);
  EXPECT_EQ(ShadowRouletteWeight(0, 0, 0.5), 1);
}

TEST(ShadowRoulette, PilotReadsTheProbesMeanRadianceUnderAUniformSky) {
  // Nothing but a uniform sky of radiance L: every probe sample's two techniques (a uniform
  // direction and the sky's own uniform sample), weighted 1/2 each by MIS, add exactly L to the
  // mean radiance, so the pilot's threshold is kRouletteShare x max(L) to rounding.
  Scene scene;
  const Vec3d sky{0.5, 1.0, 2.0};
  scene.environment = {Environment::Kind::kUniform, sky, nullptr};
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  const LightSet lights(scene, **tracer);
  BakeSettings settings;
  const ProbeIntegrator integrator(scene, **tracer, lights, settings);
  SharedCounters counters;
  const double t = integrator.RouletteRadiance({1, 2, 3}, 42, 4096, &counters);
  EXPECT_NEAR(t, ProbeIntegrator::kRouletteShare * 2.0, 1e-12);
  // Its rays are counted as work (one first ray and one light sample per path at least); its
  // paths are no sample of the probe's.
  EXPECT_GE(counters.rays.load(), 2 * ProbeIntegrator::kPilotSamples);
  EXPECT_EQ(counters.samples.load(), 0);
  // Too few samples for a pilot worth its cost: no roulette.
  const int64_t few = ProbeIntegrator::kPilotDivisor * ProbeIntegrator::kMinPilotSamples - 1;
  EXPECT_EQ(integrator.RouletteRadiance({1, 2, 3}, 42, few, nullptr), 0);
  settings.shadowRoulette = false;
  const ProbeIntegrator off(scene, **tracer, lights, settings);
  EXPECT_EQ(off.RouletteRadiance({1, 2, 3}, 42, 4096, nullptr), 0);
}

// RoomWithOpening (a ceiling light, a sun through the roof's opening and a sky: weak shadow rays
// from deep in the room toward the sky and the sun, joins to far sunlit points) with 3 x 3 x 2
// probes.
BakeJob Room(int64_t samples) {
  BakeJob job = MakeJob(2, samples, {-3, -2, 0.5});
  job.scene = RoomWithOpening();
  job.grid.counts[0] = 3, job.grid.counts[1] = 3, job.grid.counts[2] = 2;
  job.grid.spacing = {3, 2, 1.5};
  job.settings.maxDepth = 4;
  return job;
}

TEST(ShadowRoulette, KeepsTheRoomsEstimateWithFewerRays) {
  // No closed form: the bake with roulette is held against the bake without it (other numbers),
  // as DistantLightPaths.AgreeWithTheProbesOwnPathsInARoom does, over 4 pairs of seeds: each
  // coefficient's difference over the two bakes' combined standard error, z, is near Student's t
  // with 63 degrees of freedom (E[z^2] ~ 1.03). A probe's 9 coefficients share its paths, so a
  // pair's mean z^2 over 18 probes x 9 varies more than independent ones would: measured 0.70 to
  // 1.72 over 11 pairs of bakes (the roulette on in neither, in one: alike), a standard deviation
  // of about 0.25, so the mean of 4 pairs is accepted within 4 x 0.25 / 2 of 1.03. A weight that
  // dropped the rays not traced, or counted the survivors once, biases every probe the same way
  // (most of their light arrives through light samples and joins) and fails it.
  double sumZ2 = 0, maxZ = 0;
  int64_t playedRays = 0, tracedRays = 0;
  constexpr int kPairs = 4;
  for (int pair = 0; pair < kPairs; ++pair) {
    BakeJob job = Room(2048);
    job.settings.seed = uint64_t(2 * pair + 1);
    const ProbeVolume played = BakeOrDie(job);
    job.settings.shadowRoulette = false;
    const ProbeVolume same = BakeOrDie(job);  // the same numbers, every ray traced
    job.settings.seed = uint64_t(2 * pair + 2);
    const ProbeVolume traced = BakeOrDie(job);
    const Agreement z = CompareBakes(played, traced, job.grid.ProbeCount());
    std::printf("[measured] seeds %d, %d: roulette against none: mean z^2 %.3f (max |z| %.2f)\n",
                2 * pair + 1, 2 * pair + 2, z.meanZ2, z.maxZ);
    sumZ2 += z.meanZ2;
    maxZ = std::max(maxZ, z.maxZ);
    // The roulette ran: the same job with the same seed traces fewer rays with it (the pilot's
    // included), and other bits.
    EXPECT_LT(played.stats.rays, same.stats.rays);
    EXPECT_NE(played.radiance[0], same.radiance[0]);
    playedRays += played.stats.rays, tracedRays += same.stats.rays;
  }
  std::printf("[measured] mean z^2 %.3f over %d pairs; %.3f of the rays traced without roulette\n",
              sumZ2 / kPairs, kPairs, double(playedRays) / double(tracedRays));
  EXPECT_NEAR(sumZ2 / kPairs, 1.03, 4 * 0.25 / std::sqrt(double(kPairs)));
  EXPECT_LT(maxZ, kSigmas);
}

TEST(ShadowRoulette, SameBitsOnOneThreadAndMany) {
  // The pilot is the probe's own: its threshold, and so every decision, whatever thread bakes it.
  BakeJob job = Room(1024);
  job.settings.batches = 8;
  const ProbeVolume one = BakeOrDie(job, 1), many = BakeOrDie(job, 4);
  for (size_t c = 0; c < one.radiance.size(); ++c) EXPECT_EQ(one.radiance[c], many.radiance[c]);
  EXPECT_EQ(one.stdError, many.stdError);
  EXPECT_EQ(one.stats.rays, many.stats.rays);
}

TEST(ShadowRoulette, PacketsAndSingleRaysPlayAlike) {
  // The decisions read the contributions and numbers of each sample, not how its rays were
  // grouped: a call traced as packets and ray by ray sums alike (tolerance: the packet kernel's
  // hits may differ in the last float bit, ProbeIntegrator.PacketsChangeNoResult).
  const Scene scene = RoomWithOpening();
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  const LightSet lights(scene, **tracer);
  BakeSettings settings;
  const ProbeIntegrator packets(scene, **tracer, lights, settings, /*packets=*/true);
  const ProbeIntegrator single(scene, **tracer, lights, settings, /*packets=*/false);
  const Vec3d p = Vec3d{2.5, -2, 2} - (*tracer)->offset();
  const double threshold = packets.RouletteRadiance(p, 17, 1024, nullptr);
  ASSERT_GT(threshold, 0);
  EXPECT_EQ(threshold, single.RouletteRadiance(p, 17, 1024, nullptr));
  std::vector<double> a(3 * size_t(ShCoeffCount(settings.shOrder))), b(a.size());
  SharedCounters ca, cb;
  const ProbeIntegrator::BatchWork wa{512, a}, wb{512, b};
  ASSERT_TRUE(packets.TraceBatches(p, 17, 0, {&wa, 1}, &ca, nullptr, threshold));
  ASSERT_TRUE(single.TraceBatches(p, 17, 0, {&wb, 1}, &cb, nullptr, threshold));
  EXPECT_EQ(ca.rays.load(), cb.rays.load());
  double scale = 0;
  for (double v : b) scale = std::max(scale, std::fabs(v));
  ASSERT_GT(scale, 0);
  for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-5 * scale) << i / 3;
  // And the threshold mattered: without it the call traces more rays.
  SharedCounters cn;
  std::vector<double> n(a.size());
  const ProbeIntegrator::BatchWork wn{512, n};
  ASSERT_TRUE(packets.TraceBatches(p, 17, 0, {&wn, 1}, &cn, nullptr, 0));
  EXPECT_LT(ca.rays.load(), cn.rays.load());
}

}  // namespace
}  // namespace probebake
