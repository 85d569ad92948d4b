// The probe's sampling at low sample counts (core/src/bake/probe_integrator.h: a randomly rotated
// spherical Fibonacci set per batch) and the calibration of its error estimates
// (core/src/bake/probe_finish.h), on scenes whose projection is known exactly.
//
// Each case bakes a lattice of 256 probes. Every probe is an independent estimate (its own
// rotations and streams) and, in these scenes, statistically the same one, so the figures over
// the lattice are what one probe does on average and at worst. Errors are relative to the exact
// c0. Bakes are deterministic: a per-probe bound below is a fact about these 256 probes, chosen
// where it holds with room to spare (the measured worst is printed), and an RMS bound is a
// statistical statement with its margin stated.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bake_test_util.h"
#include "probebake/sh/sh_convolution.h"

namespace probebake {
namespace {

using namespace probebake::testing;

constexpr int kDefaultBatches = BakeSettings{}.batches;

double Square(double x) {
  return x * x;
}

// A lattice of 8 x 8 x 4 probes from `origin`, `samples` per probe, the default batch count.
BakeJob Lattice(int order, int64_t samples, Vec3d origin = {}) {
  BakeJob job = MakeJob(order, samples, origin);
  job.settings.batches = kDefaultBatches;
  job.grid.counts[0] = job.grid.counts[1] = 8;
  job.grid.counts[2] = 4;
  job.grid.spacing = {0.37, 0.41, 0.43};
  return job;
}

// A black plane through `point` facing `normal`, 2e6 across: the sky it fails to hide from a
// probe within a few units lies within 1e-5 rad of the horizon (a share of c0 below 1e-5).
void AddBlackPlane(BakeJob* job, const Vec3d& point, const Vec3d& normal) {
  const uint32_t black = AddMaterial(&job->scene, {0, 0, 0});
  const Framed f = Framed::FromZ(normal);
  const double s = 1e6;
  AddQuad(&job->scene, point - f.s * s - f.t * s, point + f.s * s - f.t * s,
          point + f.s * s + f.t * s, point - f.s * s + f.t * s, black);
}

// Figures of a lattice bake against the exact projection `exact` (per coefficient, the same in
// every channel: grey light). Channel 0 is compared; the channels share their paths.
struct LatticeErrors {
  // Per coefficient: RMS over probes of (c - exact) / exact_0.
  std::vector<double> rms;
  // Per probe: max over coefficients of l <= 2, and over all, of |c - exact| / exact_0.
  std::vector<double> worstL2, worstAll;
  // sqrt(sum of squared measured errors / sum of squared reported errors) over the probes: for
  // std_error (the irradiance figure) and std_error_l0. 0 when there is nothing to compare.
  double honesty = 0, honestyL0 = 0;
  // A single probe's std_error against the true standard error (the RMS of the measured
  // irradiance errors over the probes, which are statistically the same): the 5% and 95%
  // quantiles over the probes of their ratio.
  double spreadLow = 0, spreadHigh = 0;
};

LatticeErrors Compare(const ProbeVolume& v, const std::vector<double>& exact) {
  const int n = v.CoeffCount();
  const int64_t probes = v.grid.ProbeCount();
  LatticeErrors out;
  out.rms.assign(n, 0.0);
  double irrSq = 0, seSq = 0, l0Sq = 0, seL0Sq = 0, exactIrrSq = 0;
  std::vector<double> reported;
  for (int l = 0, i = 0; i < n; ++l)
    for (int m = -l; m <= l; ++m, ++i) exactIrrSq += Square(IrradianceBandFactor(l) * exact[i]);
  for (int64_t p = 0; p < probes; ++p) {
    double worstL2 = 0, worstAll = 0, errIrrSq = 0;
    for (int l = 0, i = 0; i < n; ++l) {
      for (int m = -l; m <= l; ++m, ++i) {
        const double d = v.radiance[i][3 * p] - exact[i];
        const double rel = std::abs(d) / exact[0];
        out.rms[i] += rel * rel;
        if (l <= 2) worstL2 = std::max(worstL2, rel);
        worstAll = std::max(worstAll, rel);
        errIrrSq += Square(IrradianceBandFactor(l) * d);
      }
    }
    out.worstL2.push_back(worstL2);
    out.worstAll.push_back(worstAll);
    irrSq += errIrrSq / exactIrrSq;
    seSq += Square(v.stdError[p]);
    reported.push_back(v.stdError[p]);
    l0Sq += Square((v.radiance[0][3 * p] - exact[0]) / exact[0]);
    seL0Sq += Square(v.stdErrorL0[p]);
  }
  for (double& r : out.rms) r = std::sqrt(r / double(probes));
  out.honesty = seSq > 0 ? std::sqrt(irrSq / seSq) : 0;
  const double trueError = std::sqrt(irrSq / double(probes));
  std::sort(reported.begin(), reported.end());
  out.spreadLow = reported[size_t(probes / 20)] / trueError;
  out.spreadHigh = reported[size_t(probes - 1 - probes / 20)] / trueError;
  // Where L0 is exact (every sample sees the same radiance) both are rounding: no ratio.
  out.honestyL0 = seL0Sq > 0 && out.rms[0] > 1e-6 ? std::sqrt(l0Sq / seL0Sq) : 0;
  return out;
}

double MaxOf(const std::vector<double>& v, size_t begin, size_t end) {
  return *std::max_element(v.begin() + begin, v.begin() + std::min(end, v.size()));
}

void Print(const std::string& what, const LatticeErrors& e) {
  std::printf(
      "[measured] %s: RMS over probes, worst coefficient: l <= 2 %.2e, all %.2e; worst probe: "
      "l <= 2 %.2e, all %.2e; honesty std_error %.2f, std_error_l0 %.2f; 90%% of probes' "
      "std_error within %.2f to %.2f of the true one\n",
      what.c_str(), MaxOf(e.rms, 0, 9), MaxOf(e.rms, 0, e.rms.size()),
      MaxOf(e.worstL2, 0, e.worstL2.size()), MaxOf(e.worstAll, 0, e.worstAll.size()), e.honesty,
      e.honestyL0, e.spreadLow, e.spreadHigh);
}

// Calibration: the mean over probes of the squared measured error and of the squared reported
// one both estimate the variance (the batch variance is unbiased whatever the batch count), so
// their ratio's square root is near 1. Its spread over 256 probes: a probe's squared irradiance
// error is a weighted sum of squared Gaussians, relative variance at most 2 (one term), so the
// sum over 256 has a relative spread of at most sqrt(2 / 256) = 8.8%; the reported variance pools
// at least 3 (batches - 1) degrees of freedom, at most sqrt(2 / 3 / 256) = 5.1%; the ratio's
// square root at most half their quadrature sum, 5.1%. Four of them: [0.8, 1.2]. A reported error
// 25% too small or too large falls outside.
constexpr double kHonestyLow = 0.8, kHonestyHigh = 1.2;

void ExpectHonest(double honesty, const std::string& what) {
  EXPECT_GE(honesty, kHonestyLow) << what;
  EXPECT_LE(honesty, kHonestyHigh) << what;
}

// A single probe's figure (the default 4 batches): one coefficient's standard error from 4
// batches (3 degrees of freedom) lies, for 90% of probes, between sqrt(chi2_3(5%) / 3) = 0.34
// and sqrt(chi2_3(95%) / 3) = 1.61 times the true one. std_error pools the spread of every
// coefficient, at least 3 of them with comparable weights in these scenes (9 degrees of freedom:
// 0.61 to 1.37), so its range lies well inside; one coefficient's figure would fill it.
void ExpectPooledSpread(const LatticeErrors& e, const std::string& what) {
  EXPECT_GT(e.spreadLow, 0.34) << what;
  EXPECT_LT(e.spreadHigh, 1.61) << what;
}

TEST(ProbeSampling, UniformSkyAt256SamplesIsAccurateToOrderEight) {
  // Issue target: every coefficient to l = 2 within 2e-3 of c0, to l = 8 within 5e-3. With the
  // default 4 batches the first holds at every probe (measured worst 1.3e-3) and the second for
  // the RMS over probes (2.4e-3) but not at every probe (worst 8.8e-3: 64 directions and 64 light
  // points per batch cannot resolve band 8 everywhere); with 2 batches of 128 both hold at every
  // probe (worst l <= 8: 3.1e-3).
  BakeJob job = Lattice(8, 256);
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  const std::vector<double> exact = CapProjection(8, {0, 0, 1}, -1);
  const LatticeErrors e = Compare(BakeOrDie(job), exact);
  Print("uniform sky, 256 samples, 4 batches", e);
  EXPECT_LE(MaxOf(e.worstL2, 0, e.worstL2.size()), 2e-3);
  // RMS over 256 probes: a relative spread of 4.4% each; the bound is twice the measured figure.
  EXPECT_LE(MaxOf(e.rms, 0, e.rms.size()), 5e-3);
  // L0 is exact here (every sample of either technique sees the same radiance), the other
  // coefficients carry the error, which std_error sees and std_error_l0 cannot.
  EXPECT_LT(e.rms[0], 1e-6);
  ExpectHonest(e.honesty, "uniform sky");
  ExpectPooledSpread(e, "uniform sky");

  job.settings.batches = 2;
  const LatticeErrors two = Compare(BakeOrDie(job), exact);
  Print("uniform sky, 256 samples, 2 batches", two);
  EXPECT_LE(MaxOf(two.worstAll, 0, two.worstAll.size()), 5e-3);
  EXPECT_LE(MaxOf(two.worstL2, 0, two.worstL2.size()), 2e-3);
}

TEST(ProbeSampling, BlackGroundHemisphereAt256And512Samples) {
  // Issue target: every coefficient to l = 2 within 1e-2 of c0 at 256 samples. Not met: the
  // horizon is a discontinuity, which no randomised point set integrates faster than about n^-3/4
  // (sets at the least cap discrepancy do no better than Fibonacci's here), and honest
  // independent batches cost (batches)^1/4 of that. Measured with the default 4 batches: RMS over
  // probes 1.3e-2 for the worst coefficient (2 batches: 1.1e-2), worst probe 4e-2. What holds:
  // the error is the one reported (honesty), it does not depend on how the horizon lies (a tilted
  // ground gives the same), the RMS stays below 1.5e-2 at 256 samples (the measured 1.31e-2 with
  // 3 spreads of the RMS of 256 probes, 4.4% each, to spare), and it falls as n^-3/4, so the
  // target holds at 512 samples: 1.31e-2 x 2^-3/4 = 7.8e-3, 8.8e-3 with the same 3 spreads. Two
  // extra environment samples per sample reach 9.4e-3 at 256 but cost more than they gain
  // wherever the ground reflects (docs/performance-history.md, 2026-12-07).
  struct Case {
    int64_t samples;
    double bound;
  };
  for (const Case c : {Case{256, 1.5e-2}, Case{512, 1e-2}}) {
    for (const bool tilted : {false, true}) {
      const Vec3d normal = tilted ? Normalize(Vec3d{0.3, 0.2, 1}) : Vec3d{0, 0, 1};
      BakeJob job = Lattice(2, c.samples, {0, 0, 1});
      job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
      AddBlackPlane(&job, {0, 0, 0}, normal);
      const LatticeErrors e = Compare(BakeOrDie(job), CapProjection(2, normal, 0));
      const std::string what = std::string(tilted ? "tilted black ground" : "black ground") + ", " +
                               std::to_string(c.samples) + " samples";
      Print(what + ", 4 batches", e);
      EXPECT_LE(MaxOf(e.rms, 0, 9), c.bound) << what;
      ExpectHonest(e.honesty, what);
      ExpectHonest(e.honestyL0, what + " (L0)");
      ExpectPooledSpread(e, what);
    }
  }
}

TEST(ProbeSampling, FurnaceAndConstantMapErrorsAreTheReportedOnes) {
  {
    // A closed box whose walls emit 1 and reflect 1/2, depth 3: 1 + 1/2 + 1/4 + 1/8 everywhere.
    BakeJob job = Lattice(2, 256, {0.1, 0.1, 0.1});
    const uint32_t wall = AddMaterial(&job.scene, {0.5, 0.5, 0.5}, {1, 1, 1});
    AddBox(&job.scene, {-1, -1, -1}, {4, 4, 3}, wall, /*inward=*/true);
    job.settings.maxDepth = 3;
    std::vector<double> exact = CapProjection(2, {0, 0, 1}, -1);
    for (double& c : exact) c *= 1.875;
    const LatticeErrors e = Compare(BakeOrDie(job), exact);
    Print("furnace, 256 samples, 4 batches", e);
    ExpectHonest(e.honesty, "furnace");
    ExpectHonest(e.honestyL0, "furnace (L0)");
    ExpectPooledSpread(e, "furnace");
  }
  {
    // A constant map is sampled by its cells, not as the uniform sky is, and gains less from the
    // rotated set (docs/accuracy-and-speed.md); its error is still the one reported.
    auto map = std::make_shared<EnvironmentMap>();
    map->width = 16;
    map->height = 8;
    map->rgb.assign(3 * 16 * 8, 1.0f);
    BakeJob job = Lattice(2, 256);
    job.scene.environment = {Environment::Kind::kMap, {}, map};
    const LatticeErrors e = Compare(BakeOrDie(job), CapProjection(2, {0, 0, 1}, -1));
    Print("constant map, 256 samples, 4 batches", e);
    ExpectHonest(e.honesty, "constant map");
    ExpectPooledSpread(e, "constant map");
  }
}

TEST(ProbeSampling, FewerLargerBatchesBeatManySmallOnes) {
  // The reason for the default: at equal samples the error of smooth light falls with the size of
  // each batch's point set. Measured RMS (worst coefficient, l <= 2) under the uniform sky at 256
  // samples: 16 batches 2.3e-3, 4 batches 4.5e-4.
  BakeJob job = Lattice(2, 256);
  job.scene.environment = {Environment::Kind::kUniform, {1, 1, 1}, nullptr};
  const std::vector<double> exact = CapProjection(2, {0, 0, 1}, -1);
  const LatticeErrors four = Compare(BakeOrDie(job), exact);
  job.settings.batches = 16;
  const LatticeErrors sixteen = Compare(BakeOrDie(job), exact);
  EXPECT_LT(2 * MaxOf(four.rms, 0, 9), MaxOf(sixteen.rms, 0, 9));
  ExpectHonest(sixteen.honesty, "uniform sky, 16 batches");
}

}  // namespace
}  // namespace probebake
