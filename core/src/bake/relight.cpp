#include "probebake/bake/relight.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cmath>
#include <numbers>
#include <string>

#include "environment_light.h"
#include "probe_finish.h"
#include "probebake/base/status.h"
#include "probebake/math/mat3.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/sh/sh_rotation.h"
#include "probebake/sh/sh_window.h"

namespace probebake {

std::vector<Vec3d> ProjectEnvironmentSh(const Environment& env, int order) {
  return EnvironmentLight(env).ProjectSh(order);
}

absl::StatusOr<std::vector<Vec3d>> RotateSkyAboutUp(std::span<const Vec3d> sky, int order,
                                                    double degrees) {
  if (order < 0 || order > kMaxShOrder)
    return absl::InvalidArgumentError("sky: order " + std::to_string(order) + " is outside [0, " +
                                      std::to_string(kMaxShOrder) + "]");
  if (sky.size() != size_t(ShCoeffCount(order)))
    return absl::InvalidArgumentError("sky: " + std::to_string(sky.size()) +
                                      " coefficients for order " + std::to_string(order));
  if (!std::isfinite(degrees))
    return absl::InvalidArgumentError("rotate: the angle must be finite");
  const Mat3d r = Mat3d::Rotation({0, 0, 1}, degrees * std::numbers::pi / 180);
  PB_ASSIGN_OR_RETURN(const ShRotation rotation, ShRotation::Create(order, r));
  std::vector<Vec3d> out(sky.size());
  rotation.ApplyRgb(sky, out);
  return out;
}

absl::StatusOr<ProbeVolume> Relight(const ProbeVolume& volume, std::span<const Vec3d> sky,
                                    const RelightOptions& options) {
  if (volume.skyTransferOrder <= 0)
    return absl::InvalidArgumentError(
        "volume: it has no sky transfer (bake it with settings.skyTransfer.order > 0)");
  const int coeffs = volume.CoeffCount(), skyCoeffs = volume.SkyCoeffCount();
  const int64_t probes = volume.grid.ProbeCount();
  if (volume.skyTransfer.size() != size_t(coeffs) * size_t(skyCoeffs) ||
      volume.radiance.size() != size_t(coeffs))
    return absl::InvalidArgumentError("volume: its sky transfer planes do not match its orders");
  int skyOrder = 0;
  while (size_t(ShCoeffCount(skyOrder)) < sky.size()) ++skyOrder;
  if (size_t(ShCoeffCount(skyOrder)) != sky.size())
    return absl::InvalidArgumentError("sky: " + std::to_string(sky.size()) +
                                      " coefficients, not (order + 1)^2 for any order");
  for (size_t i = 0; i < sky.size(); ++i)
    if (!std::isfinite(sky[i].x) || !std::isfinite(sky[i].y) || !std::isfinite(sky[i].z))
      return absl::InvalidArgumentError("sky: coefficient " + std::to_string(i) + " is not finite");
  // The sky's columns that T has; the rest of T's columns see 0.
  const int used = std::min(skyCoeffs, int(sky.size()));

  // Every field but the transfer, which would be copied only to be freed.
  ProbeVolume out;
  out.grid = volume.grid;
  out.shOrder = volume.shOrder;
  out.active = volume.active;
  out.radiance = volume.radiance;
  out.irradiance = volume.irradiance;
  out.radianceStdError = volume.radianceStdError;
  out.autoWindowT = volume.autoWindowT;
  out.validity = volume.validity;
  out.offset = volume.offset;
  out.visibility = volume.visibility;
  out.filled = volume.filled;
  out.stdError = volume.stdError;
  out.stdErrorL0 = volume.stdErrorL0;
  out.sampleCount = volume.sampleCount;
  out.window = volume.window;
  out.stats = volume.stats;
  const bool irradiance = !volume.irradiance.empty();
  const bool autoWindow = options.window == ShWindow::kAuto;
  ShBandWindow window;
  if (options.window == ShWindow::kHanning) window = ShBandWindow::Hanning(options.windowWidth);
  if (options.window == ShWindow::kLanczos) window = ShBandWindow::Lanczos();
  if (autoWindow && irradiance) out.autoWindowT.assign(size_t(probes), 0.0f);
  std::atomic<bool> overflow{false};
  // Blocks of probes, each plane read along the block: the planes are separate arrays, and a
  // probe at a time would touch (L+1)^2 (Ls+1)^2 of them at once, far more streams than the
  // hardware prefetches (measured 9 s per million probes that way, at L = Ls = 2).
  constexpr int64_t kBlock = 256;
  tbb::parallel_for(
      tbb::blocked_range<int64_t>(0, (probes + kBlock - 1) / kBlock, 1),
      [&](const tbb::blocked_range<int64_t>& blocks) {
        std::vector<Vec3d> sum(size_t(kBlock) * size_t(coeffs));
        std::vector<Vec3d> radiance(static_cast<size_t>(coeffs)), irr(static_cast<size_t>(coeffs));
        for (int64_t block = blocks.begin(); block != blocks.end(); ++block) {
          const int64_t first = block * kBlock, end = std::min(probes, first + kBlock);
          // sum[(p - first) coeffs + r] = local_r + sum_s T_rs sky_s, s in order.
          for (int r = 0; r < coeffs; ++r) {
            const float* local = volume.radiance[size_t(r)].data();
            for (int64_t p = first; p < end; ++p)
              sum[size_t((p - first) * coeffs + r)] =
                  Vec3d(local[3 * p], local[3 * p + 1], local[3 * p + 2]);
            for (int s = 0; s < used; ++s) {
              const float* t = volume.skyTransfer[size_t(r * skyCoeffs + s)].data();
              const Vec3d k = sky[size_t(s)];
              for (int64_t p = first; p < end; ++p)
                sum[size_t((p - first) * coeffs + r)] +=
                    Vec3d(t[3 * p], t[3 * p + 1], t[3 * p + 2]) * k;
            }
          }
          for (int64_t p = first; p < end; ++p) {
            if (!volume.active[size_t(p)]) continue;
            for (int r = 0; r < coeffs; ++r) {
              radiance[size_t(r)] = sum[size_t((p - first) * coeffs + r)];
              float* o = &out.radiance[size_t(r)][3 * size_t(p)];
              for (int ch = 0; ch < 3; ++ch) {
                o[ch] = float(radiance[size_t(r)][ch]);
                if (!std::isfinite(o[ch])) overflow.store(true, std::memory_order_relaxed);
              }
            }
            if (!irradiance) continue;
            RadianceToIrradianceRgb(volume.shOrder, radiance, irr);
            if (autoWindow) {
              const AutoWindowResult chosen = FindAutoShWindow(volume.shOrder, radiance);
              ApplyShWindowRgb(chosen.window, volume.shOrder, irr);
              out.autoWindowT[size_t(p)] = float(chosen.window.parameter);
            } else {
              ApplyShWindowRgb(window, volume.shOrder, irr);
            }
            for (int r = 0; r < coeffs; ++r)
              for (int ch = 0; ch < 3; ++ch)
                out.irradiance[size_t(r)][3 * size_t(p) + size_t(ch)] = float(irr[size_t(r)][ch]);
          }
        }
      });
  if (overflow.load())
    return absl::InvalidArgumentError("sky: the relit radiance overflows 32-bit floats");
  if (autoWindow && irradiance) {
    int64_t windowed = 0, active = 0;
    double maxT = 0;
    for (int64_t p = 0; p < probes; ++p) {
      if (!volume.active[size_t(p)]) continue;
      ++active;
      if (out.autoWindowT[size_t(p)] > 0) ++windowed;
      maxT = std::max(maxT, double(out.autoWindowT[size_t(p)]));
    }
    out.window = AutoWindowSummary(windowed, active, maxT);
  }
  return out;
}

}  // namespace probebake
