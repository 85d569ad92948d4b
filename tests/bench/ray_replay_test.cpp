// The bench's ray recorder and replay (bench_ray_replay.h): the recorder sees exactly the rays the
// tracer counts, kind by kind, and raw Embree, given the recorded rays as the tracer cast them,
// answers as the tracer's Embree did (hit or miss and the hit distance to the bit; occluded or
// not). A hook that missed a wave's rays, reported a packet's lanes out of order, recorded a ray
// other than the one traced (another origin, its direction rounded differently, another tfar)
// or the wrong answer fails one of these.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "bake/bake_test_util.h"
#include "bench_ray_replay.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/probe_integrator.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/bake/bake.h"

namespace probebake::bench {
namespace {

using namespace probebake::testing;

struct Case {
  const char* name;
  bool medium;
  int64_t count;  // samples per call: >= 128 traces packets, fewer one ray at a time
};

// Every ray of calls at three probes, recorded, against the tracer's counters; then replayed.
TEST(RayReplay, RecorderSeesTheTracersRaysAndEmbreeAnswersAlike) {
  const Case cases[] = {{"packets", false, 1000}, {"alone", false, 100}, {"medium", true, 300}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    Scene scene = RoomWithOpening();
    if (c.medium)
      scene.medium = Medium{{0.02, 0.02, 0.02}, {0.1, 0.1, 0.1}, 0.3, {-4, -3, 0}, {4, 3, 3}};
    auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
    ASSERT_TRUE(tracer.ok()) << tracer.status();
    const LightSet lights(scene, **tracer);
    BakeSettings settings;
    settings.shOrder = 2;
    settings.maxDepth = 8;
    settings.seed = 5;
    ProbeIntegrator integrator(scene, **tracer, lights, settings);
    RayRecorder recorder(BakeSection{1});
    integrator.SetRayObserver(&recorder);
    SharedCounters counters;
    std::vector<double> sum(size_t(3 * ShCoeffCount(settings.shOrder)));
    const Vec3d probes[] = {{-2, 2, 1.5}, {2.5, -2, 2}, {1, 0.5, 0.6}};
    for (uint32_t p = 0; p < 3; ++p)
      ASSERT_TRUE(integrator.TraceBatch(probes[p] - (*tracer)->offset(), 17 + p, p, c.count, sum,
                                        &counters, nullptr));
    EXPECT_EQ(recorder.calls(), 3);

    // Counts, kind by kind: one first ray per sample, the shadow rays, the rest continuations.
    const int64_t rays = counters.rays.load(), samples = counters.samples.load(),
                  shadow = counters.shadowRays.load();
    EXPECT_EQ(samples, 3 * c.count);
    EXPECT_EQ(int64_t(recorder.rays().size()), rays);
    EXPECT_EQ(recorder.Count(RayKind::kProbe, false), samples);
    EXPECT_EQ(recorder.Count(RayKind::kShadow, false), shadow);
    EXPECT_EQ(recorder.Count(RayKind::kBounce, false), rays - samples - shadow);
    EXPECT_GT(recorder.Count(RayKind::kBounce, false), samples / 2);
    EXPECT_GT(recorder.Count(RayKind::kShadow, false), samples / 2);
    int64_t packed = 0;
    for (const ObservedRay& r : recorder.rays()) packed += r.packed;
    if (c.count >= 128 && !c.medium) {
      EXPECT_GT(packed, int64_t(recorder.rays().size()) / 2);
    } else {
      EXPECT_EQ(packed, 0);
    }

    // Replayed as cast: the same answers, hit distances to the bit.
    absl::StatusOr<RayReplay> replay = RayReplay::Build(scene, recorder.rays());
    ASSERT_TRUE(replay.ok()) << replay.status();
    const std::vector<std::pair<bool, float>> answers = replay->ReplayAsCast();
    ASSERT_EQ(answers.size(), recorder.rays().size());
    int64_t compared = 0, differ = 0;
    int64_t hits[kRayKinds] = {}, misses[kRayKinds] = {};
    for (size_t i = 0; i < answers.size(); ++i) {
      const ObservedRay& r = recorder.rays()[i];
      if (!r.cast) continue;
      ++compared;
      (r.hit ? hits : misses)[int(r.kind)]++;
      const bool same = answers[i].first == r.hit &&
                        (r.kind == RayKind::kShadow || !r.hit || answers[i].second == r.tHit);
      if (!same && differ++ < 5)
        ADD_FAILURE() << RayKindName(r.kind) << " ray " << i << ": tracer " << r.hit << " at "
                      << r.tHit << ", replay " << answers[i].first << " at " << answers[i].second;
    }
    EXPECT_EQ(differ, 0) << "of " << compared;
    // Both answers occur for every kind, so the comparison could have failed either way.
    for (int k = 0; k < kRayKinds; ++k) {
      EXPECT_GT(hits[k], 0) << RayKindName(RayKind(k));
      EXPECT_GT(misses[k], 0) << RayKindName(RayKind(k));
    }
  }
}

// An observer changes nothing in a bake's bits, and sees the sampling's rays of the whole bake.
TEST(RayReplay, ObservedBakeHasTheSameBits) {
  BakeJob job = MakeJob(2, 512, {-2, -1, 1});
  job.scene = RoomWithOpening();
  job.grid.counts[0] = 3;
  job.grid.counts[1] = 2;
  job.grid.spacing = {2, 2, 1};
  BakeOptions options;
  options.threads = 1;
  const absl::StatusOr<ProbeVolume> plain = Bake(job, options);
  ASSERT_TRUE(plain.ok()) << plain.status();
  RayRecorder recorder(BakeSection{1});
  options.rayObserver = &recorder;
  const absl::StatusOr<ProbeVolume> observed = Bake(job, options);
  ASSERT_TRUE(observed.ok()) << observed.status();
  ASSERT_EQ(plain->CoeffCount(), observed->CoeffCount());
  for (int c = 0; c < plain->CoeffCount(); ++c)
    EXPECT_EQ(plain->radiance[c], observed->radiance[c]) << "coefficient " << c;
  EXPECT_EQ(plain->stdError, observed->stdError);
  EXPECT_EQ(plain->stats.rays, observed->stats.rays);
  // Every probe's sampling: one first ray per sample, and per path of the probe's pilot (the
  // shadow rays' roulette, probe_integrator.h: 512 samples are worth 4 paths); the bake's count
  // adds placement, validity and visibility rays, which the observer does not see.
  const int64_t pilot =
      std::min(ProbeIntegrator::kPilotSamples, 512 / ProbeIntegrator::kPilotDivisor);
  ASSERT_GE(pilot, ProbeIntegrator::kMinPilotSamples);
  EXPECT_EQ(recorder.Count(RayKind::kProbe, false),
            observed->stats.samples + observed->stats.probes * pilot);
  EXPECT_LT(int64_t(recorder.rays().size()), observed->stats.rays);
}

}  // namespace
}  // namespace probebake::bench
