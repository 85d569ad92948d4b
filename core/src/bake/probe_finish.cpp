#include "probe_finish.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "probebake/base/check.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"

namespace probebake {

ProbeEstimate::ProbeEstimate(int coeffCount, int maxBatches, bool sampledMayBeNonZero)
    : coeffs_(coeffCount),
      sums_(size_t(maxBatches) * 3 * coeffCount, 0.0),
      counts_(maxBatches, 0),
      exact_(size_t(3) * coeffCount, 0.0),
      sampledMayBeNonZero_(sampledMayBeNonZero) {}

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

double ProbeEstimate::RelativeError(int batches) const {
  const int64_t n = Samples(batches);
  auto lumL0 = [](const double* rgb) { return Luminance(Vec3d{rgb[0], rgb[1], rgb[2]}); };
  double sampled = 0;
  for (int b = 0; b < batches; ++b) sampled += lumL0(&sums_[size_t(b) * 3 * coeffs_]);
  sampled = n > 0 ? sampled / double(n) : 0.0;
  const double mean = sampled + lumL0(exact_.data());
  int used = 0;
  double var = 0;
  for (int b = 0; b < batches; ++b) {
    if (counts_[b] == 0) continue;
    const double mb = lumL0(&sums_[size_t(b) * 3 * coeffs_]) / double(counts_[b]);
    const double wb = double(counts_[b]) / double(n);
    var += wb * wb * (mb - sampled) * (mb - sampled);
    ++used;
  }
  if (used < 2) return std::numeric_limits<double>::infinity();
  var *= double(used) / double(used - 1);
  const double se = std::sqrt(var);
  // No spread. All batches black while light could be found: no evidence (0/0 is not 0).
  if (se == 0)
    return sampled == 0 && sampledMayBeNonZero_ ? std::numeric_limits<double>::infinity() : 0;
  return mean != 0 ? se / std::abs(mean) : std::numeric_limits<double>::infinity();
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
  volume->stdError[probe] = float(estimate.RelativeError(batches));
  volume->sampleCount[probe] = float(estimate.Samples(batches));
  return autoT;
}

ProbeVolume EmptyLike(const ProbeVolume& v) {
  ProbeVolume out;
  out.grid = v.grid;
  out.shOrder = v.shOrder;
  out.active = v.active;
  out.validity = v.validity;
  out.window = v.window;
  const size_t planeSize = v.validity.size() * 3;
  out.radiance.assign(v.radiance.size(), std::vector<float>(planeSize, 0.0f));
  out.irradiance.assign(v.irradiance.size(), std::vector<float>(planeSize, 0.0f));
  out.radianceStdError.assign(v.radianceStdError.size(), std::vector<float>(planeSize, 0.0f));
  out.autoWindowT.assign(v.autoWindowT.size(), 0.0f);
  out.stdError.assign(v.stdError.size(), 0.0f);
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
  if (!to->autoWindowT.empty() && from.autoWindowT.size() == to->autoWindowT.size())
    to->autoWindowT[probe] = from.autoWindowT[probe];
  to->stdError[probe] = from.stdError[probe];
  to->sampleCount[probe] = from.sampleCount[probe];
}

}  // namespace probebake
