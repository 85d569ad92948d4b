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

  ProbeVolume out = volume;
  out.skyTransferOrder = 0;
  std::vector<std::vector<float>>().swap(out.skyTransfer);
  std::vector<std::vector<float>>().swap(out.skyTransferStdError);
  const bool irradiance = !volume.irradiance.empty();
  const bool autoWindow = options.window == ShWindow::kAuto;
  ShBandWindow window;
  if (options.window == ShWindow::kHanning) window = ShBandWindow::Hanning(options.windowWidth);
  if (options.window == ShWindow::kLanczos) window = ShBandWindow::Lanczos();
  if (autoWindow && irradiance) out.autoWindowT.assign(size_t(probes), 0.0f);
  std::atomic<bool> overflow{false};
  tbb::parallel_for(
      tbb::blocked_range<int64_t>(0, probes, 256), [&](const tbb::blocked_range<int64_t>& range) {
        std::vector<Vec3d> radiance(static_cast<size_t>(coeffs)), irr(static_cast<size_t>(coeffs));
        for (int64_t p = range.begin(); p != range.end(); ++p) {
          if (!volume.active[size_t(p)]) continue;
          for (int r = 0; r < coeffs; ++r) {
            const float* local = &volume.radiance[size_t(r)][3 * size_t(p)];
            Vec3d sum(local[0], local[1], local[2]);
            for (int s = 0; s < used; ++s) {
              const float* t = &volume.skyTransfer[size_t(r * skyCoeffs + s)][3 * size_t(p)];
              sum += Vec3d(t[0], t[1], t[2]) * sky[size_t(s)];
            }
            radiance[size_t(r)] = sum;
            float* o = &out.radiance[size_t(r)][3 * size_t(p)];
            for (int ch = 0; ch < 3; ++ch) {
              o[ch] = float(sum[ch]);
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
