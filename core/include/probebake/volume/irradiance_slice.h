// A picture of a bake: the irradiance a surface with a fixed normal would receive, over a plane
// slicing the probe grid (`probebake inspect OUT.vdb --slice z=1.5`).
//
// Image axes (the remaining world axes, the second one pointing up in the picture):
//   x-slice: right = +Y, up = +Z;   y-slice: right = +X, up = +Z;   z-slice: right = +X, up = +Y.
// The image covers every probe cell: probe (i, j) of the plane sits at the centre of a square of
// `pixelsPerProbe` pixels, so the picture spans [min - spacing/2, max + spacing/2] on both axes;
// beyond the outermost probes the field is held constant (clamped interpolation).
//
// Per pixel: the irradiance the reference sampler (probe_sampler.h, default options) reads at the
// pixel's world point for the normal: the 8 surrounding probes with DDGI-style weights (trilinear,
// backface, visibility when the volume has moments, relocation offsets applied), inactive and
// invalid probes (validity < 0.5) skipped; with no usable neighbour the pixel shows a grey
// checker (no data). Irradiance at the normal n is E(n) = sum_i E_i Y_i(n), with E_i the
// irradiance SH when the volume has them, else radiance SH times the band factor A_l
// (docs/spherical-harmonics.md).
//
// Tone mapping: negative values (SH ringing) clip to 0; an exposure maps the given percentile of
// pixel luminance (Rec.709 weights, over data pixels) to 1; values above 1 clip; then the sRGB
// transfer function and 8-bit rounding.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "probebake/bake/probe_volume.h"
#include "probebake/base/status.h"
#include "probebake/math/vec3.h"

namespace probebake {

struct SliceOptions {
  int axis = 2;      // 0 = x, 1 = y, 2 = z: the axis the slice plane is normal to
  double value = 0;  // world coordinate of the plane along `axis`, within the grid's extent
                     // widened by half a spacing on both sides
  // Surface normal for the irradiance (a non-zero vector; normalised here). Default: +axis, e.g.
  // +Z for a z-slice: the light a floor-like surface facing up would receive.
  std::optional<Vec3d> normal;
  int pixelsPerProbe = 16;  // >= 1
  int maxImageSize = 2048;  // >= 1: larger images use fewer pixels per probe (even < 1)
  // Dots (when there are >= 8 pixels per probe) at the probes of the layer nearest the plane:
  // white for valid probes, red for invalid ones; inactive probes are not marked.
  bool markProbes = false;
  double exposurePercentile = 0.99;  // in (0, 1]
};

// Parses the CLI form "<axis>=<value>", e.g. "z=1.5" (axis x, y or z, either case), into
// options->axis and options->value. INVALID_ARGUMENT "slice: <reason>" otherwise.
absl::Status ParseSliceSpec(const std::string& spec, SliceOptions* options);

// An 8-bit sRGB picture, rows top to bottom, 3 bytes per pixel.
struct SliceImage {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
  // The linear irradiance behind each pixel (3 floats per pixel, same order), before exposure;
  // NaN where the pixel has no valid probe.
  std::vector<float> irradiance;
  double exposure = 1;  // the scale applied before clipping and encoding
};

// Renders the slice. INVALID_ARGUMENT naming the option when the options do not fit the volume,
// or when the volume is inconsistent (plane sizes).
absl::StatusOr<SliceImage> RenderIrradianceSlice(const ProbeVolume& volume,
                                                 const SliceOptions& options);

// Renders the slice and writes it as an 8-bit RGB PNG (atomically, like the volume). Errors as
// RenderIrradianceSlice, plus I/O errors naming `pngPath`.
absl::Status WriteIrradianceSlice(const ProbeVolume& volume, const SliceOptions& options,
                                  const std::string& pngPath);

}  // namespace probebake
