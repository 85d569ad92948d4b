#include "bench_metrics.h"

#include <algorithm>
#include <cmath>

#include "bench_util.h"
#include "probebake/base/check.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/sh/sphere_quadrature.h"

namespace probebake::bench {
namespace {

int BandOf(int index) {
  int l = 0;
  while ((l + 1) * (l + 1) <= index) ++l;
  return l;
}

}  // namespace

std::vector<ProbeErrors> CompareWithReference(const ProbeVolume& volume,
                                              const Reference& reference) {
  const int order = volume.shOrder;
  const int coeffs = volume.CoeffCount();
  PB_CHECK_LE(order, reference.order);
  PB_CHECK_EQ(volume.radianceStdError.size(), size_t(coeffs));
  PB_CHECK_EQ(reference.active.size(), size_t(volume.grid.ProbeCount()));
  const std::vector<SphereQuadratureNode> rule = SphereQuadratureForDegree(2 * order);
  std::vector<double> band(coeffs);
  for (int c = 0; c < coeffs; ++c) band[c] = IrradianceBandFactor(BandOf(c));

  std::vector<ProbeErrors> out;
  std::vector<Vec3d> bake(coeffs), ref(coeffs);
  for (int64_t p = 0; p < volume.grid.ProbeCount(); ++p) {
    if (!volume.active[p] || volume.validity[p] == 0.0f || !reference.active[p]) continue;
    double radErr2 = 0, radRef2 = 0, predicted2 = 0, predictedRef2 = 0, parsevalErr2 = 0,
           parsevalRef2 = 0, lumErr2 = 0, lumRef2 = 0;
    for (int c = 0; c < coeffs; ++c) {
      const double lumBake = Luminance(Vec3d(
          volume.radiance[c][3 * p], volume.radiance[c][3 * p + 1], volume.radiance[c][3 * p + 2]));
      const double lumRef = Luminance(reference.radiance[p][c]);
      lumErr2 += band[c] * band[c] * (lumBake - lumRef) * (lumBake - lumRef);
      lumRef2 += band[c] * band[c] * lumRef * lumRef;
      for (int ch = 0; ch < 3; ++ch) {
        bake[c][ch] = volume.radiance[c][3 * p + ch];
        ref[c][ch] = reference.radiance[p][c][ch];
        const double d = bake[c][ch] - ref[c][ch];
        radErr2 += d * d;
        radRef2 += ref[c][ch] * ref[c][ch];
        parsevalErr2 += band[c] * band[c] * d * d;
        parsevalRef2 += band[c] * band[c] * ref[c][ch] * ref[c][ch];
        const double se = volume.radianceStdError[c][3 * p + ch];
        const double seRef = reference.stdError[p][c][ch];
        predicted2 += band[c] * band[c] * se * se;
        predictedRef2 += band[c] * band[c] * seRef * seRef;
      }
    }
    double irrErr2 = 0, irrRef2 = 0;
    for (const SphereQuadratureNode& node : rule) {
      const Vec3d eb = IrradianceAtRgb(order, bake, node.direction);
      const Vec3d er = IrradianceAtRgb(order, ref, node.direction);
      const Vec3d d = eb - er;
      irrErr2 += node.weight * Dot(d, d);
      irrRef2 += node.weight * Dot(er, er);
    }
    if (!(irrRef2 > 0)) continue;  // a black reference probe has no relative error
    // The quadrature is exact for these polynomials: it must agree with Parseval.
    PB_CHECK_LE(std::abs(irrRef2 - parsevalRef2), 1e-9 * parsevalRef2);
    PB_CHECK_LE(std::abs(irrErr2 - parsevalErr2), 1e-9 * parsevalRef2 + 1e-9 * parsevalErr2);

    ProbeErrors e;
    e.probe = p;
    e.irradianceRel = std::sqrt(irrErr2 / irrRef2);
    e.radianceRel = std::sqrt(radErr2 / radRef2);
    const double lumRef = Luminance(ref[0]);
    e.l0Signed = (Luminance(bake[0]) - lumRef) / std::abs(lumRef);
    e.l0Rel = std::abs(e.l0Signed);
    e.irradianceLumRel = lumRef2 > 0 ? std::sqrt(lumErr2 / lumRef2) : 0;
    e.stdError = volume.stdError[p];
    e.stdErrorL0 = volume.stdErrorL0[p];
    e.refRelStdError = reference.relStdError[p];
    e.refRelStdErrorL0 = reference.relStdErrorL0[p];
    e.irradiancePredicted = std::sqrt(predicted2 / irrRef2);
    e.irradiancePredictedRef = std::sqrt(predictedRef2 / irrRef2);
    e.samples = volume.sampleCount[p];
    out.push_back(e);
  }
  return out;
}

ErrorSummary Summarise(const std::vector<ProbeErrors>& errors) {
  ErrorSummary s;
  s.probes = int64_t(errors.size());
  if (errors.empty()) return s;
  std::vector<double> irr;
  double l0Sq = 0, seSq = 0, expectedSq = 0, expectedL0Sq = 0, irrSq = 0, expectedIrrSq = 0,
         lumSq = 0;
  for (const ProbeErrors& e : errors) {
    irr.push_back(e.irradianceRel);
    s.meanIrradianceRel += e.irradianceRel;
    s.maxIrradianceRel = std::max(s.maxIrradianceRel, e.irradianceRel);
    s.meanRadianceRel += e.radianceRel;
    l0Sq += e.l0Rel * e.l0Rel;
    lumSq += e.irradianceLumRel * e.irradianceLumRel;
    s.meanStdError += e.stdError;
    s.meanStdErrorL0 += e.stdErrorL0;
    seSq += e.stdError * e.stdError;
    expectedSq += e.stdError * e.stdError + e.refRelStdError * e.refRelStdError;
    expectedL0Sq += e.stdErrorL0 * e.stdErrorL0 + e.refRelStdErrorL0 * e.refRelStdErrorL0;
    irrSq += e.irradianceRel * e.irradianceRel;
    expectedIrrSq += e.irradiancePredicted * e.irradiancePredicted +
                     e.irradiancePredictedRef * e.irradiancePredictedRef;
    s.meanSamples += e.samples;
    s.meanSignedL0 += e.l0Signed;
    s.refMeanIrradianceRel += e.irradiancePredictedRef;
    s.refMeanStdError += e.refRelStdError;
  }
  const double n = double(errors.size());
  s.meanIrradianceRel /= n;
  s.medianIrradianceRel = Median(irr);
  s.rmsIrradianceRel = std::sqrt(irrSq / n);
  s.meanRadianceRel /= n;
  s.rmsL0Rel = std::sqrt(l0Sq / n);
  s.rmsIrradianceLumRel = std::sqrt(lumSq / n);
  s.meanStdError /= n;
  s.meanStdErrorL0 /= n;
  s.rmsStdError = std::sqrt(seSq / n);
  s.honesty = expectedSq > 0 ? s.rmsIrradianceLumRel / std::sqrt(expectedSq / n) : 0;
  s.honestyL0 = expectedL0Sq > 0 ? s.rmsL0Rel / std::sqrt(expectedL0Sq / n) : 0;
  s.honestyIrradiance = expectedIrrSq > 0 ? s.rmsIrradianceRel / std::sqrt(expectedIrrSq / n) : 0;
  s.meanSamples /= n;
  s.meanSignedL0 /= n;
  s.meanSignedL0StdError = std::sqrt(expectedL0Sq) / n;
  s.refMeanIrradianceRel /= n;
  s.refMeanStdError /= n;
  return s;
}

}  // namespace probebake::bench
