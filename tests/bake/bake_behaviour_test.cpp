// The bake's behaviour beyond single closed forms: estimators agree and MIS wins, validity and
// placement, determinism across threads and runs, resumption, cancellation, adaptive sampling,
// extreme magnitudes and scales.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>

#include "bake_test_util.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// A floor lit by a small bright sphere light (direction sampling finds it rarely: ~0.1% of
// probe rays) and a large disk light hanging low over the floor (area sampling is poor under it:
// pdf d^2 / (A cos) blows up near the disk), probes between them.
BakeJob TwoLightScene(Estimator estimator) {
  BakeJob job = MakeJob(2, 32768, {-0.5, 0, 0.4});
  job.grid.spacing = {1, 1, 1};
  job.grid.counts[0] = 2;
  const uint32_t floor = AddMaterial(&job.scene, {0.6, 0.6, 0.6});
  AddQuad(&job.scene, {-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}, floor);
  job.scene.lights.push_back(SphereLight{{1.0, 0.5, 0.6}, 0.1, {200, 200, 200}});
  job.scene.lights.push_back(DiskLight{{0, 0, 0.8}, {0, 0, -1}, 2.0, {1, 1, 1}, false});
  job.settings.estimator = estimator;
  job.settings.maxDepth = 3;
  job.settings.russianRoulette = false;
  return job;
}

TEST(Estimators, AllThreeAgreeAndMisHasTheLowestVariance) {
  const ProbeVolume mis = BakeOrDie(TwoLightScene(Estimator::kNeeMis));
  const ProbeVolume light = BakeOrDie(TwoLightScene(Estimator::kLightSampling));
  const ProbeVolume direction = BakeOrDie(TwoLightScene(Estimator::kDirectionSampling));
  for (int64_t probe = 0; probe < 2; ++probe) {
    const ProbeResult a = Probe(mis, probe), b = Probe(light, probe), c = Probe(direction, probe);
    for (size_t k = 0; k < a.radiance.size(); ++k) {
      for (int ch = 0; ch < 3; ++ch) {
        // Independent estimates of the same number: the difference has standard error
        // sqrt(sa^2 + sb^2).
        const double sab = std::hypot(a.stdError[k][ch], b.stdError[k][ch]);
        const double sac = std::hypot(a.stdError[k][ch], c.stdError[k][ch]);
        EXPECT_NEAR(a.radiance[k][ch], b.radiance[k][ch], kSigmas * sab) << probe << " " << k;
        EXPECT_NEAR(a.radiance[k][ch], c.radiance[k][ch], kSigmas * sac) << probe << " " << k;
      }
    }
    // Same samples per probe: MIS must give the smallest standard error of L0. Measured here:
    // MIS 8-15x below light sampling and 25-48x below direction sampling; a factor 3 keeps the
    // test far from the ~9% relative uncertainty of a 64-batch error estimate.
    EXPECT_LT(a.relError * 3, b.relError) << "probe " << probe << " MIS vs light sampling";
    EXPECT_LT(a.relError * 3, c.relError) << "probe " << probe << " MIS vs direction sampling";
  }
}

TEST(Validity, ProbeInsideAClosedBoxIsInvalid) {
  // Probe 0 inside a closed box with outward faces, probe 1 outside it.
  BakeJob job = MakeJob(1, 256, {0, 0, 0});
  job.grid.counts[0] = 2;
  job.grid.spacing = {3, 1, 1};
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddBox(&job.scene, {-1, -1, -1}, {1, 1, 1}, grey, /*inward=*/false);

  job.grid.placement = Placement::kAll;
  ProbeVolume all = BakeOrDie(job);
  EXPECT_TRUE(all.active[0]);
  EXPECT_EQ(all.validity[0], 0.0f);
  EXPECT_TRUE(all.active[1]);
  EXPECT_EQ(all.validity[1], 1.0f);
  EXPECT_EQ(all.stats.invalidProbes, 1);

  job.grid.placement = Placement::kOutsideGeometry;
  ProbeVolume outside = BakeOrDie(job);
  EXPECT_FALSE(outside.active[0]);
  EXPECT_EQ(outside.sampleCount[0], 0.0f);
  EXPECT_TRUE(outside.active[1]);
  EXPECT_EQ(outside.stats.probes, 1);
  // The baked probe's values do not depend on which others were baked.
  EXPECT_EQ(all.radiance[0][3], outside.radiance[0][3]);
}

TEST(Placement, NearSurfacesKeepsOnlyProbesCloseToGeometry) {
  // Probes at x = 0, 1, 2, 3 above a floor quad spanning x in [-1, 0.5]: with surfaceDistance 1,
  // probes at height 0.5 over x = 0 and 1 are within reach (distance 0.5 and ~0.71), 2 and 3 not.
  BakeJob job = MakeJob(1, 64, {0, 0, 0.5});
  job.grid.counts[0] = 4;
  job.grid.placement = Placement::kNearSurfaces;
  job.grid.surfaceDistance = 1.0;
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddQuad(&job.scene, {-1, -1, 0}, {0.5, -1, 0}, {0.5, 1, 0}, {-1, 1, 0}, grey);
  const ProbeVolume v = BakeOrDie(job);
  EXPECT_TRUE(v.active[0]);
  EXPECT_TRUE(v.active[1]);
  EXPECT_FALSE(v.active[2]);
  EXPECT_FALSE(v.active[3]);
}

BakeJob DemoLikeScene() {
  BakeJob job = MakeJob(2, 256, {-0.8, -0.8, 0.3});
  job.grid.counts[0] = job.grid.counts[1] = 3;
  job.grid.counts[2] = 2;
  job.grid.spacing = {0.8, 0.8, 0.8};
  job.settings.batches = 16;
  job.settings.seed = 7;
  job.scene.environment = {Environment::Kind::kUniform, {0.3, 0.4, 0.6}, nullptr};
  const uint32_t white = AddMaterial(&job.scene, {0.7, 0.7, 0.7});
  const uint32_t red = AddMaterial(&job.scene, {0.7, 0.1, 0.1});
  AddQuad(&job.scene, {-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}, white);
  AddBox(&job.scene, {0.2, 0.2, 0}, {0.6, 0.6, 0.5}, red, false);
  job.scene.lights.push_back(RectLight{{-0.5, -0.5, 2}, {0, 1, 0}, {1, 0, 0}, {5, 5, 5}, false});
  job.scene.lights.push_back(
      DirectionalLight{Normalize(Vec3d{0.3, 0.2, -1}), {2, 2, 2}, std::cos(0.53 / 2 * kPi / 180)});
  job.scene.lights.push_back(PointLight{{1, -1, 1}, {1, 1, 1}});
  return job;
}

void ExpectIdentical(const ProbeVolume& a, const ProbeVolume& b) {
  ASSERT_EQ(a.radiance.size(), b.radiance.size());
  for (size_t c = 0; c < a.radiance.size(); ++c)
    EXPECT_EQ(0, std::memcmp(a.radiance[c].data(), b.radiance[c].data(),
                             a.radiance[c].size() * sizeof(float)))
        << "coefficient " << c;
  EXPECT_EQ(a.stdError, b.stdError);
  EXPECT_EQ(a.stdErrorL0, b.stdErrorL0);
  EXPECT_EQ(a.sampleCount, b.sampleCount);
  EXPECT_EQ(a.validity, b.validity);
  EXPECT_EQ(a.active, b.active);
}

TEST(Determinism, SameBitsForAnyThreadCountAndRun) {
  const BakeJob job = DemoLikeScene();
  const ProbeVolume one = BakeOrDie(job, 1);
  const ProbeVolume two = BakeOrDie(job, 2);
  const ProbeVolume again = BakeOrDie(job, 2);
  ExpectIdentical(one, two);
  ExpectIdentical(two, again);
  // And the seed matters.
  BakeJob other = job;
  other.settings.seed = 8;
  const ProbeVolume reseeded = BakeOrDie(other, 2);
  EXPECT_NE(reseeded.radiance[0], one.radiance[0]);
}

// The sharding of a grid across machines does not change a result (docs/job-format.md). A 4x3x3
// grid and three sub-grids tiling it, each written as a user would (its own min, typed in
// decimal), bake every probe to the same bits. Spacing 0.8 is not binary: the sub-grids'
// positions at x = 1.6 and z = 1.9 differ from the whole grid's (-0.8 + 0.8 * 3, 0.3 + 0.8 * 2)
// in the last bits, which the probe sites must absorb (probe_site.h).
void ExpectShardsBakeAsTheWholeGrid(BakeJob whole) {
  whole.grid.counts[0] = 4;
  whole.grid.counts[2] = 3;
  whole.settings.irradiance = true;
  whole.settings.targetRelError = 0.05;  // adaptive: each probe's stopping point must agree too
  const ProbeVolume all = BakeOrDie(whole, 2);
  struct Shard {
    Vec3d min;
    int counts[3];
    int offset[3];  // index of the shard's first probe in the whole grid
  };
  const Shard shards[] = {{{-0.8, -0.8, 0.3}, {3, 3, 2}, {0, 0, 0}},
                          {{1.6, -0.8, 0.3}, {1, 3, 3}, {3, 0, 0}},
                          {{-0.8, -0.8, 1.9}, {3, 3, 1}, {0, 0, 2}}};
  int compared = 0, movedPositions = 0;
  for (const Shard& shard : shards) {
    BakeJob job = whole;
    job.grid.origin = shard.min;
    std::copy(shard.counts, shard.counts + 3, job.grid.counts);
    const ProbeVolume part = BakeOrDie(job, 1);
    for (int64_t probe = 0; probe < job.grid.ProbeCount(); ++probe) {
      int i, j, k;
      job.grid.Coords(probe, &i, &j, &k);
      const int wi = i + shard.offset[0], wj = j + shard.offset[1], wk = k + shard.offset[2];
      const int64_t w = whole.grid.LinearIndex(wi, wj, wk);
      const Vec3d a = job.grid.Position(i, j, k), b = whole.grid.Position(wi, wj, wk);
      movedPositions += (a.x != b.x || a.y != b.y || a.z != b.z) ? 1 : 0;
      const ProbeResult x = Probe(part, probe), y = Probe(all, w);
      EXPECT_EQ(x.active, y.active) << "probe " << w;
      EXPECT_EQ(x.validity, y.validity) << "probe " << w;
      EXPECT_EQ(x.sampleCount, y.sampleCount) << "probe " << w;
      EXPECT_EQ(x.relError, y.relError) << "probe " << w;
      for (int c = 0; c < part.CoeffCount(); ++c) {
        for (int ch = 0; ch < 3; ++ch) {
          EXPECT_EQ(part.radiance[c][3 * probe + ch], all.radiance[c][3 * w + ch])
              << "probe " << w << " coefficient " << c;
          EXPECT_EQ(part.irradiance[c][3 * probe + ch], all.irradiance[c][3 * w + ch])
              << "probe " << w << " coefficient " << c;
        }
      }
      ASSERT_EQ(part.offset.empty(), all.offset.empty());
      for (int ch = 0; ch < 3 && !part.offset.empty(); ++ch)
        EXPECT_EQ(part.offset[3 * probe + ch], all.offset[3 * w + ch]) << "probe " << w;
      ASSERT_EQ(part.visibility.size(), all.visibility.size());
      for (size_t t = 0; t < part.visibility.size(); ++t)
        for (int ch = 0; ch < 3; ++ch)
          EXPECT_EQ(part.visibility[t][3 * probe + ch], all.visibility[t][3 * w + ch])
              << "probe " << w << " texel " << t;
      ++compared;
    }
  }
  EXPECT_EQ(compared, 36);  // the shards tile the whole grid
  EXPECT_GT(movedPositions, 0) << "the shards did not exercise rounding differences";
}

TEST(Determinism, ShardedGridGivesTheSameBitsAsTheWholeGrid) {
  ExpectShardsBakeAsTheWholeGrid(DemoLikeScene());
}

TEST(Determinism, ShardedGridWithRelocationAndVisibilityGivesTheSameBits) {
  // A post through the grid point (0.8, 0, 0.3) and the floor 0.3 below the lowest layer: with
  // R = 0.4 * 0.8 = 0.32 and clearance 0.08, that probe moves out of the post.
  BakeJob job = DemoLikeScene();
  const uint32_t grey = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  AddBox(&job.scene, {0.7, -0.1, 0}, {0.9, 0.1, 0.5}, grey, /*inward=*/false);
  job.settings.relocationMaxOffset = 0.4;
  job.settings.visibility = true;
  BakeJob whole = job;
  whole.grid.counts[0] = 4;
  whole.grid.counts[2] = 3;
  const ProbeVolume all = BakeOrDie(whole, 2);
  int moved = 0;
  for (float x : all.offset) moved += x != 0 ? 1 : 0;
  EXPECT_GT(moved, 0) << "no probe was relocated";
  ExpectShardsBakeAsTheWholeGrid(job);
}

TEST(Determinism, ResumedBakeGivesTheSameBits) {
  // Resuming from any subset of finished probes reproduces the uninterrupted bake exactly.
  const BakeJob job = DemoLikeScene();
  const ProbeVolume full = BakeOrDie(job, 2);
  ProbeVolume partial = full;
  std::vector<uint8_t> done(full.active.size(), 0);
  for (size_t p = 0; p < done.size(); ++p) {
    if (p % 3 == 0) {
      done[p] = 1;
    } else {  // not finished: its values must not leak into the result
      for (auto& plane : partial.radiance) plane[3 * p] = plane[3 * p + 1] = plane[3 * p + 2] = -1;
      partial.stdError[p] = partial.stdErrorL0[p] = partial.sampleCount[p] = -1;
    }
  }
  BakeOptions resume;
  resume.threads = 1;
  resume.coefficientErrors = true;
  resume.resumeFrom = &partial;
  resume.resumeDone = &done;
  absl::StatusOr<ProbeVolume> second = Bake(job, resume);
  ASSERT_TRUE(second.ok()) << second.status();
  ExpectIdentical(full, *second);
}

TEST(Determinism, CheckpointTakenDuringABakeResumesToTheSameBits) {
  // Cancel at the first checkpoint holding a finished probe (the bake takes far longer than the
  // 1 ms checkpoint period), then resume from that checkpoint.
  BakeJob job = DemoLikeScene();
  job.settings.samplesPerProbe = 16384;
  const ProbeVolume full = BakeOrDie(job, 2);
  std::atomic<bool> cancel{false};
  ProbeVolume partial;
  std::vector<uint8_t> done;
  BakeOptions options;
  options.threads = 2;
  options.coefficientErrors = true;
  options.cancel = &cancel;
  options.checkpointIntervalSeconds = 0;
  options.progressIntervalSeconds = 0.001;
  options.checkpoint = [&](const ProbeVolume& v, const std::vector<uint8_t>& flags) {
    if (done.empty() && std::count(flags.begin(), flags.end(), uint8_t{1}) >= 1) {
      partial = v;
      done = flags;
      cancel = true;
    }
  };
  absl::StatusOr<ProbeVolume> first = Bake(job, options);
  ASSERT_EQ(first.status().code(), absl::StatusCode::kCancelled);
  ASSERT_FALSE(done.empty());
  ASSERT_LT(std::count(done.begin(), done.end(), uint8_t{1}), job.grid.ProbeCount());
  BakeOptions resume;
  resume.threads = 1;
  resume.coefficientErrors = true;
  resume.resumeFrom = &partial;
  resume.resumeDone = &done;
  absl::StatusOr<ProbeVolume> second = Bake(job, resume);
  ASSERT_TRUE(second.ok()) << second.status();
  ExpectIdentical(full, *second);
}

TEST(Cancellation, StopsPromptly) {
  BakeJob job = DemoLikeScene();
  job.settings.samplesPerProbe = 1 << 22;  // minutes of work
  std::atomic<bool> cancel{false};
  BakeOptions options;
  options.threads = 2;
  options.cancel = &cancel;
  options.progressIntervalSeconds = 0.05;
  const auto start = std::chrono::steady_clock::now();
  options.progress = [&](const BakeProgress& p) {
    if (p.elapsedSeconds > 0.2) cancel = true;
  };
  absl::StatusOr<ProbeVolume> v = Bake(job, options);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(v.status().code(), absl::StatusCode::kCancelled);
  // Workers look at the flag every 64 samples; a sample is microseconds.
  EXPECT_LT(seconds, 5.0);
}

TEST(Adaptive, StopsWhenTheTargetIsMetAndNotBefore) {
  BakeJob job = DemoLikeScene();
  job.settings.samplesPerProbe = 1 << 16;
  job.settings.batches = 64;
  job.settings.targetRelError = 0.02;
  const ProbeVolume v = BakeOrDie(job, 2);
  int64_t early = 0;
  for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
    if (!v.active[p]) continue;
    if (v.sampleCount[p] < job.settings.samplesPerProbe) {
      ++early;
      // It stopped on the confidence bound of its error, not the estimate (bake.h): with k
      // batches of 1024 samples, stdError (1 + 2 / sqrt(2 (k - 1))) <= target.
      const int k = int(v.sampleCount[p] / 1024);
      EXPECT_LE(AdaptiveErrorBound(v.stdError[p], k), 0.02 * (1 + 1e-6))
          << "probe " << p << " stopped before meeting the target";
      // The first round (8 batches) can never end sampling alone: a second must confirm it.
      EXPECT_GE(k, 10) << "probe " << p << " stopped without a confirming round";
      EXPECT_GT(AdaptiveErrorBound(v.stdError[p], k), v.stdError[p] * 1.1) << "no margin";
    }
  }
  EXPECT_GT(early, 0) << "no probe met a 2% target within 65536 samples";
}

// With visibility, an adaptive probe samples at least kMinVisibilitySamples (4 rays a texel of
// its moments) even where its error target is met sooner: at a loose 20% target, 512 samples in
// 64 batches, every probe would stop after its first two rounds (80 samples) without the floor.
TEST(Adaptive, WithVisibilityAProbeSamplesEnoughForItsMoments) {
  BakeJob job = DemoLikeScene();
  job.settings.samplesPerProbe = 512;
  job.settings.batches = 64;
  job.settings.targetRelError = 0.2;
  job.settings.visibility = true;
  const ProbeVolume v = BakeOrDie(job, 2);
  job.settings.visibility = false;
  const ProbeVolume without = BakeOrDie(job, 2);
  int64_t early = 0, earlyWithout = 0;
  for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
    if (!v.active[p]) continue;
    EXPECT_GE(v.sampleCount[p], float(kMinVisibilitySamples)) << "probe " << p;
    early += v.sampleCount[p] < job.settings.samplesPerProbe;
    earlyWithout += without.sampleCount[p] < float(kMinVisibilitySamples);
  }
  // The floor is what holds them: without visibility probes stop sooner.
  EXPECT_GT(earlyWithout, 0)
      << "no probe met the target before 256 samples: the test tests nothing";
  EXPECT_GT(early, 0) << "no probe stopped before the cap";
}

// A closed room (albedo 0.7) lit only through a 10 cm hole in its ceiling by a bright sky, at the
// PREVIEW preset's numbers: most probes' first two rounds (80 samples) find no light at all. Such
// a probe's error is unknown, not zero: it must sample on, and a probe that ends black says so
// with an infinite error (it stopped at 80 samples, black with error 0, before the fix).
TEST(Adaptive, AProbeThatHasSeenNoLightYetSamplesOn) {
  BakeJob job = MakeJob(2, 512, {0, 0, 0});
  job.grid.origin = {-0.75, -0.75, -0.75};
  job.grid.counts[0] = job.grid.counts[1] = job.grid.counts[2] = 4;
  job.grid.spacing = {0.5, 0.5, 0.5};
  job.grid.placement = Placement::kAll;
  job.settings.batches = 64;
  job.settings.maxDepth = 6;
  job.settings.targetRelError = 0.05;
  job.scene.environment = {Environment::Kind::kUniform, {1000, 1000, 1000}, nullptr};
  const uint32_t grey = AddMaterial(&job.scene, {0.7, 0.7, 0.7});
  const double h = 0.05;
  // Each listed counter-clockwise seen from outside, added reversed: front faces point in.
  auto wall = [&](Vec3d a, Vec3d b, Vec3d c, Vec3d d) { AddQuad(&job.scene, d, c, b, a, grey); };
  // Floor, four walls, and the ceiling around the hole [-h, h]^2.
  wall({-1, 1, -1}, {1, 1, -1}, {1, -1, -1}, {-1, -1, -1});
  wall({-1, -1, -1}, {1, -1, -1}, {1, -1, 1}, {-1, -1, 1});
  wall({1, 1, -1}, {-1, 1, -1}, {-1, 1, 1}, {1, 1, 1});
  wall({-1, 1, -1}, {-1, -1, -1}, {-1, -1, 1}, {-1, 1, 1});
  wall({1, -1, -1}, {1, 1, -1}, {1, 1, 1}, {1, -1, 1});
  wall({-1, -1, 1}, {1, -1, 1}, {1, -h, 1}, {-1, -h, 1});
  wall({-1, h, 1}, {1, h, 1}, {1, 1, 1}, {-1, 1, 1});
  wall({-1, -h, 1}, {-h, -h, 1}, {-h, h, 1}, {-1, h, 1});
  wall({h, -h, 1}, {1, -h, 1}, {1, h, 1}, {h, h, 1});
  BakeOptions options;
  BakeProgress last;
  options.progress = [&](const BakeProgress& p) { last = p; };
  const absl::StatusOr<ProbeVolume> baked = Bake(job, options);
  ASSERT_TRUE(baked.ok()) << baked.status();
  const ProbeVolume& v = *baked;
  int black = 0, earlyStops = 0, unknown = 0;
  double knownSum = 0;
  for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
    ASSERT_TRUE(v.active[p]);
    if (std::isinf(v.stdError[p]))
      ++unknown;
    else
      knownSum += v.stdError[p];
    const Vec3f l0(v.radiance[0][3 * p], v.radiance[0][3 * p + 1], v.radiance[0][3 * p + 2]);
    if (v.sampleCount[p] < job.settings.samplesPerProbe) {
      ++earlyStops;
      EXPECT_GT(l0.x, 0) << "probe " << p << " stopped black at " << v.sampleCount[p];
      EXPECT_GT(v.stdError[p], 0) << "probe " << p;
    }
    if (l0.x == 0 && l0.y == 0 && l0.z == 0) {
      ++black;
      EXPECT_TRUE(std::isinf(v.stdError[p])) << "probe " << p << " is black with a known error";
    }
  }
  // Not vacuous: at this seed some probes end black (8 of 64), most find light.
  RecordProperty("black", black);
  RecordProperty("earlyStops", earlyStops);
  EXPECT_GT(black, 0);
  EXPECT_LT(black, 64);
  // The job's error estimate averages the known errors and counts the unknown ones apart.
  EXPECT_EQ(last.probesErrorUnknown, unknown);
  // The volume's errors are floats (rounding 6e-8 each), the estimate averages their doubles.
  EXPECT_NEAR(last.errorEstimate, knownSum / (64 - unknown), 1e-6 * last.errorEstimate);
}

// Where no sample can be non-zero (a point light with nothing to scatter it: no mesh, or black
// ones; or no light at all), black batches are exact: error 0, and an adaptive bake stops at its
// first confirming round.
TEST(Adaptive, AProbeWhoseSamplesAreZeroByConstructionIsExact) {
  for (const bool pointLight : {true, false}) {
    BakeJob job = MakeJob(2, 512, {0, 0, 0});
    job.settings.batches = 64;
    job.settings.targetRelError = 0.05;
    if (pointLight) job.scene.lights.push_back(PointLight{{0, 0, 2}, {10, 10, 10}});
    AddQuad(&job.scene, {-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
            AddMaterial(&job.scene, {0, 0, 0}));  // a black floor scatters nothing
    const ProbeVolume v = BakeOrDie(job);
    EXPECT_EQ(v.stdError[0], 0.0f) << "point light: " << pointLight;
    EXPECT_EQ(v.sampleCount[0], 10 * 512 / 64) << "point light: " << pointLight;
    EXPECT_EQ(v.radiance[0][0] > 0, pointLight);
  }
}

TEST(Extremes, TinyAndHugeRadianceInOneScene) {
  // Two closed furnace boxes in one scene, emitting 1e-12 and 1e12: both probes get
  // Le / (1 - rho) exactly in expectation, neither underflows nor overflows.
  BakeJob job = MakeJob(2, 2048, {0, 0, 0});
  job.grid.counts[0] = 2;
  job.grid.spacing = {10, 1, 1};
  job.settings.maxDepth = 60;
  const Vec3d rho{0.5, 0.5, 0.5};
  AddBox(&job.scene, {-1, -1, -1}, {1, 1, 1}, AddMaterial(&job.scene, rho, {1e-12, 1e-12, 1e-12}),
         true);
  AddBox(&job.scene, {9, -1, -1}, {11, 1, 1}, AddMaterial(&job.scene, rho, {1e12, 1e12, 1e12}),
         true);
  const ProbeVolume v = BakeOrDie(job);
  const std::vector<double> uniform = CapProjection(2, {0, 0, 1}, -1);
  ExpectProjection(Probe(v, 0), uniform, Vec3d{2e-12, 2e-12, 2e-12}, "1e-12 furnace");
  ExpectProjection(Probe(v, 1), uniform, Vec3d{2e12, 2e12, 2e12}, "1e12 furnace");
}

TEST(Extremes, LightTooCloseForTheVolumesFloatsFailsTheBakeNamingTheProbe) {
  // I = 1e30 (the largest a job may give) at d = 1e-5: I / d^2 = 1e40, past float's 3.4e38. It
  // was written as inf with std_error 0 (black-box maths audit); at d = 1e-3 (1e36) it fits.
  for (const double d : {1e-3, 1e-5}) {
    BakeJob job = MakeJob(1, 16, {0, 0, 0});
    job.grid.counts[0] = 2;
    job.grid.spacing = {1, 1, 1};
    job.scene.lights.push_back(PointLight{{1, 0, d}, {1e30, 1e30, 1e30}});
    BakeOptions options;
    options.threads = 1;
    const absl::StatusOr<ProbeVolume> v = Bake(job, options);
    if (d > 1e-4) {
      ASSERT_TRUE(v.ok()) << v.status();
      EXPECT_TRUE(std::isfinite(v->radiance[0][3])) << v->radiance[0][3];
      EXPECT_GT(v->radiance[0][3], 1e35);
      continue;
    }
    ASSERT_FALSE(v.ok());
    EXPECT_EQ(v.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(v.status().message().find("grid: the probe (1, 0, 0) at (1, 0, 0) receives more "
                                        "light than the volume's 32-bit floats hold"),
              std::string::npos)
        << v.status();
  }
}

TEST(Extremes, ProbeNextToAWallAndFarFromTheOrigin) {
  // A probe 1e-5 above a black floor under a uniform sky sees exactly the upper hemisphere: no ray
  // leaks under the floor. Then the same with the whole scene moved by 1e5 units.
  for (double shift : {0.0, 1e5}) {
    const Vec3d t{shift, -shift, shift};
    BakeJob job = MakeJob(3, 4096, Vec3d{0.25, 0.5, 1e-5} + t);
    job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
    const uint32_t black = AddMaterial(&job.scene, {0, 0, 0});
    const double s = 1e3;
    AddQuad(&job.scene, Vec3d{-s, -s, 0} + t, Vec3d{s, -s, 0} + t, Vec3d{s, s, 0} + t,
            Vec3d{-s, s, 0} + t, black);
    const ProbeResult r = Probe(BakeOrDie(job), 0);
    EXPECT_EQ(r.validity, 1);
    ExpectProjection(r, CapProjection(3, {0, 0, 1}, 0), {1, 1, 1},
                     "wall probe, shift " + std::to_string(shift), 2 * kPi * 1e-3 * 1.5);
  }
}

TEST(Extremes, WhiteGroundFarFromTheOriginHasNoAcne) {
  // Bounce rays spawned off a floor at 1e5 units must not hit it again: the reflected radiance
  // rho L below the horizon (WhiteGroundReflectsTheSkyOnce) survives the shift.
  const double shift = 1e5;
  const Vec3d t{shift, shift, shift};
  BakeJob job = MakeJob(2, 4096, Vec3d{0, 0, 0.5} + t);
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  const uint32_t white = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  const double s = 1e4;
  AddQuad(&job.scene, Vec3d{-s, -s, 0} + t, Vec3d{s, -s, 0} + t, Vec3d{s, s, 0} + t,
          Vec3d{-s, s, 0} + t, white);
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  const std::vector<double> up = CapProjection(2, {0, 0, 1}, 0),
                            down = CapProjection(2, {0, 0, -1}, 0);
  std::vector<double> expected(up.size());
  for (size_t c = 0; c < up.size(); ++c) expected[c] = up[c] + 0.5 * down[c];
  ExpectProjection(r, expected, {1, 1, 1}, "far white ground", 2 * kPi * 1e-4 * 1.5);
}

// A large tilted square through the local origin (the centre of the scene's bounds): its
// vertices are at ~s while the points shaded near the probe are at ~0.5, so float error on the
// surface scales with s, not with the hit point (ray_offset.h). Axis-aligned floors do not show
// this: their coordinate along the normal is exact in float.
Vec3d TiltedNormal() {
  return Normalize(Vec3d{0.3, 0.2, 1});
}
void AddTiltedSquare(Scene* scene, double s, uint32_t material, bool facingUp) {
  const Framed f = Framed::FromZ(TiltedNormal());
  Vec3d c[4] = {(-f.s - f.t) * s, (f.s - f.t) * s, (f.s + f.t) * s, (-f.s + f.t) * s};
  if (!facingUp) std::swap(c[1], c[3]);
  AddQuad(scene, c[0], c[1], c[2], c[3], material);
}

TEST(Extremes, LargeTiltedFloorAtTheLocalOriginHasNoAcne) {
  // White floor under a uniform sky: radiance 1 from above, rho = 0.5 from below, as
  // WhiteGroundFarFromTheOriginHasNoAcne. Bounce rays that hit the floor again lose that light
  // (5% of L00 at s = 1e3 before the fix). The finite floor lets the sky through below the
  // horizon within an angle h / s of it: at most 2 pi (h / s) sr, each direction off by
  // (1 - 0.5) |Y| <= 0.5 * 1.1 (|Y_lm| <= 1.093 up to l = 2).
  const Vec3d n = TiltedNormal();
  const double h = 0.5;
  for (double s : {1e3, 2e4}) {
    BakeJob job = MakeJob(2, 4096, n * h);
    job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
    AddTiltedSquare(&job.scene, s, AddMaterial(&job.scene, {0.5, 0.5, 0.5}), true);
    const std::vector<double> up = CapProjection(2, n, 0), down = CapProjection(2, -n, 0);
    std::vector<double> expected(up.size());
    for (size_t c = 0; c < up.size(); ++c) expected[c] = up[c] + 0.5 * down[c];
    ExpectProjection(Probe(BakeOrDie(job), 0), expected, {1, 1, 1},
                     "tilted white floor, half-size " + std::to_string(s),
                     2 * kPi * (h / s) * 0.5 * 1.1);
  }
}

TEST(Extremes, AProbeOnAFloorSeesItsFrontSide) {
  // The white tilted floor under a uniform sky, with the probe on it: exactly on its plane, or
  // behind it by 2^-24 s, less than the tracer resolves (2^-22 of the floor's coordinates,
  // SurfaceResolution), so moved to its front side in both cases. It must bake as just above it
  // (radiance 1 from above, 0.5 from below), not see the sky through the floor (which gave L00 its
  // full-sphere value and no gradient). The probe then sits a ray offset, at most 2^-17 s, above
  // the floor: the sky shows below its horizon within 2 pi (2^-17 s / s) sr, each direction off by
  // 0.5 * 1.1 as in the test above.
  const Vec3d n = TiltedNormal();
  const Framed f = Framed::FromZ(n);
  for (double s : {1.0, 1e3}) {
    // At the floor's centre (the local origin) and at a point of it away from there.
    for (const Vec3d& on : {Vec3d{}, f.s * (0.37 * s) - f.t * (0.21 * s)}) {
      for (double behind : {0.0, 0x1p-24 * s}) {
        BakeJob job = MakeJob(2, 4096, on - n * behind);
        job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
        AddTiltedSquare(&job.scene, s, AddMaterial(&job.scene, {0.5, 0.5, 0.5}), true);
        const std::vector<double> up = CapProjection(2, n, 0), down = CapProjection(2, -n, 0);
        std::vector<double> expected(up.size());
        for (size_t c = 0; c < up.size(); ++c) expected[c] = up[c] + 0.5 * down[c];
        const ProbeResult r = Probe(BakeOrDie(job), 0);
        EXPECT_EQ(r.validity, 1.0f);
        ExpectProjection(r, expected, {1, 1, 1},
                         "probe on a tilted white floor, half-size " + std::to_string(s) +
                             ", behind it by " + std::to_string(behind) + ", " +
                             std::to_string(Length(on)) + " from its centre",
                         2 * kPi * 0x1p-17 * 0.5 * 1.1);
      }
    }
  }
}

TEST(Extremes, AProbeInACornerSeesOnlyTheOpenOctant) {
  // Three black quads meeting at the origin (a floor and two walls, fronts facing +x, +y, +z),
  // uniform sky, the probe at their common corner: it sees the sky over the octant x, y, z > 0
  // alone, L00 = (4 pi / 8) Y00. Moved off each surface in turn, it sits a ray offset (at most
  // 2^-17 s) from each; the sky then shows past the quads' far edges only within about
  // 3 * 2 pi * 2^-17 sr, each direction off by Y00.
  const double s = 10;
  BakeJob job = MakeJob(0, 4096, {0, 0, 0});
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  const uint32_t black = AddMaterial(&job.scene, {0, 0, 0});
  AddQuad(&job.scene, {0, 0, 0}, {s, 0, 0}, {s, s, 0}, {0, s, 0}, black);  // floor, +z
  AddQuad(&job.scene, {0, 0, 0}, {0, s, 0}, {0, s, s}, {0, 0, s}, black);  // wall, +x
  AddQuad(&job.scene, {0, 0, 0}, {0, 0, s}, {s, 0, s}, {s, 0, 0}, black);  // wall, +y
  const double y00 = 0.5 / std::sqrt(kPi);
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  EXPECT_EQ(r.validity, 1.0f);
  ExpectProjection(r, {4 * kPi / 8 * y00}, {1, 1, 1}, "probe in a corner",
                   3 * 2 * kPi * 0x1p-17 * y00);
}

TEST(Extremes, ShadowRaysReachALargeTiltedLightAtTheLocalOrigin) {
  // A large one-sided emitting square 0.5 above the probe, facing it, and nothing else: the
  // upper hemisphere (about the square's normal) has radiance 1. Shadow rays aimed at points on it
  // must stop short of it by the float error of its vertices (~s), not of the points (~0.5), or
  // they hit the light itself and NEE loses its share (FloatSlack, LightSample::vertexScale).
  // Once as a rect light, once as an emissive mesh. Allowance: the square's finite size, as above
  // (each missing direction off by 1 |Y|).
  const Vec3d n = TiltedNormal();
  const double h = 0.5;
  const double s = 2e4;
  for (bool mesh : {false, true}) {
    BakeJob job = MakeJob(2, 4096, -n * h);
    if (mesh) {
      AddTiltedSquare(&job.scene, s, AddMaterial(&job.scene, {0, 0, 0}, {1, 1, 1}), false);
    } else {
      const Framed f = Framed::FromZ(n);
      // edge1 x edge2 = -n: emits down, toward the probe.
      job.scene.lights.push_back(
          RectLight{(-f.s - f.t) * s, f.t * (2 * s), f.s * (2 * s), {1, 1, 1}, false});
    }
    ExpectProjection(Probe(BakeOrDie(job), 0), CapProjection(2, n, 0), {1, 1, 1},
                     mesh ? "large tilted emissive mesh" : "large tilted rect light",
                     2 * kPi * (h / s) * 1.1);
  }
}

TEST(Extremes, ATiltedSquareAtTheSceneSpanLimitBakesRight) {
  // The emissive square of the test above, as wide as kMaxSceneSpan allows on its widest axis,
  // with the probe 1e-4 of its half-size below it (the tracer resolves it to ~2^-22 of that). Its
  // vertices' products overflow float from ~1e13, where it vanished; the build refuses spans past
  // 2e12 (build_test: ScenesSpanningMoreThanTheTracerHoldsAreRefused).
  const Vec3d n = TiltedNormal();
  const Framed f = Framed::FromZ(n);
  double widest = 0;
  for (int a = 0; a < 3; ++a) widest = std::max(widest, std::abs(f.s[a]) + std::abs(f.t[a]));
  const double s = kMaxSceneSpan / (2 * widest);
  const double h = 1e-4 * s;
  BakeJob job = MakeJob(2, 4096, -n * h);
  AddTiltedSquare(&job.scene, s, AddMaterial(&job.scene, {0, 0, 0}, {1, 1, 1}), false);
  ExpectProjection(Probe(BakeOrDie(job), 0), CapProjection(2, n, 0), {1, 1, 1},
                   "tilted emissive square at the span limit", 2 * kPi * (h / s) * 1.1);
}

TEST(Extremes, OrderEightAgainstACap) {
  BakeJob job = MakeJob(8, 8192);
  job.scene.lights.push_back(SphereLight{{0.5, 0.5, 1.5}, 0.6, {1, 1, 1}});
  const Vec3d c{0.5, 0.5, 1.5};
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, CapProjection(8, Normalize(c), std::sqrt(1 - 0.36 / LengthSquared(c))),
                   {1, 1, 1}, "order 8 sphere");
}

}  // namespace
}  // namespace probebake
