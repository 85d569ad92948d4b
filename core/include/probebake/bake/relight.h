// Relighting a volume baked with a sky transfer (BakeSettings::skyTransferOrder, docs/job-format.md
// "Sky transfer"): the probe's radiance under a sky is its local radiance plus T times the sky's
// SH, per RGB channel:
//   radiance_r = local_r + sum_s T[r][s] sky_s,   r < (L+1)^2, s < (Ls+1)^2.
// The sky enters at order Ls only: its higher bands (a sun's sharp disk, a horizon's edge) are
// lost, which is the truncation error of relighting (README, "Relighting"). Everything here is a
// pure function of its inputs: the same bits on every run and thread count.
#pragma once

#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/bake/probe_volume.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake {

// The SH coefficients of order `order` (0 to kMaxShOrder; (order+1)^2 RGB entries, radiance
// units) of `env` as a bake sees it: a uniform radiance L projects to L00 = 2 sqrt(pi) L and
// nothing else; a map's radiance (piecewise constant over its pixels' cells, the map's scale and
// rotation applied, core/src/bake/environment_light.h) is integrated cell by cell, with a 3 x 3
// Gauss-Legendre rule in sin(latitude) and longitude (where dw = dz dlon) per cell: the error
// from the rule is far below the float rounding of the map's values for the cells of any map of
// more than a few pixels. A black or absent environment gives zeros.
std::vector<Vec3d> ProjectEnvironmentSh(const Environment& env, int order);

// `sky` (order `order`) rotated about the up axis +Z by `degrees`, counter-clockwise seen from
// above (a map's rotationDeg: rotating a Z-up map by d and projecting it equals projecting it and
// rotating by d). Exact up to rounding (an SH rotation of each band). INVALID_ARGUMENT for an
// order outside [0, kMaxShOrder], a sky of the wrong size or a non-finite angle.
absl::StatusOr<std::vector<Vec3d>> RotateSkyAboutUp(std::span<const Vec3d> sky, int order,
                                                    double degrees);

// How the relit volume's irradiance is made, as the bake did (BakeSettings::window, windowWidth).
struct RelightOptions {
  ShWindow window = ShWindow::kNone;
  double windowWidth = 3;
};

// The volume under `sky`: a volume of the same layout with radiance = local + T sky at every
// active probe (in double, stored as float), irradiance regenerated from it (with the window, the
// AUTO one chosen again per probe) when the volume has irradiance, and no sky transfer (an
// ordinary volume, docs/volume-format.md format 3). Validity, offsets, visibility, sample counts
// and std_error are kept as baked: std_error and std_error_l0 describe the local lights only.
// `sky` holds (Ls'+1)^2 RGB coefficients for any order Ls': bands above the volume's Ls are
// ignored (T has no columns for them), missing ones count as 0. INVALID_ARGUMENT when the volume
// has no sky transfer, its planes are inconsistent, `sky` is not a square count or holds a
// non-finite value, or a relit value overflows float.
absl::StatusOr<ProbeVolume> Relight(const ProbeVolume& volume, std::span<const Vec3d> sky,
                                    const RelightOptions& options = {});

}  // namespace probebake
