// Randomised QMC against plain Monte Carlo on a smooth spherical integral with a closed form:
// RMSE over independent scrambles (streams) at N = 2^6 .. 2^14, log-log slope fitted.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "sampling/stats.h"

namespace probebake {
namespace {

constexpr int kReplicates = 256;
constexpr int kMinLog2N = 6, kMaxLog2N = 14;

// f(w) = exp(k w.d) over the unit sphere; integral 4 pi sinh(k) / k. k = 2, d a generic
// direction so the integrand is not aligned with the sampling parameterisation.
struct Integrand {
  static constexpr double k = 2;
  Vec3d d = Normalize(Vec3d{1, 2, 3});
  double operator()(const Vec3d& w) const { return std::exp(k * Dot(w, d)); }
  static double Exact() { return 4 * std::numbers::pi * std::sinh(k) / k; }
};

struct Convergence {
  std::vector<double> log2N, log2Rmse;
  testing::LineFit fit;
  double maxBiasSigmas = 0;  // largest |mean error| / (its standard error) over the N levels
};

// Estimates use the dimension layout of a tracer (a 1D decision, then the direction), so the
// direction comes from dimension set 1, exercising the padding of SobolSampler.
template <typename S>
Convergence Measure() {
  const Integrand f;
  const double exact = Integrand::Exact();
  Convergence c;
  for (int m = kMinLog2N; m <= kMaxLog2N; ++m) {
    const int n = 1 << m;
    double sumSq = 0, sum = 0;
    for (int r = 0; r < kReplicates; ++r) {
      S s(2024, Hash(r, m));  // an independent randomisation per (replicate, N)
      double estimate = 0;
      for (int i = 0; i < n; ++i) {
        s.StartSample(i);
        s.Get1D();
        const Vec3d w = SampleUniformSphere(s.Get2D());
        estimate += f(w) / UniformSpherePdf();
      }
      const double error = estimate / n / exact - 1;  // relative error
      sum += error;
      sumSq += error * error;
    }
    const double rmse = std::sqrt(sumSq / kReplicates);
    c.log2N.push_back(m);
    c.log2Rmse.push_back(std::log2(rmse));
    // Unbiasedness: the mean of R independent errors has standard error ~ sd / sqrt(R) (sd ~
    // rmse); sd is itself estimated, hence the ratio is ~ Student t with R - 1 dof.
    c.maxBiasSigmas = std::max(
        c.maxBiasSigmas, std::abs(sum / kReplicates) / (rmse / std::sqrt(double(kReplicates))));
  }
  c.fit = testing::FitLine(c.log2N, c.log2Rmse);
  return c;
}

std::string Describe(const Convergence& c) {
  std::ostringstream s;
  s << "slope = " << c.fit.slope << " +- " << c.fit.slopeStdError << " (1 sigma); log2 RMSE:";
  for (size_t i = 0; i < c.log2N.size(); ++i) s << " N=2^" << c.log2N[i] << ":" << c.log2Rmse[i];
  return s.str();
}

// A priori uncertainty of the slope: with R = 256 replicates the RMSE estimate has relative
// standard error ~ 1/sqrt(2R) = 4.4% (Gaussian errors), 0.064 in log2; over 9 levels with
// sum (x - mean)^2 = 60 the slope's standard error is 0.064 / sqrt(60) = 0.008. The bounds below
// sit > 10 such sigmas from the expected slopes (-0.5 for MC; about -1.5 for scrambled Sobol on
// a smooth integrand, somewhat less here because the sphere map has sqrt singularities at the
// poles), and the residual-based error is checked to be of that order so the test stays sharp.
TEST(Convergence, SobolBeatsIndependentOnASmoothSphericalIntegral) {
  const Convergence sobol = Measure<SobolSampler>();
  const Convergence independent = Measure<IndependentSampler>();
  RecordProperty("sobol_slope", std::to_string(sobol.fit.slope));
  RecordProperty("independent_slope", std::to_string(independent.fit.slope));
  std::cout << "Sobol:       " << Describe(sobol) << "\nIndependent: " << Describe(independent)
            << "\n";
  EXPECT_LE(sobol.fit.slope, -0.9) << Describe(sobol);
  EXPECT_GE(independent.fit.slope, -0.6) << Describe(independent);
  EXPECT_LE(independent.fit.slope, -0.4) << Describe(independent);
  EXPECT_LE(sobol.fit.slopeStdError, 0.05) << Describe(sobol);
  EXPECT_LE(independent.fit.slopeStdError, 0.05) << Describe(independent);
  // At the largest N, QMC must be far more accurate than MC (not only steeper).
  EXPECT_LT(sobol.log2Rmse.back(), independent.log2Rmse.back() - 3);
  // Both estimators are unbiased: every level's mean error within 5 standard errors.
  EXPECT_LE(sobol.maxBiasSigmas, 5) << Describe(sobol);
  EXPECT_LE(independent.maxBiasSigmas, 5) << Describe(independent);
}

}  // namespace
}  // namespace probebake
