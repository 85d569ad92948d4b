// From sample sums to a stored probe: the mean SH coefficients, the standard errors from the
// independent batches, irradiance and its window (docs/spherical-harmonics.md,
// docs/accuracy-and-speed.md).
//
// Error estimates: batch b is an independent randomisation (its own rotated point set and
// scrambled Sobol stream, or its own random numbers) of n_b samples with sum S_b, so its mean
// m_b = S_b / n_b is an unbiased, independent estimate of every coefficient. The probe's estimate
// is the pooled mean m = sum S_b / N (N = sum n_b) and, per coefficient,
//   Var(m) ~= B / (B - 1) * sum_b (n_b / N)^2 (m_b - m)^2,
// which is the textbook s^2 / B for equal batches. Exact delta-light terms add to m and not to
// the variance. Two relative figures, both of luminance (the coefficients' RGB weighted by
// Luminance, so that the channels' covariance counts):
//   - std_error: the relative standard error of the irradiance reconstructed from the
//     coefficients, RMS over the sphere of normals, relative to the RMS irradiance. The
//     irradiance is E(n) = sum_i A_l(i) c_i Y_i(n) (A_l the clamped cosine's band factors,
//     unwindowed), so by orthonormality the mean of its squared error over normals is
//     sum_i A_l^2 Var(c_i) / 4 pi, and of its square sum_i A_l^2 c_i^2 / 4 pi:
//       std_error = sqrt(sum_i A_l^2 Var(c_i)) / sqrt(sum_i A_l^2 c_i^2).
//     It covers every band the irradiance holds (l <= 2 carry almost all of it), not only L0.
//   - std_error_l0: sqrt(Var(c_0)) / |c_0|, the figure of format 1.
// Batches that all saw nothing carry no evidence of the error: a dim probe lit through a small
// opening reads 0 with no spread until a path finds the opening. Its error is then unknown
// (+infinity), unless nothing sampled can ever be non-zero (ProbeEstimate's `sampledMayBeNonZero`).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "probebake/bake/probe_volume.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"
#include "probebake/sh/sh_window.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {

class ProbeEstimate {
 public:
  // sampledMayBeNonZero: false when the scene gives every sample zero by construction (no light
  // to sample, and delta lights with nothing to scatter them: no mesh of non-zero albedo, no
  // scattering medium), so that identical all-zero batches are exact rather than unknown.
  // visibility: also keep each batch's visibility moments (BatchMoments). skyCoeffCount > 0: also
  // keep each batch's sky transfer sum (BatchTransfer), (Ls+1)^2 sky coefficients.
  ProbeEstimate(int coeffCount, int maxBatches, bool sampledMayBeNonZero, bool visibility = false,
                int skyCoeffCount = 0);

  // The running sum of batch b: coeffCount x 3 doubles, coefficient-major RGB.
  std::span<double> BatchSum(int b) {
    return {sums_.data() + size_t(b) * 3 * coeffs_, size_t(3 * coeffs_)};
  }
  void SetBatchSamples(int b, int64_t n) { counts_[b] = n; }
  // The visibility moments of batch b (ProbeIntegrator::BatchWork::moments); empty without
  // visibility.
  std::span<double> BatchMoments(int b) {
    if (moments_.empty()) return {};
    return {moments_.data() + size_t(b) * kMomentsSize, size_t(kMomentsSize)};
  }
  // The first `batches` batches' moments summed in batch order: per texel (sum 1/t, sum 1/t^2,
  // rays).
  std::vector<double> Moments(int batches) const;
  // The running sky transfer sum of batch b (ProbeIntegrator::BatchWork::transfer's layout);
  // empty without sky transfer.
  std::span<double> BatchTransfer(int b) {
    if (transfer_.empty()) return {};
    const size_t size = TransferSize();
    return {transfer_.data() + size_t(b) * size, size};
  }
  // Pooled mean of the first `batches` batches' T, and the standard error of every entry (the
  // estimator of CoefficientErrors).
  std::vector<double> TransferMean(int batches) const;
  std::vector<double> TransferErrors(int batches) const;
  // Adds an exactly known term radiance * Y(wi) (a delta light seen from the probe).
  void AddExact(int order, const Vec3d& wi, const Vec3d& radiance);

  int64_t Samples(int batches) const;
  // Pooled mean of the first `batches` batches plus the exact part: coeffCount x 3 doubles.
  std::vector<double> Mean(int batches) const;
  // Standard error of every coefficient and channel (coeffCount x 3), same estimator as below.
  std::vector<double> CoefficientErrors(int batches) const;
  // The relative standard errors of the first `batches` batches (see above). Each is +infinity
  // with fewer than 2 batches, with a zero mean, or when every sample was zero although the scene
  // has light to find; 0 when every batch agrees otherwise (an exact probe).
  struct RelativeErrors {
    double irradiance = 0;  // std_error
    double l0 = 0;          // std_error_l0
  };
  RelativeErrors Relative(int batches) const;

 private:
  int coeffs_;
  std::vector<double> sums_;  // maxBatches x coeffs x 3
  std::vector<int64_t> counts_;
  std::vector<double> exact_;  // coeffs x 3
  static constexpr int kMomentsSize = 3 * kVisibilityTexels;
  std::vector<double> moments_;  // maxBatches x kMomentsSize, or empty
  size_t TransferSize() const { return size_t(3) * coeffs_ * skyCoeffs_; }
  int skyCoeffs_;
  std::vector<double> transfer_;  // maxBatches x TransferSize(), or empty
  bool sampledMayBeNonZero_;
};

class ProbeFinisher {
 public:
  explicit ProbeFinisher(const BakeSettings& settings);
  // The window as recorded in the file's sh_window metadata: NONE, HANNING(width=W), LANCZOS, or
  // for AUTO a summary of the per-probe heat windows (AutoWindowSummary).
  std::string WindowName() const;
  // Stores the estimate of the first `batches` batches as probe `probe` of `volume` (radiance,
  // irradiance and window when requested, std_error, std_error_l0, sample_count, and the
  // visibility moments when the volume has them: per texel mean 1/t, mean 1/t^2 and the ray
  // count; a texel no ray went through reads as all free, (0, 0, 0); the sky transfer, rounded to
  // half precision, when the volume has it). Returns the
  // AUTO window's heat parameter t chosen for this probe (0: left unwindowed; 0 for other windows).
  double Finish(const ProbeEstimate& estimate, int batches, int64_t probe,
                ProbeVolume* volume) const;

 private:
  const BakeSettings& settings_;
  ShBandWindow window_;  // HANNING, LANCZOS: fixed; AUTO: chosen per probe
};

// x rounded to the nearest half-precision (IEEE binary16) number, ties to even; +-inf beyond
// 65504 (the largest half). The precision of the stored sky transfer (docs/volume-format.md).
float RoundToHalf(float x);

// A volume with the layout of `v` (grid, order, active mask, validity, window, planes) whose
// per-probe values are all zero.
ProbeVolume EmptyLike(const ProbeVolume& v);

// Copies every per-probe value of `probe` from one volume to another of the same layout.
void CopyProbe(const ProbeVolume& from, int64_t probe, ProbeVolume* to);

}  // namespace probebake
