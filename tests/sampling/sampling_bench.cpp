// Costs of the sampling primitives the tracer calls per path vertex. Run:
//   build/bin/probebake_sampling_bench
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "probebake/sampling/distribution.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/spherical_rectangle.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

// One StartSample per 8 Get2D calls (a path of a few bounces), reported per Get2D.
template <typename S>
void BM_Get2D(benchmark::State& state) {
  S s(1, Hash(7, 0));
  uint64_t index = 0;
  double sink = 0;
  for (auto _ : state) {
    s.StartSample(index++ & 0xffffffffu);
    for (int d = 0; d < 8; ++d) {
      const Vec2d u = s.Get2D();
      sink += u.x + u.y;
    }
  }
  benchmark::DoNotOptimize(sink);
  state.SetItemsProcessed(state.iterations() * 8);
}
BENCHMARK(BM_Get2D<SobolSampler>);
BENCHMARK(BM_Get2D<IndependentSampler>);

template <typename S>
void BM_Get1D(benchmark::State& state) {
  S s(1, Hash(7, 0));
  uint64_t index = 0;
  double sink = 0;
  for (auto _ : state) {
    s.StartSample(index++ & 0xffffffffu);
    for (int d = 0; d < 8; ++d) sink += s.Get1D();
  }
  benchmark::DoNotOptimize(sink);
  state.SetItemsProcessed(state.iterations() * 8);
}
BENCHMARK(BM_Get1D<SobolSampler>);
BENCHMARK(BM_Get1D<IndependentSampler>);

// Warps fed from a precomputed table of u so only the warp is timed.
std::vector<Vec2d> Us() {
  std::vector<Vec2d> u(4096);
  IndependentSampler s(3, 3);
  for (int i = 0; i < 4096; ++i) {
    s.StartSample(i);
    u[i] = s.Get2D();
  }
  return u;
}

template <typename F>
void RunWarp(benchmark::State& state, F f) {
  const std::vector<Vec2d> u = Us();
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(f(u[i]));
    i = (i + 1) & 4095;
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_UniformSphere(benchmark::State& st) {
  RunWarp(st, [](Vec2d u) { return SampleUniformSphere(u); });
}
void BM_CosineHemisphere(benchmark::State& st) {
  RunWarp(st, [](Vec2d u) { return SampleCosineHemisphere(u); });
}
void BM_UniformCone(benchmark::State& st) {
  RunWarp(st, [](Vec2d u) { return SampleUniformCone(u, 0.99998918); });
}
void BM_UniformTriangle(benchmark::State& st) {
  RunWarp(st, [](Vec2d u) { return SampleUniformTriangle(u); });
}
void BM_HenyeyGreenstein(benchmark::State& st) {
  RunWarp(st, [](Vec2d u) { return SampleHenyeyGreenstein(u, 0.7); });
}
void BM_InvertUniformSphere(benchmark::State& st) {
  RunWarp(st, [](Vec2d u) { return InvertUniformSphereSample(SampleUniformSphere(u)); });
}
void BM_SphericalRectangle(benchmark::State& st) {
  RunWarp(st, [](Vec2d u) {
    return SampleSphericalRectangle(u, {0.3, 0.2, 1}, {-0.5, -0.5, 0}, {1, 0, 0}, {0, 1, 0});
  });
}
BENCHMARK(BM_UniformSphere);
BENCHMARK(BM_CosineHemisphere);
BENCHMARK(BM_UniformCone);
BENCHMARK(BM_UniformTriangle);
BENCHMARK(BM_HenyeyGreenstein);
BENCHMARK(BM_InvertUniformSphere);
BENCHMARK(BM_SphericalRectangle);

// DiscreteDistribution over state.range(0) weights (log-uniform 1e-6 .. 1e9), random u.
void BM_DiscreteSample(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::vector<double> w(n);
  IndependentSampler s(4, 4);
  for (int i = 0; i < n; ++i) {
    s.StartSample(i);
    w[i] = std::pow(10.0, -6 + 15 * s.Get1D());
  }
  const DiscreteDistribution d(w);
  uint64_t k = 0;
  for (auto _ : state) {
    s.StartSample(n + (k++ & 0xfffffff));
    benchmark::DoNotOptimize(d.Sample(s.Get1D()));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_DiscreteSample)->Arg(1000)->Arg(1000000);

void BM_DiscreteBuild(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::vector<double> w(n);
  for (int i = 0; i < n; ++i) w[i] = 1 + (i % 7);
  for (auto _ : state) benchmark::DoNotOptimize(DiscreteDistribution(w).Total());
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_DiscreteBuild)->Arg(1000000);

// An environment map of range(0) x range(1) texels (cols x rows): texels log-uniform over six
// decades, or (range(2) = 1) a smooth sky, bright toward one horizon, weighted by its rows'
// solid angle like the demo room's 128 x 64 sky.
void BM_PiecewiseConstant2DSample(benchmark::State& state) {
  const int cols = int(state.range(0)), rows = int(state.range(1));
  const bool sky = state.range(2) == 1;
  std::vector<double> w(size_t(rows) * cols);
  IndependentSampler s(5, 5);
  for (int i = 0; i < rows * cols; ++i) {
    s.StartSample(i);
    const double lat = 3.14159265358979 * ((i / cols + 0.5) / rows - 0.5);
    const double lon = 6.28318530717959 * ((i % cols + 0.5) / cols);
    w[i] = sky ? std::cos(lat) * (0.2 + std::exp(4 * std::cos(lon) * std::cos(lat) - 4) +
                                  0.5 * std::max(0.0, std::sin(lat)))
               : std::pow(10.0, -3 + 6 * s.Get1D());
  }
  const PiecewiseConstant2D d(w, rows, cols);
  uint64_t k = 0;
  for (auto _ : state) {
    s.StartSample(rows * cols + (k++ & 0xfffffff));
    benchmark::DoNotOptimize(d.Sample(s.Get2D()));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_PiecewiseConstant2DSample)
    ->Args({1024, 512, 0})
    ->Args({128, 64, 1})
    ->Args({2048, 1024, 1});

}  // namespace
}  // namespace probebake

BENCHMARK_MAIN();
