// The probe integrator's packet tracing (core/src/bake/probe_integrator.h): tracing a group of
// samples together, its rays as sorted packets, changes which rays Embree traverses together,
// never a sample's result, its random numbers or the order in which samples are summed. Samples
// traced one at a time (packets off) are the reference.
#include "core/src/bake/probe_integrator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "bake_test_util.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/tracer_scene.h"

namespace probebake {
namespace {

using namespace probebake::testing;

struct BatchResult {
  std::vector<double> sum;
  int64_t rays = 0, samples = 0;
};

BatchResult Trace(const ProbeIntegrator& integrator, const TracerScene& tracer, Vec3d world,
                  int64_t count, const BakeSettings& settings) {
  BatchResult r;
  r.sum.assign(size_t(3 * ShCoeffCount(settings.shOrder)), 0.0);
  SharedCounters counters;
  EXPECT_TRUE(integrator.TraceBatch(world - tracer.offset(), /*probeKey=*/17, /*batch=*/3, count,
                                    r.sum, &counters, nullptr));
  r.rays = counters.rays.load();
  r.samples = counters.samples.load();
  return r;
}

// Every estimator and sampler, batches of one chunk, a chunk and a part, several chunks, and
// probes in the open, under the roof and beside the box, and paths that end at the probe's hit
// (maxDepth 0), after the first vertex (maxDepth 1), by roulette from the first vertex on, or
// only at depth 32 (no roulette: the waves' sampler restarts past the Sobol sampler's cached
// seeds): packets (at the probe and at every vertex) and samples traced alone agree. A
// permutation mix-up between samples, a lost shadow ray or a skipped random dimension changes
// at least one sample's contribution, at least ~1/count of the largest coefficient here
// (thousands of times the tolerance). The tolerance allows the hits of Embree's packet kernel to
// differ from its single-ray kernel's in the last float bit (2^-24 relative), which moves a
// path's later vertices by as little (on this project's machines the two agree bit for bit).
TEST(ProbeIntegrator, PacketsChangeNoResult) {
  const Scene scene = RoomWithOpening();
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  const LightSet lights(scene, **tracer);
  const Estimator estimators[] = {Estimator::kNeeMis, Estimator::kLightSampling,
                                  Estimator::kDirectionSampling};
  const SamplerKind samplers[] = {SamplerKind::kSobol, SamplerKind::kIndependent};
  const Vec3d probes[] = {{-2, 2, 1.5}, {2.5, -2, 2}, {1, 0.5, 0.6}};
  const int64_t counts[] = {128, 256, 300, 1000};
  struct Depth {
    int maxDepth, rrMinDepth;
  };
  const Depth depths[] = {
      {BakeSettings{}.maxDepth, BakeSettings{}.rrMinDepth}, {0, 1}, {1, 1}, {8, 1}, {32, 64}};
  for (Estimator estimator : estimators) {
    for (SamplerKind sampler : samplers) {
      for (const Depth& depth : depths) {
        BakeSettings settings;
        settings.estimator = estimator;
        settings.sampler = sampler;
        settings.maxDepth = depth.maxDepth;
        settings.rrMinDepth = depth.rrMinDepth;
        const ProbeIntegrator packets(scene, **tracer, lights, settings, /*packets=*/true);
        const ProbeIntegrator single(scene, **tracer, lights, settings, /*packets=*/false);
        for (const Vec3d& p : probes) {
          for (int64_t count : counts) {
            SCOPED_TRACE(::testing::Message()
                         << "estimator " << int(estimator) << ", sampler " << int(sampler)
                         << ", maxDepth " << depth.maxDepth << ", rrMinDepth " << depth.rrMinDepth
                         << ", probe " << p.x << " " << p.y << " " << p.z << ", " << count
                         << " samples");
            const BatchResult a = Trace(packets, **tracer, p, count, settings);
            const BatchResult b = Trace(single, **tracer, p, count, settings);
            EXPECT_EQ(a.samples, count);
            EXPECT_EQ(a.samples, b.samples);
            EXPECT_EQ(a.rays, b.rays);
            double scale = 0;
            for (double v : b.sum) scale = std::max(scale, std::fabs(v));
            ASSERT_GT(scale, 0);
            for (size_t i = 0; i < a.sum.size(); ++i)
              EXPECT_NEAR(a.sum[i], b.sum[i], 1e-5 * scale) << "coefficient " << i / 3;
          }
        }
      }
    }
  }
}

// Batches traced together by TraceBatches (their probe rays share packets) sum as each would
// alone, whatever their sizes (an empty one among them, chunks that straddle batches), and
// count the same work. Tolerance as above.
TEST(ProbeIntegrator, BatchesTracedTogetherSumAsAlone) {
  const Scene scene = RoomWithOpening();
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  const LightSet lights(scene, **tracer);
  const BakeSettings settings;
  const ProbeIntegrator integrator(scene, **tracer, lights, settings);
  const Vec3d p = Vec3d{-1.5, 1.8, 1.2} - (*tracer)->offset();
  const int64_t counts[] = {64, 64, 0, 37, 91, 200};
  const size_t coeffs = size_t(3 * ShCoeffCount(settings.shOrder));
  constexpr uint32_t kFirstBatch = 5;

  std::vector<std::vector<double>> together(std::size(counts), std::vector<double>(coeffs));
  std::vector<ProbeIntegrator::BatchWork> work;
  for (size_t k = 0; k < std::size(counts); ++k) work.push_back({counts[k], together[k]});
  SharedCounters togetherCounters;
  ASSERT_TRUE(integrator.TraceBatches(p, 17, kFirstBatch, work, &togetherCounters, nullptr));

  SharedCounters aloneCounters;
  for (size_t k = 0; k < std::size(counts); ++k) {
    SCOPED_TRACE(::testing::Message() << "batch " << k);
    std::vector<double> alone(coeffs);
    ASSERT_TRUE(integrator.TraceBatch(p, 17, kFirstBatch + uint32_t(k), counts[k], alone,
                                      &aloneCounters, nullptr));
    double scale = 0;
    for (double v : alone) scale = std::max(scale, std::fabs(v));
    if (counts[k] == 0) {
      EXPECT_EQ(scale, 0);
      EXPECT_EQ(together[k], alone);
      continue;
    }
    ASSERT_GT(scale, 0);
    for (size_t i = 0; i < coeffs; ++i)
      EXPECT_NEAR(together[k][i], alone[i], 1e-5 * scale) << "coefficient " << i / 3;
  }
  EXPECT_EQ(togetherCounters.samples.load(), aloneCounters.samples.load());
  EXPECT_EQ(togetherCounters.rays.load(), aloneCounters.rays.load());
}

}  // namespace
}  // namespace probebake
