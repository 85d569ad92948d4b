#include "probe_finish.h"

#include <cmath>
#include <limits>
#include <sstream>

#include <Imath/half.h>

#include "probebake/base/check.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"

namespace probebake {

ProbeEstimate::ProbeEstimate(int coeffCount, int maxBatches, bool sampledMayBeNonZero,
                             bool visibility, int skyCoeffCount)
    : coeffs_(coeffCount),
      sums_(size_t(maxBatches) * 3 * coeffCount, 0.0),
      counts_(maxBatches, 0),
      exact_(size_t(3) * coeffCount, 0.0),
      moments_(visibility ? size_t(maxBatches) * kMomentsSize : 0, 0.0),
      skyCoeffs_(skyCoeffCount),
      transfer_(size_t(maxBatches) * TransferSize(), 0.0),
      sampledMayBeNonZero_(sampledMayBeNonZero) {}

std::vector<double> ProbeEstimate::TransferMean(int batches) const {
  const size_t size = TransferSize();
  const int64_t n = Samples(batches);
  std::vector<double> mean(size, 0.0);
  // In batch order, as Mean: the same bits whatever thread traced each batch.
  for (int b = 0; b < batches; ++b)
    for (size_t k = 0; k < size; ++k) mean[k] += transfer_[size_t(b) * size + k];
  if (n > 0)
    for (double& m : mean) m /= double(n);
  return mean;
}

std::vector<double> ProbeEstimate::TransferErrors(int batches) const {
  const size_t size = TransferSize();
  const int64_t n = Samples(batches);
  int used = 0;
  for (int b = 0; b < batches; ++b) used += counts_[b] > 0 ? 1 : 0;
  if (used < 2) return std::vector<double>(size, std::numeric_limits<double>::infinity());
  const std::vector<double> mean = TransferMean(batches);
  std::vector<double> var(size, 0.0);
  for (int b = 0; b < batches; ++b) {
    if (counts_[b] == 0) continue;
    const double wb = double(counts_[b]) / double(n);
    for (size_t k = 0; k < size; ++k) {
      const double d = transfer_[size_t(b) * size + k] / double(counts_[b]) - mean[k];
      var[k] += wb * wb * d * d;
    }
  }
  for (double& v : var) v = std::sqrt(v * double(used) / double(used - 1));
  return var;
}

std::vector<double> ProbeEstimate::Moments(int batches) const {
  std::vector<double> total(kMomentsSize, 0.0);
  if (moments_.empty()) return total;
  for (int b = 0; b < batches; ++b)
    for (int i = 0; i < kMomentsSize; ++i) total[i] += moments_[size_t(b) * kMomentsSize + i];
  return total;
}

void ProbeEstimate::AddExact(int order, const Vec3d& wi, const Vec3d& radiance) {
  double y[kMaxShCoeffCount];
  EvalShBasis(order, wi, y);
  for (int i = 0; i < coeffs_; ++i) {
    exact_[3 * i] += y[i] * radiance.x;
    exact_[3 * i + 1] += y[i] * radiance.y;
    exact_[3 * i + 2] += y[i] * radiance.z;
  }
}

int64_t ProbeEstimate::Samples(int batches) const {
  int64_t n = 0;
  for (int b = 0; b < batches; ++b) n += counts_[b];
  return n;
}

std::vector<double> ProbeEstimate::Mean(int batches) const {
  const int64_t n = Samples(batches);
  std::vector<double> mean(size_t(3) * coeffs_, 0.0);
  // Batches are summed in index order: the same bits whatever thread traced them.
  for (int b = 0; b < batches; ++b)
    for (size_t k = 0; k < mean.size(); ++k) mean[k] += sums_[size_t(b) * 3 * coeffs_ + k];
  for (size_t k = 0; k < mean.size(); ++k)
    mean[k] = (n > 0 ? mean[k] / double(n) : 0.0) + exact_[k];
  return mean;
}

std::vector<double> ProbeEstimate::CoefficientErrors(int batches) const {
  const int64_t n = Samples(batches);
  const size_t size = size_t(3) * coeffs_;
  std::vector<double> pooled(size, 0.0), var(size, 0.0);
  int used = 0;
  for (int b = 0; b < batches; ++b) {
    if (counts_[b] == 0) continue;
    ++used;
    for (size_t k = 0; k < size; ++k) pooled[k] += sums_[size_t(b) * size + k];
  }
  if (used < 2) return std::vector<double>(size, std::numeric_limits<double>::infinity());
  for (size_t k = 0; k < size; ++k) pooled[k] /= double(n);
  for (int b = 0; b < batches; ++b) {
    if (counts_[b] == 0) continue;
    const double wb = double(counts_[b]) / double(n);
    for (size_t k = 0; k < size; ++k) {
      const double d = sums_[size_t(b) * size + k] / double(counts_[b]) - pooled[k];
      var[k] += wb * wb * d * d;
    }
  }
  for (size_t k = 0; k < size; ++k) var[k] = std::sqrt(var[k] * double(used) / double(used - 1));
  return var;
}

ProbeEstimate::RelativeErrors ProbeEstimate::Relative(int batches) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int64_t n = Samples(batches);
  const auto luminance = [](const double* rgb) { return Luminance(Vec3d{rgb[0], rgb[1], rgb[2]}); };
  // Per coefficient: the sampled pooled mean and the batch spread of luminance.
  std::vector<double> sampled(coeffs_, 0.0), var(coeffs_, 0.0);
  int used = 0;
  for (int b = 0; b < batches; ++b) {
    if (counts_[b] == 0) continue;
    ++used;
    const double* sum = &sums_[size_t(b) * 3 * coeffs_];
    for (int i = 0; i < coeffs_; ++i) sampled[i] += luminance(sum + 3 * i);
  }
  if (used < 2) return {kInf, kInf};
  for (double& m : sampled) m /= double(n);
  for (int b = 0; b < batches; ++b) {
    if (counts_[b] == 0) continue;
    const double* sum = &sums_[size_t(b) * 3 * coeffs_];
    const double wb = double(counts_[b]) / double(n);
    for (int i = 0; i < coeffs_; ++i) {
      const double d = luminance(sum + 3 * i) / double(counts_[b]) - sampled[i];
      var[i] += wb * wb * d * d;
    }
  }
  for (double& v : var) v *= double(used) / double(used - 1);
  // sum_i w_i x_i over the coefficients with w_i = A_l(i)^2.
  double errorSq = 0, sampledSq = 0, meanSq = 0;
  for (int l = 0, i = 0; i < coeffs_; ++l) {
    const double a = IrradianceBandFactor(l);
    for (int m = -l; m <= l; ++m, ++i) {
      const double mean = sampled[i] + luminance(&exact_[3 * i]);
      errorSq += a * a * var[i];
      sampledSq += a * a * sampled[i] * sampled[i];
      meanSq += a * a * mean * mean;
    }
  }
  // No spread. All batches black while light could be found: no evidence (0/0 is not 0).
  const auto relative = [this](double se, double sampledSize, double meanSize) {
    if (se == 0) return sampledSize == 0 && sampledMayBeNonZero_ ? kInf : 0.0;
    return meanSize != 0 ? se / meanSize : kInf;
  };
  return {relative(std::sqrt(errorSq), sampledSq, std::sqrt(meanSq)),
          relative(std::sqrt(var[0]), sampled[0], std::abs(sampled[0] + luminance(exact_.data())))};
}

ProbeFinisher::ProbeFinisher(const BakeSettings& settings) : settings_(settings) {
  if (settings.window == ShWindow::kHanning) window_ = ShBandWindow::Hanning(settings.windowWidth);
  if (settings.window == ShWindow::kLanczos) window_ = ShBandWindow::Lanczos();
}

std::string ProbeFinisher::WindowName() const {
  if (settings_.window == ShWindow::kAuto) return "AUTO";
  return window_.ToString();
}

std::string AutoWindowSummary(int64_t windowed, int64_t probes, double maxT) {
  std::ostringstream s;
  s.precision(6);
  s << "AUTO(heat exp(-t l(l+1)) per probe; " << windowed << " of " << probes
    << " probes windowed, max t=" << maxT << ")";
  return s.str();
}

double ProbeFinisher::Finish(const ProbeEstimate& estimate, int batches, int64_t probe,
                             ProbeVolume* volume) const {
  const int order = settings_.shOrder;
  const int coeffs = ShCoeffCount(order);
  const std::vector<double> mean = estimate.Mean(batches);
  for (int c = 0; c < coeffs; ++c)
    for (int ch = 0; ch < 3; ++ch) volume->radiance[c][3 * probe + ch] = float(mean[3 * c + ch]);
  double autoT = 0;
  if (!volume->irradiance.empty()) {
    std::vector<Vec3d> radiance(coeffs), irradiance(coeffs);
    for (int c = 0; c < coeffs; ++c) radiance[c] = {mean[3 * c], mean[3 * c + 1], mean[3 * c + 2]};
    RadianceToIrradianceRgb(order, radiance, irradiance);
    if (settings_.window == ShWindow::kAuto) {
      const AutoWindowResult chosen = FindAutoShWindow(order, radiance);
      ApplyShWindowRgb(chosen.window, order, irradiance);
      autoT = chosen.window.parameter;
      if (!volume->autoWindowT.empty()) volume->autoWindowT[probe] = float(autoT);
    } else {
      ApplyShWindowRgb(window_, order, irradiance);
    }
    for (int c = 0; c < coeffs; ++c) {
      volume->irradiance[c][3 * probe] = float(irradiance[c].x);
      volume->irradiance[c][3 * probe + 1] = float(irradiance[c].y);
      volume->irradiance[c][3 * probe + 2] = float(irradiance[c].z);
    }
  }
  if (!volume->radianceStdError.empty()) {
    const std::vector<double> se = estimate.CoefficientErrors(batches);
    for (int c = 0; c < coeffs; ++c)
      for (int ch = 0; ch < 3; ++ch)
        volume->radianceStdError[c][3 * probe + ch] = float(se[3 * c + ch]);
  }
  const ProbeEstimate::RelativeErrors errors = estimate.Relative(batches);
  volume->stdError[probe] = float(errors.irradiance);
  volume->stdErrorL0[probe] = float(errors.l0);
  volume->sampleCount[probe] = float(estimate.Samples(batches));
  if (!volume->visibility.empty()) {
    const std::vector<double> m = estimate.Moments(batches);
    for (int t = 0; t < kVisibilityTexels; ++t) {
      const double n = m[3 * t + 2];
      float* out = &volume->visibility[t][3 * size_t(probe)];
      out[0] = float(n > 0 ? m[3 * t] / n : 0.0);
      out[1] = float(n > 0 ? m[3 * t + 1] / n : 0.0);
      out[2] = float(n);
    }
  }
  if (!volume->skyTransfer.empty()) {
    const std::vector<double> t = estimate.TransferMean(batches);
    for (size_t e = 0; e < volume->skyTransfer.size(); ++e)
      for (int ch = 0; ch < 3; ++ch)
        volume->skyTransfer[e][3 * probe + ch] = RoundToHalf(float(t[3 * e + ch]));
    if (!volume->skyTransferStdError.empty()) {
      const std::vector<double> se = estimate.TransferErrors(batches);
      for (size_t e = 0; e < volume->skyTransfer.size(); ++e)
        for (int ch = 0; ch < 3; ++ch)
          volume->skyTransferStdError[e][3 * probe + ch] = float(se[3 * e + ch]);
    }
  }
  return autoT;
}

float RoundToHalf(float x) {
  return float(Imath::half(x));
}

ProbeVolume EmptyLike(const ProbeVolume& v) {
  ProbeVolume out;
  out.grid = v.grid;
  out.shOrder = v.shOrder;
  out.active = v.active;
  out.validity = v.validity;
  out.offset = v.offset;
  out.window = v.window;
  const size_t planeSize = v.validity.size() * 3;
  out.radiance.assign(v.radiance.size(), std::vector<float>(planeSize, 0.0f));
  out.irradiance.assign(v.irradiance.size(), std::vector<float>(planeSize, 0.0f));
  out.radianceStdError.assign(v.radianceStdError.size(), std::vector<float>(planeSize, 0.0f));
  out.visibility.assign(v.visibility.size(), std::vector<float>(planeSize, 0.0f));
  out.skyTransferOrder = v.skyTransferOrder;
  out.skyTransfer.assign(v.skyTransfer.size(), std::vector<float>(planeSize, 0.0f));
  out.skyTransferStdError.assign(v.skyTransferStdError.size(), std::vector<float>(planeSize, 0.0f));
  out.autoWindowT.assign(v.autoWindowT.size(), 0.0f);
  out.stdError.assign(v.stdError.size(), 0.0f);
  out.stdErrorL0.assign(v.stdErrorL0.size(), 0.0f);
  out.sampleCount.assign(v.sampleCount.size(), 0.0f);
  return out;
}

void CopyProbe(const ProbeVolume& from, int64_t probe, ProbeVolume* to) {
  for (size_t c = 0; c < to->radiance.size(); ++c)
    for (int ch = 0; ch < 3; ++ch)
      to->radiance[c][3 * probe + ch] = from.radiance[c][3 * probe + ch];
  if (!to->irradiance.empty() && from.irradiance.size() == to->irradiance.size())
    for (size_t c = 0; c < to->irradiance.size(); ++c)
      for (int ch = 0; ch < 3; ++ch)
        to->irradiance[c][3 * probe + ch] = from.irradiance[c][3 * probe + ch];
  if (!to->radianceStdError.empty() && from.radianceStdError.size() == to->radianceStdError.size())
    for (size_t c = 0; c < to->radianceStdError.size(); ++c)
      for (int ch = 0; ch < 3; ++ch)
        to->radianceStdError[c][3 * probe + ch] = from.radianceStdError[c][3 * probe + ch];
  if (!to->visibility.empty() && from.visibility.size() == to->visibility.size())
    for (size_t t = 0; t < to->visibility.size(); ++t)
      for (int ch = 0; ch < 3; ++ch)
        to->visibility[t][3 * probe + ch] = from.visibility[t][3 * probe + ch];
  for (auto [src, dst] : {std::pair{&from.skyTransfer, &to->skyTransfer},
                          std::pair{&from.skyTransferStdError, &to->skyTransferStdError}}) {
    if (dst->empty() || src->size() != dst->size()) continue;
    for (size_t e = 0; e < dst->size(); ++e)
      for (int ch = 0; ch < 3; ++ch) (*dst)[e][3 * probe + ch] = (*src)[e][3 * probe + ch];
  }
  if (!to->offset.empty() && from.offset.size() == to->offset.size())
    for (int ch = 0; ch < 3; ++ch) to->offset[3 * probe + ch] = from.offset[3 * probe + ch];
  if (!to->autoWindowT.empty() && from.autoWindowT.size() == to->autoWindowT.size())
    to->autoWindowT[probe] = from.autoWindowT[probe];
  to->stdError[probe] = from.stdError[probe];
  to->stdErrorL0[probe] = from.stdErrorL0[probe];
  to->sampleCount[probe] = from.sampleCount[probe];
}

}  // namespace probebake
