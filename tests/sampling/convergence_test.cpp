// Randomised QMC against plain Monte Carlo on a smooth spherical integral with a closed form:
// RMSE over independent scrambles (streams) at N = 2^6 .. 2^14, log-log slope fitted; first for
// the scalar integral, then for all nine order-2 SH coefficients of the same function.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "probebake/sh/sh_projection.h"
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

// ---- The same f projected onto all nine order-2 SH coefficients (the estimator a probe uses:
// uniform-sphere directions, f / pdf accumulated by the library's ShAccumulator).
//
// Reference coefficients by Funk–Hecke: for f(ω) = F(ω·d), ∫ F(ω·d) Y_lm(ω) dω = λ_l Y_lm(d)
// with λ_l = 2π ∫_{-1}^{1} F(t) P_l(t) dt; for F = exp(k t) the integral is 2 i_l(k) (modified
// spherical Bessel function of the first kind), so c_lm = 4π i_l(k) Y_lm(d), with
//   i_0(k) = sinh k / k,   i_1(k) = cosh k / k - sinh k / k²,
//   i_2(k) = (1/k + 3/k³) sinh k - 3 cosh k / k².
double SphericalBesselI(int l, double k) {
  const double s = std::sinh(k), c = std::cosh(k);
  if (l == 0) return s / k;
  if (l == 1) return c / k - s / (k * k);
  return (1 / k + 3 / (k * k * k)) * s - 3 * c / (k * k);
}

// Y_i(d), i < 9, from the closed forms of docs/spherical-harmonics.md with exact constants
// (independent of the library's basis, so a basis error would show as a bias below): sqrt(1/(4π)),
// sqrt(3/(4π)), sqrt(15/(4π)), 3 sqrt(5/(16π)) (z² - 1/3), sqrt(15/(16π)) (x² - y²).
std::array<double, 9> ReferenceSh2(const Vec3d& d) {
  const double pi = std::numbers::pi;
  const double k0 = std::sqrt(1 / (4 * pi)), k1 = std::sqrt(3 / (4 * pi));
  const double k2 = std::sqrt(15 / (4 * pi)), k6 = 3 * std::sqrt(5 / (16 * pi));
  const double k8 = std::sqrt(15 / (16 * pi));
  return {k0,
          -k1 * d.y,
          k1 * d.z,
          -k1 * d.x,
          k2 * d.x * d.y,
          -k2 * d.y * d.z,
          k6 * (d.z * d.z - 1.0 / 3),
          -k2 * d.x * d.z,
          k8 * (d.x * d.x - d.y * d.y)};
}

std::array<double, 9> ExactShCoefficients() {
  const Integrand f;
  std::array<double, 9> c = ReferenceSh2(f.d);
  for (int l = 0; l <= 2; ++l)
    for (int i = l * l; i < (l + 1) * (l + 1); ++i)
      c[i] *= 4 * std::numbers::pi * SphericalBesselI(l, Integrand::k);
  return c;
}

TEST(Convergence, ShReferenceCoefficientsAreRight) {
  // The closed forms of i_l against libstdc++'s I_{l+1/2}: i_l(k) = sqrt(π/(2k)) I_{l+1/2}(k),
  // and λ_l against a 30-point Gauss-Legendre rule for 2π ∫ e^{kt} P_l(t) dt (error of order
  // k^60/60! ≈ 1e-64: rounding only). i_2 loses ~1 digit to cancellation at k = 2 (terms ~3.2
  // summing to 0.35); 1e-14 relative covers that and the 10^2 eps of a special function.
  const double k = Integrand::k;
  const testing::Quadrature gl = testing::GaussLegendre(30, -1, 1);
  for (int l = 0; l <= 2; ++l) {
    const double i = SphericalBesselI(l, k);
    EXPECT_NEAR(i, std::sqrt(std::numbers::pi / (2 * k)) * std::cyl_bessel_i(l + 0.5, k), 1e-14 * i)
        << "l " << l;
    double integral = 0;
    for (size_t j = 0; j < gl.x.size(); ++j) {
      const double t = gl.x[j];
      const double p = l == 0 ? 1 : (l == 1 ? t : 1.5 * t * t - 0.5);
      integral += gl.w[j] * std::exp(k * t) * p;
    }
    EXPECT_NEAR(2 * std::numbers::pi * integral, 4 * std::numbers::pi * i,
                1e-14 * 4 * std::numbers::pi * i)
        << "l " << l;
  }
  // ReferenceSh2 against the documented test vector (given to 9 decimals).
  const std::array<double, 9> y = ReferenceSh2(Vec3d{0.48, 0.6, 0.64});
  const double spec[9] = {0.282094792,  -0.293161507, 0.312705608,  -0.234529206, 0.314653948,
                          -0.419538597, 0.072161590,  -0.335630878, -0.070797138};
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(y[i], spec[i], 1e-9) << "i " << i;
}

// Statistics of one (sampler, N) level over kShReplicates independent streams. Metric: per
// replicate the relative L2 error of the coefficient vector, r = ||ĉ - c|| / ||c|| (by Parseval
// the relative L2 error of the reconstructed order-2 function); the level's RMS error is
// sqrt(mean r²).
constexpr int kShReplicates = 256;

struct ShLevel {
  double rms = 0;            // sqrt(mean r²)
  double log2RmsSe = 0;      // standard error of log2(rms) from the spread of r² (delta method)
  double maxBiasSigmas = 0;  // max over coefficients of |mean error| / (its standard error)
};

template <typename S>
ShLevel MeasureShLevel(int n, uint64_t level) {
  const Integrand f;
  const std::array<double, 9> exact = ExactShCoefficients();
  double norm2 = 0;
  for (double c : exact) norm2 += c * c;
  std::vector<double> r2(kShReplicates);
  std::array<double, 9> sum{}, sumSq{};
  std::array<double, 9> estimate{};
  ShAccumulator acc(2);
  for (int r = 0; r < kShReplicates; ++r) {
    S s(2025, Hash(r, level));  // an independent randomisation per (replicate, level)
    acc.Reset();
    for (int i = 0; i < n; ++i) {
      s.StartSample(i);
      const Vec3d w = SampleUniformSphere(s.Get2D());
      acc.Add(w, f(w) / UniformSpherePdf());
    }
    acc.Sum(estimate, 1.0 / n);
    double e2 = 0;
    for (int i = 0; i < 9; ++i) {
      const double e = estimate[i] - exact[i];
      e2 += e * e;
      sum[i] += e;
      sumSq[i] += e * e;
    }
    r2[r] = e2 / norm2;
  }
  ShLevel out;
  const double mean = std::accumulate(r2.begin(), r2.end(), 0.0) / kShReplicates;
  double var = 0;
  for (double x : r2) var += (x - mean) * (x - mean);
  var /= kShReplicates - 1;
  out.rms = std::sqrt(mean);
  // log2 sqrt(m) = log2(m)/2, so se = (se(m)/m) / (2 ln 2) with se(m) = sqrt(var/R).
  out.log2RmsSe = std::sqrt(var / kShReplicates) / mean / (2 * std::numbers::ln2);
  for (int i = 0; i < 9; ++i) {
    const double m = sum[i] / kShReplicates;
    const double sd = std::sqrt((sumSq[i] - kShReplicates * m * m) / (kShReplicates - 1));
    out.maxBiasSigmas = std::max(out.maxBiasSigmas, std::abs(m) / (sd / std::sqrt(kShReplicates)));
  }
  return out;
}

struct ShConvergence {
  std::vector<double> log2N, log2Rms, log2RmsSe;
  testing::LineFit fit;
  double slopeSeReplicates = 0;  // the slope's standard error propagated from the levels' se
  double maxBiasSigmas = 0;
  double rms10k = 0, rms10kSe = 0;  // at N = 10000 (relative se of rms)
  // The larger of the residual-based and the propagated standard error: the first also sees
  // curvature (a non-power-law), the second is honest even when 9 points happen to line up.
  double SlopeSe() const { return std::max(fit.slopeStdError, slopeSeReplicates); }
};

template <typename S>
ShConvergence MeasureSh() {
  ShConvergence c;
  for (int m = kMinLog2N; m <= kMaxLog2N; ++m) {
    const ShLevel level = MeasureShLevel<S>(1 << m, m);
    c.log2N.push_back(m);
    c.log2Rms.push_back(std::log2(level.rms));
    c.log2RmsSe.push_back(level.log2RmsSe);
    c.maxBiasSigmas = std::max(c.maxBiasSigmas, level.maxBiasSigmas);
  }
  c.fit = testing::FitLine(c.log2N, c.log2Rms);
  // OLS slope = Σ (x_j - x̄) y_j / Sxx with independent levels: var = Σ (x_j - x̄)² σ_j² / Sxx².
  const double mx = std::accumulate(c.log2N.begin(), c.log2N.end(), 0.0) / c.log2N.size();
  double sxx = 0, v = 0;
  for (size_t j = 0; j < c.log2N.size(); ++j) {
    const double dx = c.log2N[j] - mx;
    sxx += dx * dx;
    v += dx * dx * c.log2RmsSe[j] * c.log2RmsSe[j];
  }
  c.slopeSeReplicates = std::sqrt(v) / sxx;
  const ShLevel at10k = MeasureShLevel<S>(10000, 100);  // level id 100: streams unused above
  c.rms10k = at10k.rms;
  c.rms10kSe = at10k.log2RmsSe * 2 * std::numbers::ln2 / 2;  // relative se of rms = se(m)/(2m)
  c.maxBiasSigmas = std::max(c.maxBiasSigmas, at10k.maxBiasSigmas);
  return c;
}

std::string Describe(const ShConvergence& c) {
  std::ostringstream s;
  s << "slope = " << c.fit.slope << " +- " << c.SlopeSe() << " (1 sigma; residual "
    << c.fit.slopeStdError << ", replicates " << c.slopeSeReplicates << "); log2 RMS rel. error:";
  for (size_t i = 0; i < c.log2N.size(); ++i) s << " 2^" << c.log2N[i] << ":" << c.log2Rms[i];
  s << "; N=10000: " << c.rms10k << " (+- " << 100 * c.rms10kSe << "%)";
  return s.str();
}

// Slopes, a priori: independent sampling has E[r²] = σ²/N exactly, so slope -0.5. Each level's
// log2 RMS has standard error <= (1/(2 ln 2)) sqrt(2/R) = 0.064 (r² a chi-square-like sum of
// up to 9 squared Gaussian errors, relative sd <= sqrt(2)), so over 9 levels (Sxx = 60) the slope
// has standard error <= 0.008; the test computes it from the data (SlopeSe) and requires it
// below 0.03 so the checks stay sharp. Asserted:
//  - independent: |slope + 0.5| <= 4 sigma (two-sided false alarm 6e-5);
//  - Sobol steeper: slope_ind - slope_sobol >= 5 sqrt(se_ind² + se_sobol²) (a 5-sigma
//    difference) and >= 0.3 in absolute terms (an effect, not only a detectable one);
//  - unbiasedness: every coefficient's mean error within 5 standard errors at every level
//    (9 coefficients x 10 levels x 2 samplers = 180 t statistics with R - 1 = 255 dof, each
//    beyond 5 with probability ~6e-7: family-wise 1e-4).
// At N = 10000 (not a power of two: not a complete net, Sobol's worst case between powers) the
// RMS relative error is printed for both; google/spherical-harmonics' random projection, measured
// at 9e-4 with 10k random samples for order 2 when the project started, is for an unstated
// function and metric, so it is context, not a threshold. Ours must be below independent's by 5
// combined sigmas of log2 RMS.
TEST(Convergence, SobolBeatsIndependentOnAllOrder2ShCoefficients) {
  const ShConvergence sobol = MeasureSh<SobolSampler>();
  const ShConvergence independent = MeasureSh<IndependentSampler>();
  RecordProperty("sh_sobol_slope", std::to_string(sobol.fit.slope));
  RecordProperty("sh_sobol_slope_se", std::to_string(sobol.SlopeSe()));
  RecordProperty("sh_independent_slope", std::to_string(independent.fit.slope));
  RecordProperty("sh_independent_slope_se", std::to_string(independent.SlopeSe()));
  RecordProperty("sh_sobol_rms_rel_error_10k", std::to_string(sobol.rms10k));
  RecordProperty("sh_independent_rms_rel_error_10k", std::to_string(independent.rms10k));
  std::cout << "Order-2 SH projection of exp(2 w.d), RMS relative L2 coefficient error over "
            << kShReplicates << " streams\nSobol:       " << Describe(sobol)
            << "\nIndependent: " << Describe(independent) << "\n";

  EXPECT_LE(independent.SlopeSe(), 0.03) << Describe(independent);
  EXPECT_LE(sobol.SlopeSe(), 0.03) << Describe(sobol);
  EXPECT_LE(std::abs(independent.fit.slope + 0.5), 4 * independent.SlopeSe())
      << Describe(independent);
  const double diff = independent.fit.slope - sobol.fit.slope;
  const double diffSe = std::hypot(independent.SlopeSe(), sobol.SlopeSe());
  EXPECT_GE(diff, 5 * diffSe) << Describe(sobol) << "\n" << Describe(independent);
  EXPECT_GE(diff, 0.3) << Describe(sobol) << "\n" << Describe(independent);
  const double log2Gap = std::log2(independent.rms10k / sobol.rms10k);
  const double log2GapSe = std::hypot(sobol.rms10kSe, independent.rms10kSe) / std::numbers::ln2;
  EXPECT_GE(log2Gap, 5 * log2GapSe) << Describe(sobol) << "\n" << Describe(independent);
  EXPECT_LE(sobol.maxBiasSigmas, 5) << Describe(sobol);
  EXPECT_LE(independent.maxBiasSigmas, 5) << Describe(independent);
}

}  // namespace
}  // namespace probebake
