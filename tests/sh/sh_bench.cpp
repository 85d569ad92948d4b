// Benchmarks of the SH core (run: build/bin/probebake_sh_bench). Time per iteration is the time
// per call. Inputs cycle through 1024 precomputed directions/rotations so nothing is constant.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "probebake/math/mat3.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/sh/sh_projection.h"
#include "probebake/sh/sh_rotation.h"
#include "probebake/sh/sh_window.h"

namespace probebake {
namespace {

constexpr int kInputs = 1024;

template <typename T>
std::vector<Vec3<T>> Directions() {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> n(0, 1);
  std::vector<Vec3<T>> dirs;
  for (int i = 0; i < kInputs; ++i)
    dirs.push_back(Vec3<T>(Normalize(Vec3d{n(rng), n(rng), n(rng)})));
  return dirs;
}

std::vector<Mat3d> Rotations() {
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Mat3d> rs;
  for (int i = 0; i < kInputs; ++i) {
    const Vec3d axis = Normalize(Vec3d{u(rng), u(rng), u(rng) + 0.01});
    rs.push_back(Mat3d::Rotation(axis, 3 * u(rng)));
  }
  return rs;
}

template <typename T>
void BM_EvalShBasis(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto dirs = Directions<T>();
  T out[kMaxShCoeffCount];
  size_t i = 0;
  for (auto _ : state) {
    EvalShBasis(order, dirs[i++ & (kInputs - 1)], out);
    benchmark::DoNotOptimize(out);
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_EvalShBasis<double>)->Arg(1)->Arg(2)->Arg(3)->Arg(4)->Arg(8)->Arg(9);
BENCHMARK(BM_EvalShBasis<float>)->Arg(1)->Arg(2)->Arg(3)->Arg(4)->Arg(8)->Arg(9);

void BM_EvalShBasisRecurrence(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto dirs = Directions<double>();
  double out[kMaxShCoeffCount];
  size_t i = 0;
  for (auto _ : state) {
    EvalShBasisRecurrence(order, dirs[i++ & (kInputs - 1)], out);
    benchmark::DoNotOptimize(out);
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_EvalShBasisRecurrence)->Arg(2)->Arg(3)->Arg(4)->Arg(8);

void BM_RotationBuild(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto rs = Rotations();
  size_t i = 0;
  for (auto _ : state) {
    auto rot = ShRotation::Create(order, rs[i++ & (kInputs - 1)]);
    benchmark::DoNotOptimize(rot);
  }
}
BENCHMARK(BM_RotationBuild)->Arg(1)->Arg(2)->Arg(4)->Arg(8);

void BM_RotationApply(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const ShRotation rot = *ShRotation::Create(order, Rotations()[0]);
  std::vector<double> in(ShCoeffCount(order), 0.5), out(ShCoeffCount(order));
  for (auto _ : state) {
    rot.Apply(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_RotationApply)->Arg(1)->Arg(2)->Arg(4)->Arg(8);

void BM_RotationApplyRgb(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const ShRotation rot = *ShRotation::Create(order, Rotations()[0]);
  std::vector<Vec3d> in(ShCoeffCount(order), Vec3d{0.5, 0.25, 1}), out(ShCoeffCount(order));
  for (auto _ : state) {
    rot.ApplyRgb(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_RotationApplyRgb)->Arg(2)->Arg(8);

void BM_IrradianceAtRgb(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto dirs = Directions<double>();
  std::vector<Vec3d> radiance(ShCoeffCount(order), Vec3d{0.5, 0.25, 1});
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(IrradianceAtRgb(order, radiance, dirs[i++ & (kInputs - 1)]));
  }
}
BENCHMARK(BM_IrradianceAtRgb)->Arg(2)->Arg(8);

void BM_IrradianceAt(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto dirs = Directions<double>();
  std::vector<double> radiance(ShCoeffCount(order), 0.5);
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(IrradianceAt(order, radiance, dirs[i++ & (kInputs - 1)]));
  }
}
BENCHMARK(BM_IrradianceAt)->Arg(2)->Arg(8);

// One radiance sample into an RGB projection: basis evaluation plus the accumulate.
void BM_AccumulateRgb(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto dirs = Directions<double>();
  ShAccumulatorRgb acc(order);
  size_t i = 0;
  for (auto _ : state) {
    acc.Add(dirs[i & (kInputs - 1)], Vec3d{0.5, 0.25, 1.0 + static_cast<double>(i & 7)});
    ++i;
  }
  benchmark::DoNotOptimize(acc.count());
}
BENCHMARK(BM_AccumulateRgb)->Arg(1)->Arg(2)->Arg(4)->Arg(8);

// Auto window of probes lit by one to three directional lights and no ambient light, whose
// irradiance rings negative: the search runs in full (the costly case).
void BM_AutoWindowRinging(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0));
  const auto dirs = Directions<double>();
  std::vector<std::vector<Vec3d>> probes;
  std::vector<double> y(ShCoeffCount(order));
  for (int p = 0; p < 64; ++p) {
    std::vector<Vec3d> radiance(ShCoeffCount(order));
    for (int k = 0; k <= p % 3; ++k) {
      EvalShBasis(order, dirs[3 * p + k], y.data());
      const Vec3d power{1.0 + k, 0.5 + 0.1 * (p % 7), 0.8};
      for (int i = 0; i < ShCoeffCount(order); ++i) radiance[i] += power * y[i];
    }
    probes.push_back(radiance);
  }
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(FindAutoShWindow(order, probes[i++ % probes.size()]));
  }
}
BENCHMARK(BM_AutoWindowRinging)
    ->Arg(1)
    ->Arg(2)
    ->Arg(3)
    ->Arg(4)
    ->Arg(6)
    ->Arg(8)
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace probebake

BENCHMARK_MAIN();
