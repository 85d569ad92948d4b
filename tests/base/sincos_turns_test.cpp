#include "probebake/math/sincos_turns.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "probebake/sampling/hash.h"

namespace probebake {
namespace {

// The header's stated bound: 4 * 2^-53 absolute. Derivation: the reduction is exact; x = 2 pi r
// carries one rounding (relative 2^-53), which moves sin and cos by at most |x| 2^-53 <= 0.8 *
// 2^-53; Estrin's scheme on S and C, both well conditioned, and the final additions contribute at
// most ~1.5 * 2^-53 more; the truncated series terms are below 1e-19.
constexpr double kBound = 4 * 0x1p-53;

struct Worst {
  double error = 0;
  double at = 0;
};

// Against long double sin/cos of 2 pi t (64-bit significand: its own error is ~2^-64 relative),
// reduced to a fraction of a turn first (t - floor(t) is exact in double), since 2 pi t in long
// double would carry an error of ~2^-64 |t| radians.
void Check(double t, Worst* worst) {
  const long double x =
      2 * 3.141592653589793238462643383279502884L * static_cast<long double>(t - std::floor(t));
  const SinCos sc = SinCosTurns(t);
  const double es = static_cast<double>(std::fabs(static_cast<long double>(sc.sin) - sinl(x)));
  const double ec = static_cast<double>(std::fabs(static_cast<long double>(sc.cos) - cosl(x)));
  ASSERT_LE(es, kBound) << "sin at t = " << t;
  ASSERT_LE(ec, kBound) << "cos at t = " << t;
  if (std::max(es, ec) > worst->error) *worst = {std::max(es, ec), t};
}

TEST(SinCosTurns, MatchesLongDoubleToRoundingOverTheWarpRange) {
  Worst worst;
  // Every value the samplers produce is k 2^-32; a million of them, hashed, plus the edges of
  // the reduction's eighths, where the remainder switches sign.
  for (uint64_t i = 0; i < 1000000; ++i) Check(double(uint32_t(Hash(i) >> 32)) * 0x1p-32, &worst);
  for (int k = 0; k <= 8; ++k) {
    for (double d : {-0x1p-40, -0x1p-52, 0.0, 0x1p-52, 0x1p-40}) {
      const double t = k / 8.0 + d;
      if (t >= 0 && t < 1) Check(t, &worst);
    }
  }
  Check(1 - 0x1p-32, &worst);
  Check(0x1p-1000, &worst);
  std::printf("[measured] SinCosTurns: max |error| %.3g (%.2f ulp of 1) at t = %.17g\n",
              worst.error, worst.error / 0x1p-52, worst.at);
}

TEST(SinCosTurns, NegativeAndLargeArgumentsReduceExactly) {
  Worst worst;
  for (uint64_t i = 0; i < 100000; ++i) {
    const double f = double(Hash(i, 7) >> 11) * 0x1p-53;  // [0, 1)
    Check(-f, &worst);
    Check(1e6 + f, &worst);
    Check(-3.0 - f, &worst);
  }
  std::printf("[measured] SinCosTurns, |t| up to 1e6: max |error| %.3g\n", worst.error);
}

TEST(SinCosTurns, QuarterTurnsAreExact) {
  const double expected[4][2] = {{0, 1}, {1, 0}, {0, -1}, {-1, 0}};
  for (int k = -8; k <= 8; ++k) {
    const SinCos sc = SinCosTurns(k * 0.25);
    const int m = ((k % 4) + 4) % 4;
    EXPECT_EQ(sc.sin, expected[m][0]) << k;
    EXPECT_EQ(sc.cos, expected[m][1]) << k;
  }
}

TEST(SinCosTurns, SmallAnglesKeepRelativePrecision) {
  // sin x ~ x for tiny x: the result must keep x's relative precision, not just absolute 2^-53.
  for (double t : {1e-300, 1e-20, 1e-10, 1e-5}) {
    const long double x = 2 * 3.141592653589793238462643383279502884L * static_cast<long double>(t);
    const double s = SinCosTurns(t).sin;
    EXPECT_LE(std::fabs(static_cast<double>((static_cast<long double>(s) - sinl(x)) / sinl(x))),
              2 * 0x1p-53)
        << t;
  }
}

}  // namespace
}  // namespace probebake
