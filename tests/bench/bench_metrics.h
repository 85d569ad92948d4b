// Errors of a bake against a reference, per probe and summarised over probes.
//
// Per probe (valid in both), with L the bake's order and the reference truncated to order L, so
// the error is the estimator's and not SH truncation's:
//  - irradiance: E(n) = sum_lm A_l L_lm Y_lm(n) per RGB channel; relative L2 error over the sphere
//      sqrt(sum_ch int (E_bake - E_ref)^2 dn) / sqrt(sum_ch int E_ref^2 dn),
//    integrated by a product quadrature exact for the squared order-L polynomial (and checked
//    against the same number from coefficients by Parseval, to 1e-9);
//  - radiance SH: sqrt(sum_{i,ch} (c_bake - c_ref)^2) / sqrt(sum_{i,ch} c_ref^2);
//  - luminance irradiance: the same for the luminance of the coefficients (by Parseval,
//      sqrt(sum_i A_l^2 (lum c_bake - lum c_ref)^2) / sqrt(sum_i A_l^2 (lum c_ref)^2)), the
//      quantity the bake's std_error estimates (core/src/bake/probe_finish.h);
//  - L0: |lum(L0_bake) - lum(L0_ref)| / lum(L0_ref), the quantity its std_error_l0 estimates.
// The error the bake expects of itself: std_error, std_error_l0, and for the RGB irradiance
// sqrt(sum A_l^2 se_i^2) / |E_ref| from the per-coefficient standard errors (coefficientErrors),
// each combined in quadrature with the reference's own (independent) error.
//
// Summary "honesty" ratios: RMS over probes of the measured error divided by the RMS of the
// expected error. An honest estimate gives ~1; > 1 means errors are underestimated. (With few
// batches the ratio of one probe is far from 1 either way, but the mean of its square is
// still 1: the batch variance is unbiased.)
#pragma once

#include <cstdint>
#include <vector>

#include "bench_reference.h"
#include "probebake/bake/probe_volume.h"

namespace probebake::bench {

struct ProbeErrors {
  int64_t probe = 0;
  double irradianceRel = 0;
  double radianceRel = 0;
  double l0Rel = 0;                // |l0Signed|
  double l0Signed = 0;             // (lum(L0_bake) - lum(L0_ref)) / lum(L0_ref)
  double irradianceLumRel = 0;     // measured luminance irradiance error
  double stdError = 0;             // reported std_error
  double stdErrorL0 = 0;           // reported std_error_l0
  double refRelStdError = 0;       // the reference's own std_error ...
  double refRelStdErrorL0 = 0;     // ... and std_error_l0
  double irradiancePredicted = 0;  // expected relative irradiance error of the bake
  double irradiancePredictedRef = 0;
  double samples = 0;
};

struct ErrorSummary {
  int64_t probes = 0;
  double meanIrradianceRel = 0, medianIrradianceRel = 0, maxIrradianceRel = 0;
  double rmsIrradianceRel = 0;
  double meanRadianceRel = 0;
  double rmsL0Rel = 0;
  double rmsIrradianceLumRel = 0;
  double meanStdError = 0, rmsStdError = 0, meanStdErrorL0 = 0;
  // rmsIrradianceLumRel / sqrt(mean(stdError^2 + refRelStdError^2)): the honesty of std_error.
  double honesty = 0;
  double honestyL0 = 0;          // rmsL0Rel / sqrt(mean(stdErrorL0^2 + refRelStdErrorL0^2))
  double honestyIrradiance = 0;  // rmsIrradianceRel / sqrt(mean(pred^2 + predRef^2))
  double meanSamples = 0;
  // Mean over probes of the signed relative L0 difference, and its standard error from the
  // probes' own std errors: a bias (e.g. light lost to a depth limit) shows as a mean many
  // standard errors from 0, since noise averages out over probes and bias does not.
  double meanSignedL0 = 0, meanSignedL0StdError = 0;
  double refMeanIrradianceRel = 0;  // the reference's own expected irradiance error, mean
  double refMeanStdError = 0;
};

// Errors of every probe valid in both `volume` (active, validity 1) and `reference`. The volume
// must carry radianceStdError (BakeOptions::coefficientErrors) and have order <= the reference's.
std::vector<ProbeErrors> CompareWithReference(const ProbeVolume& volume,
                                              const Reference& reference);
ErrorSummary Summarise(const std::vector<ProbeErrors>& errors);

}  // namespace probebake::bench
