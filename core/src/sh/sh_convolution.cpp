#include "probebake/sh/sh_convolution.h"

#include <cmath>
#include <cstdint>
#include <numbers>

#include "probebake/base/check.h"
#include "probebake/sh/sh_basis.h"

namespace probebake {
namespace {

constexpr double kPi = std::numbers::pi;

// Â_l by the closed form. The central binomial C(l, l/2) is exact in a double up to l = 56
// (C(56, 28) < 2^53), and C/2^l is then exact too, so Â_l takes three roundings (2π, the
// product, the division). Beyond, C/2^l = Π (2k-1)/(2k) is formed as a product (l/2 roundings).
constexpr double IrradianceFactor(int l) {
  if (l == 1) return 2 * kPi / 3;
  if (l % 2 == 1) return 0;
  const int h = l / 2;
  double central;  // C(l, l/2) / 2^l
  if (l <= 56) {
    uint64_t c = 1;
    for (int i = 1; i <= h; ++i) c = c * static_cast<uint64_t>(h + i) / static_cast<uint64_t>(i);
    double pow2 = 1;
    for (int i = 0; i < l; ++i) pow2 *= 2;
    central = static_cast<double>(c) / pow2;
  } else {
    central = 1;
    for (int k = 1; k <= h; ++k) central *= (2.0 * k - 1) / (2.0 * k);
  }
  const double sign = (h % 2 == 1) ? 1.0 : -1.0;  // (-1)^(l/2 - 1)
  return sign * (2 * kPi * central) / ((l + 2.0) * (l - 1.0));
}

struct IrradianceTable {
  double factor[kMaxShOrder + 1];
};

constexpr IrradianceTable MakeIrradianceTable() {
  IrradianceTable t{};
  for (int l = 0; l <= kMaxShOrder; ++l) t.factor[l] = IrradianceFactor(l);
  return t;
}

constexpr IrradianceTable kIrradiance = MakeIrradianceTable();

void CheckSizes(int order, size_t in, size_t out) {
  PB_CHECK(order >= 0 && order <= kMaxShOrder);
  const size_t count = static_cast<size_t>(ShCoeffCount(order));
  PB_CHECK_GE(in, count);
  PB_CHECK_GE(out, count);
}

}  // namespace

double IrradianceBandFactor(int l) {
  PB_CHECK_GE(l, 0);
  return l <= kMaxShOrder ? kIrradiance.factor[l] : IrradianceFactor(l);
}

double CosinePowerBandFactor(int l, double n) {
  PB_CHECK_GE(l, 0);
  PB_CHECK(n >= 0 && std::isfinite(n));
  // I_l = ∫_0^1 P_l(u) u^n du. The ratio I_{l+2}/I_l = (n - l)/(n + l + 3) follows from
  // I_l = sqrt(π) 2^(-n-1) Γ(n+1) / (Γ(1 + (n-l)/2) Γ((n+l+3)/2)) (Gradshteyn–Ryzhik 7.126.2).
  double integral = (l % 2 == 0) ? 1 / (n + 1) : 1 / (n + 2);
  for (int k = l % 2; k + 2 <= l; k += 2) integral *= (n - k) / (n + k + 3);
  return 2 * kPi * integral;
}

double HenyeyGreensteinBandFactor(int l, double g) {
  PB_CHECK_GE(l, 0);
  PB_CHECK(g >= -1 && g <= 1);
  double p = 1;
  for (int k = 0; k < l; ++k) p *= g;
  return p;
}

void ScaleBands(int order, std::span<const double> factors, std::span<const double> in,
                std::span<double> out) {
  CheckSizes(order, in.size(), out.size());
  PB_CHECK_GE(factors.size(), static_cast<size_t>(order + 1));
  for (int l = 0; l <= order; ++l) {
    for (int i = l * l; i < (l + 1) * (l + 1); ++i) out[i] = factors[l] * in[i];
  }
}

void ScaleBandsRgb(int order, std::span<const double> factors, std::span<const Vec3d> in,
                   std::span<Vec3d> out) {
  CheckSizes(order, in.size(), out.size());
  PB_CHECK_GE(factors.size(), static_cast<size_t>(order + 1));
  for (int l = 0; l <= order; ++l) {
    for (int i = l * l; i < (l + 1) * (l + 1); ++i) out[i] = factors[l] * in[i];
  }
}

void ConvolveZonal(int order, std::span<const double> zonal, std::span<const double> in,
                   std::span<double> out) {
  PB_CHECK_GE(zonal.size(), static_cast<size_t>(order + 1));
  double factors[kMaxShOrder + 1];
  for (int l = 0; l <= order && l <= kMaxShOrder; ++l) {
    factors[l] = std::sqrt(4 * kPi / (2 * l + 1)) * zonal[l];
  }
  ScaleBands(order, factors, in, out);
}

void RadianceToIrradiance(int order, std::span<const double> radiance,
                          std::span<double> irradiance) {
  ScaleBands(order, kIrradiance.factor, radiance, irradiance);
}

void RadianceToIrradianceRgb(int order, std::span<const Vec3d> radiance,
                             std::span<Vec3d> irradiance) {
  ScaleBandsRgb(order, kIrradiance.factor, radiance, irradiance);
}

double IrradianceAt(int order, std::span<const double> radiance, const Vec3d& normal) {
  CheckSizes(order, radiance.size(), radiance.size());
  double y[kMaxShCoeffCount];
  EvalShBasis(order, normal, y);
  double e = 0;
  for (int l = 0; l <= order; ++l) {
    if (kIrradiance.factor[l] == 0) continue;
    double band = 0;
    for (int i = l * l; i < (l + 1) * (l + 1); ++i) band += radiance[i] * y[i];
    e += kIrradiance.factor[l] * band;
  }
  return e;
}

Vec3d IrradianceAtRgb(int order, std::span<const Vec3d> radiance, const Vec3d& normal) {
  CheckSizes(order, radiance.size(), radiance.size());
  double y[kMaxShCoeffCount];
  EvalShBasis(order, normal, y);
  Vec3d e;
  for (int l = 0; l <= order; ++l) {
    if (kIrradiance.factor[l] == 0) continue;
    Vec3d band;
    for (int i = l * l; i < (l + 1) * (l + 1); ++i) band += radiance[i] * y[i];
    e += kIrradiance.factor[l] * band;
  }
  return e;
}

void CosinePowerLobe(int order, double n, const Vec3d& d, std::span<double> out) {
  CheckSizes(order, out.size(), out.size());
  double factors[kMaxShOrder + 1];
  for (int l = 0; l <= order; ++l) factors[l] = CosinePowerBandFactor(l, n);
  EvalShBasis(order, d, out.data());
  ScaleBands(order, factors, out, out);
}

void HenyeyGreensteinLobe(int order, double g, const Vec3d& d, std::span<double> out) {
  CheckSizes(order, out.size(), out.size());
  double factors[kMaxShOrder + 1];
  for (int l = 0; l <= order; ++l) factors[l] = HenyeyGreensteinBandFactor(l, g);
  EvalShBasis(order, d, out.data());
  ScaleBands(order, factors, out, out);
}

}  // namespace probebake
