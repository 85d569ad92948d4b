// The environment guide (core/src/bake/environment_guide.h): its sampling and density agree, it
// is built only where the sky is mostly hidden, the environment's samples through it keep their
// pdfs consistent, and a bake with it meets a closed form and the bake without it, with less
// noise where the sky comes through a window.
#include "core/src/bake/environment_guide.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "bake_test_util.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/probe_integrator.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// A uniform sky seen through a cone of half-angle 30 degrees about +x, from anywhere.
EnvironmentGuide::Ray ThroughACone(const Vec3d& /*x*/, const Vec3d* wi, const Vec2d& u) {
  EnvironmentGuide::Ray ray;
  ray.wi = wi ? *wi : SampleUniformSphere(u);
  ray.pdf = 1 / (4 * kPi);
  ray.emitted = 1;
  ray.arrived = ray.wi.x > std::cos(kPi / 6) ? 1 : 0;
  return ray;
}

TEST(EnvironmentGuide, SamplesAreDistributedAsItsPdf) {
  const EnvironmentGuide guide = EnvironmentGuide::Build({0, 0, 0}, {1, 1, 1}, ThroughACone);
  // The cone is f = (1 - cos 30 deg) / 2 = 6.7% of the sphere: the pilot sees the box closed (its
  // kPilotRays rays measure f to a standard error of sqrt(f (1 - f) / kPilotRays); accepted
  // within 4 of them), and every cell guides.
  const double f = (1 - std::cos(kPi / 6)) / 2;
  EXPECT_NEAR(guide.OpenFraction(), f, 4 * std::sqrt(f * (1 - f) / EnvironmentGuide::kPilotRays));
  ASSERT_GT(guide.dims(0), 0);
  const int64_t cells = int64_t(guide.dims(0)) * guide.dims(1) * guide.dims(2);
  EXPECT_EQ(guide.GuidedCells(), cells);
  int32_t cell = -1;
  ASSERT_GT(guide.Alpha({0.5, 0.5, 0.5}, &cell), 0);
  // E_p[1 / p] is the solid angle where p > 0 (the bins any training ray arrived in, each
  // 4 pi / kBins): Sample and Pdf agree only if their ratio's mean lands on it. 2^14 Sobol points
  // integrate a piecewise-constant 1 / p over whole bins: the error is far below 1%.
  double support = 0;
  for (int b = 0; b < EnvironmentGuide::kBins; ++b) {
    // The centre of bin b, as Bin cuts the sphere.
    const int zb = b / EnvironmentGuide::kPhiBins, pb = b % EnvironmentGuide::kPhiBins;
    const double z = -1 + (zb + 0.5) * 2.0 / EnvironmentGuide::kZBins;
    const double phi = -kPi + (pb + 0.5) * 2 * kPi / EnvironmentGuide::kPhiBins;
    const double r = std::sqrt(1 - z * z);
    const Vec3d w{r * std::cos(phi), r * std::sin(phi), z};
    ASSERT_EQ(EnvironmentGuide::Bin(w), b);
    if (guide.Pdf(cell, w) > 0) support += 4 * kPi / EnvironmentGuide::kBins;
  }
  ASSERT_GT(support, 0);
  SobolSampler sampler(1, 0);
  double meanInverse = 0, inCone = 0;
  const int n = 1 << 14;
  for (int i = 0; i < n; ++i) {
    sampler.StartSample(uint64_t(i));
    const Vec3d w = guide.Sample(cell, sampler.Get2D());
    ASSERT_NEAR(Length(w), 1, 1e-12);
    const double pdf = guide.Pdf(cell, w);
    ASSERT_GT(pdf, 0) << i;
    meanInverse += 1 / pdf / n;
    inCone += w.x > std::cos(kPi / 6) ? 1.0 / n : 0.0;
  }
  EXPECT_NEAR(meanInverse, support, 0.01 * support);
  // And the guide found the cone: most of its samples land in it (bins straddle its edge).
  EXPECT_GT(inCone, 0.5);
}

TEST(EnvironmentGuide, BinsAreEqualAreaCellsOfZAndPhi) {
  // Bin finds phi's bin by comparisons: it must agree with the arc tangent's bin wherever the
  // direction is not within rounding of a boundary.
  IndependentSampler sampler(7, 0);
  const double width = 2 * kPi / EnvironmentGuide::kPhiBins;
  for (int i = 0; i < 100000; ++i) {
    sampler.StartSample(uint64_t(i));
    const Vec3d w = SampleUniformSphere(sampler.Get2D());
    const double t = (std::atan2(w.y, w.x) + kPi) / width;
    if (std::abs(t - std::round(t)) < 1e-9) continue;
    const int z =
        std::min(int((w.z + 1) * 0.5 * EnvironmentGuide::kZBins), EnvironmentGuide::kZBins - 1);
    const int phi = std::min(int(t), EnvironmentGuide::kPhiBins - 1);
    ASSERT_EQ(EnvironmentGuide::Bin(w), z * EnvironmentGuide::kPhiBins + phi) << i;
  }
}

TEST(EnvironmentGuide, LeavesAnOpenSceneAlone) {
  const EnvironmentGuide guide = EnvironmentGuide::Build(
      {0, 0, 0}, {1, 1, 1}, [](const Vec3d& x, const Vec3d* wi, const Vec2d& u) {
        EnvironmentGuide::Ray ray = ThroughACone(x, wi, u);
        ray.arrived = ray.wi.z > -0.5 ? 1 : 0;  // 75% of the sky arrives
        return ray;
      });
  EXPECT_GT(guide.OpenFraction(), EnvironmentGuide::kOpenFraction);
  EXPECT_EQ(guide.GuidedCells(), 0);
  int32_t cell;
  EXPECT_EQ(guide.Alpha({0.5, 0.5, 0.5}, &cell), 0);
  EXPECT_EQ(guide.rays(), EnvironmentGuide::kPilotRays);  // the pilot's alone
}

// A closed box 4 x 4 x 3 under a uniform sky of radiance 1, seen only through a window of
// kWindowW x kWindowH in its y = 2 wall; its floor of albedo `floor`, its other walls of albedo
// `walls`.
constexpr double kWindowW = 1.2, kWindowH = 0.8;
const Vec3d kWindowCorner{-0.6, 2, 1.0};
BakeJob WindowBox(const Vec3d& p, double floor, double walls, int64_t samples) {
  BakeJob job = MakeJob(2, samples, p);
  const uint32_t floorMaterial = AddMaterial(&job.scene, {floor, floor, floor});
  const uint32_t wall = AddMaterial(&job.scene, {walls, walls, walls});
  const double x0 = kWindowCorner.x, x1 = x0 + kWindowW;
  const double z0 = kWindowCorner.z, z1 = z0 + kWindowH;
  AddQuad(&job.scene, {-2, -2, 0}, {-2, 2, 0}, {2, 2, 0}, {2, -2, 0}, floorMaterial);
  AddQuad(&job.scene, {-2, -2, 3}, {2, -2, 3}, {2, 2, 3}, {-2, 2, 3}, wall);    // ceiling
  AddQuad(&job.scene, {-2, -2, 0}, {-2, -2, 3}, {-2, 2, 3}, {-2, 2, 0}, wall);  // x = -2
  AddQuad(&job.scene, {2, -2, 0}, {2, 2, 0}, {2, 2, 3}, {2, -2, 3}, wall);      // x = 2
  AddQuad(&job.scene, {-2, -2, 0}, {2, -2, 0}, {2, -2, 3}, {-2, -2, 3}, wall);  // y = -2
  // y = 2, around the window.
  AddQuad(&job.scene, {-2, 2, 0}, {-2, 2, z0}, {2, 2, z0}, {2, 2, 0}, wall);
  AddQuad(&job.scene, {-2, 2, z1}, {-2, 2, 3}, {2, 2, 3}, {2, 2, z1}, wall);
  AddQuad(&job.scene, {-2, 2, z0}, {-2, 2, z1}, {x0, 2, z1}, {x0, 2, z0}, wall);
  AddQuad(&job.scene, {x1, 2, z0}, {x1, 2, z1}, {2, 2, z1}, {2, 2, z0}, wall);
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  return job;
}

// Irradiance at floor point q (normal +z) from the window at radiance 1: Lambert's formula for a
// polygon, E = 1/2 sum over its edges of the angle they subtend times n . (their plane's unit
// normal).
double WindowIrradiance(const Vec3d& q) {
  const Vec3d corners[4] = {kWindowCorner, kWindowCorner + Vec3d{kWindowW, 0, 0},
                            kWindowCorner + Vec3d{kWindowW, 0, kWindowH},
                            kWindowCorner + Vec3d{0, 0, kWindowH}};
  double sum = 0;
  for (int i = 0; i < 4; ++i) {
    const Vec3d a = Normalize(corners[i] - q), b = Normalize(corners[(i + 1) % 4] - q);
    sum += std::acos(std::clamp(Dot(a, b), -1.0, 1.0)) * Normalize(Cross(a, b)).z;
  }
  return 0.5 * std::abs(sum);
}

TEST(EnvironmentGuide, SkyThroughAWindowMeetsItsClosedForm) {
  // A white floor lit by the sky through the window, black walls: a probe sees the window
  // (radiance 1) and the floor (radiance rho E(q) / pi, one bounce), c_i = int_window Y_i +
  // rho / pi int_floor E Y_i. The guide serves the floor's next-event samples of the sky (not the
  // probe's own: environment_guide.h). 2 x 2 x 2 probes across the box, each against its own
  // closed form, with the guide and without.
  constexpr double kRho = 0.8;
  BakeJob job = WindowBox({-0.6, -0.8, 1.0}, kRho, 0.0, 1024);
  job.grid.counts[0] = 2, job.grid.counts[1] = 2, job.grid.counts[2] = 2;
  job.grid.spacing = {1.2, 1.2, 1.0};
  const ProbeVolume guided = BakeOrDie(job);
  job.settings.environmentGuide = false;
  const ProbeVolume alone = BakeOrDie(job);
  for (int64_t i = 0; i < job.grid.ProbeCount(); ++i) {
    int x, y, z;
    job.grid.Coords(i, &x, &y, &z);
    const Vec3d p = job.grid.Position(x, y, z);
    std::vector<double> exact =
        ParallelogramProjection(2, p, kWindowCorner, {kWindowW, 0, 0}, {0, 0, kWindowH});
    const std::vector<double> floor = WeightedParallelogramProjection(
        2, p, {-2, -2, 0}, {4, 0, 0}, {0, 4, 0},
        [](const Vec3d& q) { return kRho / kPi * WindowIrradiance(q); });
    for (size_t c = 0; c < exact.size(); ++c) exact[c] += floor[c];
    ExpectProjection(Probe(guided, i), exact, {1, 1, 1}, "sky through a window, guided");
    ExpectProjection(Probe(alone, i), exact, {1, 1, 1}, "sky through a window, unguided");
  }
}

TEST(EnvironmentGuide, FloorIrradianceFromTheSkyWithLessNoise) {
  // What the guide is for: a floor point's next-event estimate of the sky's irradiance through
  // the window, radiance x visibility x cos / pdf, against Lambert's closed form E(q), at 16
  // points of the floor with 4096 samples each, with the guide and without.
  const BakeJob job = WindowBox({0, 0, 1.5}, 0.5, 0.5, 16);
  auto tracer = TracerScene::Build(job.scene, LocalOrigin(job.scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  const Vec3d offset = (*tracer)->offset();
  const Vec3d up{0, 0, 1};
  double variance[2] = {0, 0};
  for (int guided = 0; guided < 2; ++guided) {
    LightSet lights(job.scene, **tracer);
    if (guided) {
      const ProbeIntegrator integrator(job.scene, **tracer, lights, job.settings);
      lights.SetEnvironmentGuide(std::make_unique<EnvironmentGuide>(
          EnvironmentGuide::Build(**tracer, *lights.environment(), integrator)));
    }
    std::vector<double> importance(lights.ImportanceSize());
    for (int i = 0; i < 16; ++i) {
      const Vec3d q{-1.5 + (i % 4), -1.5 + (i / 4), 0};
      const Vec3d p = q - offset;
      const double total = lights.Importance(p, &up, /*includeDelta=*/true, importance);
      SobolSampler sampler(5, uint64_t(i));
      const int n = 4096;
      double sum = 0, sum2 = 0;
      for (int k = 0; k < n; ++k) {
        sampler.StartSample(uint64_t(k));
        const double uSelect = sampler.Get1D();
        LightSample s;
        double e = 0;
        if (lights.Sample(p, &up, importance, total, uSelect, sampler.Get2D(), &s) &&
            Dot(s.wi, up) > 0 &&
            !(*tracer)->Occluded(Vec3f(p + up * 1e-4), s.wi,
                                 std::numeric_limits<double>::infinity())) {
          e = s.radiance.y * Dot(s.wi, up) / s.pdf;
        }
        sum += e;
        sum2 += e * e;
      }
      const double mean = sum / n, var = std::max(0.0, sum2 / n - mean * mean) / (n - 1);
      const double exact = WindowIrradiance(q);
      // Independent of its neighbours' errors, each within 5 of its standard errors (plus float
      // rounding of the shadow rays' origin, far below).
      EXPECT_NEAR(mean, exact, kSigmas * std::sqrt(var) + 1e-9) << i << (guided ? " guided" : "");
      variance[guided] += var / (exact * exact);
    }
  }
  std::printf(
      "[measured] mean relative variance of a floor point's sky irradiance: guided %.3g, "
      "unguided %.3g (ratio %.3f)\n",
      variance[1] / 16, variance[0] / 16, variance[1] / variance[0]);
  // Measured 0.28. Each point's sample variance of 4096 samples is within a few percent of its
  // estimator's (10% where a rare large weight dominates), so below 0.5 is a real gain, and 1
  // (the guide unused) fails it.
  EXPECT_LT(variance[1] / variance[0], 0.5);
}

TEST(EnvironmentGuide, SampledAndFoundDensitiesAgree) {
  // Light samples of the sky from points inside the box, with and without a surface: the pdf a
  // sample reports is the one a ray along it that escapes is given (MIS needs the two equal).
  const BakeJob job = WindowBox({0, 0, 1.5}, 0.5, 0.5, 16);
  auto tracer = TracerScene::Build(job.scene, LocalOrigin(job.scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  LightSet lights(job.scene, **tracer);
  {
    const ProbeIntegrator integrator(job.scene, **tracer, lights, job.settings);
    auto guide = std::make_unique<EnvironmentGuide>(
        EnvironmentGuide::Build(**tracer, *lights.environment(), integrator));
    ASSERT_GT(guide->GuidedCells(), 0);
    lights.SetEnvironmentGuide(std::move(guide));
  }
  std::vector<double> importance(lights.ImportanceSize());
  IndependentSampler sampler(3, 0);
  const Vec3d offset = (*tracer)->offset();
  int guidedSamples = 0, checked = 0;
  for (int i = 0; i < 4000; ++i) {
    sampler.StartSample(uint64_t(i));
    const Vec2d a = sampler.Get2D();
    const Vec3d p = Vec3d{-1.9 + 3.8 * a.x, -1.9 + 3.8 * a.y, 0.1 + 2.8 * sampler.Get1D()} - offset;
    const Vec3d nStorage = Normalize(Vec3d{0.2, 0.5, 1});
    const Vec3d* n = (i % 2) ? &nStorage : nullptr;
    const double total = lights.Importance(p, n, /*includeDelta=*/true, importance);
    LightSample s;
    if (!lights.Sample(p, n, importance, total, sampler.Get1D(), sampler.Get2D(), &s)) continue;
    double found = 0;
    lights.ForEachEscaped(p, n, importance, total, s.wi, [&](const LightHit& h) {
      if (h.light == s.light) found = h.pdf;
    });
    EXPECT_NEAR(found, s.pdf, 1e-12 * s.pdf) << i;
    ++checked;
    // Through the window: a direction the sky's own sampling (uniform) rarely takes.
    guidedSamples += (s.wi.y > 0.7);
  }
  EXPECT_GT(checked, 3000);
  std::printf("[measured] %d of %d sky samples toward the window wall\n", guidedSamples, checked);
}

TEST(EnvironmentGuide, AgreesWithTheUnguidedBakeWhereWallsReflect) {
  // White walls: the sky through the window lights the room, and paths bounce before they find
  // it. No closed form, so the guided bake is held against the unguided one with other numbers,
  // as DistantLightPaths.AgreeWithTheProbesOwnPathsInARoom does (z^2's mean over 8 probes x 9
  // coefficients: standard error sqrt(2.24 / 72) = 0.176, accepted within 4 of them of 1.03).
  BakeJob job = WindowBox({-1, -1, 0.75}, 0.7, 0.7, 1024);
  job.grid.counts[0] = 2, job.grid.counts[1] = 2, job.grid.counts[2] = 2;
  job.grid.spacing = {2, 2, 1.5};
  job.settings.maxDepth = 4;
  const ProbeVolume guided = BakeOrDie(job);
  job.settings.environmentGuide = false;
  job.settings.seed = 2;
  const ProbeVolume alone = BakeOrDie(job);
  const Agreement z = CompareBakes(guided, alone, job.grid.ProbeCount());
  std::printf("[measured] guided against unguided: mean z^2 %.3f over %d coefficients (max %.2f)\n",
              z.meanZ2, z.count, z.maxZ);
  EXPECT_NEAR(z.meanZ2, 1.03, 4 * std::sqrt(2.24 / z.count));
  EXPECT_LT(z.maxZ, kSigmas);
}

TEST(EnvironmentGuide, SameBitsOnOneThreadAndMany) {
  // The guide's cells are traced in parallel.
  BakeJob job = WindowBox({-1, -1, 0.75}, 0.7, 0.7, 256);
  job.grid.counts[0] = 2;
  job.grid.spacing = {2, 1, 1};
  job.settings.batches = 4;
  const ProbeVolume one = BakeOrDie(job, 1), many = BakeOrDie(job, 4);
  for (size_t c = 0; c < one.radiance.size(); ++c) EXPECT_EQ(one.radiance[c], many.radiance[c]);
  EXPECT_EQ(one.stdError, many.stdError);
  job.settings.environmentGuide = false;
  const ProbeVolume without = BakeOrDie(job, 1);
  EXPECT_NE(one.radiance[0], without.radiance[0]);
}

}  // namespace
}  // namespace probebake
