// The power heuristic (core/src/bake/power_heuristic.h): its one-division form agrees with the
// definition, and the extremes (pdfs whose squares underflow or overflow, zero, infinity) give the
// limits of the definition instead of NaN or 0/0.
#include "core/src/bake/power_heuristic.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace probebake {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = std::numeric_limits<double>::epsilon();

// The definition in long double where it has the range (x86: 64-bit mantissa, exponent to 1e4932).
long double Weight(long double a, long double b) {
  return a * a / (a * a + b * b);
}
long double WeightOverPdf(long double a, long double b) {
  return a / (a * a + b * b);
}
// Results below the normal range keep only an absolute precision.
constexpr double kFloor = std::numeric_limits<double>::min();

TEST(PowerHeuristic, AgreesWithTheDefinitionAcrossScales) {
  // Rounding bound: PowerHeuristic takes 4 correctly rounded operations on either path, the
  // OverPdf fallback at most 7 (two scalings, two squares, a sum, two divisions); each adds at
  // most eps / 2 relative (the terms are positive, so nothing cancels), and rounding the long
  // double reference to double eps / 2 more: 4 eps at worst, 5 eps allowed.
  const double pdfs[] = {1e-300, 1e-200, 1e-150, 1e-20, 0.07957747154594767, 0.5, 1, 3.7,
                         1e20,   1e150,  1e200,  1e300};
  for (double a : pdfs) {
    for (double b : pdfs) {
      const double w = double(Weight(a, b)), wOverPdf = double(WeightOverPdf(a, b));
      EXPECT_NEAR(PowerHeuristic(a, b), w, 5 * kEps * w + kFloor) << "a " << a << " b " << b;
      EXPECT_NEAR(PowerHeuristicOverPdf(a, b), wOverPdf, 5 * kEps * wOverPdf + kFloor)
          << "a " << a << " b " << b;
      EXPECT_GE(PowerHeuristic(a, b), 0.0);
      EXPECT_LE(PowerHeuristic(a, b), 1.0);
    }
  }
}

TEST(PowerHeuristic, WeightsOfTheTwoTechniquesSumToOne) {
  // Each weight within 2 eps relative of its exact value (4 operations), the two summing to 1:
  // the sum errs by at most 2 eps, plus eps / 2 for its own rounding; 4 eps allowed.
  for (double a : {1e-250, 1e-3, 0.25, 2.0, 1e3, 1e250}) {
    for (double b : {1e-250, 1e-3, 0.25, 2.0, 1e3, 1e250}) {
      EXPECT_NEAR(PowerHeuristic(a, b) + PowerHeuristic(b, a), 1.0, 4 * kEps)
          << "a " << a << " b " << b;
    }
  }
}

TEST(PowerHeuristic, ZeroAndInfinitePdfsGiveTheLimits) {
  EXPECT_EQ(PowerHeuristic(0, 1), 0.0);
  EXPECT_EQ(PowerHeuristic(1, 0), 1.0);
  EXPECT_EQ(PowerHeuristic(kInf, 1), 1.0);
  EXPECT_EQ(PowerHeuristic(1, kInf), 0.0);
  EXPECT_EQ(PowerHeuristic(0, 1e-300), 0.0);  // the squares underflow: the fallback form
  EXPECT_EQ(PowerHeuristicOverPdf(kInf, 1), 0.0);
  EXPECT_EQ(PowerHeuristicOverPdf(1, kInf), 0.0);
  EXPECT_EQ(PowerHeuristicOverPdf(2, 0), 0.5);
}

}  // namespace
}  // namespace probebake
