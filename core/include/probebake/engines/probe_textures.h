// Probe textures a shader samples directly (`probebake export VOLUME --format textures -o
// OUT.json`, docs/engines.md): the volume's L2 radiance SH as 3D textures over the probe grid, in
// the packing engines use (Unity's APV and Unreal: L0 and L1 in RGBA16F, L2 scaled into RGBA8).
//
// Files: OUT.json (the header below) and its binary beside it, OUT.json with ".json" replaced by
// ".bin" (or ".bin" appended). The binary holds the textures one after the other, in the header's
// order; each is nx * ny * nz texels, x fastest, then y, then z (texel (i, j, k) is probe (i, j,
// k), ProbeGrid::LinearIndex), 4 channels per texel, little-endian:
//   L0_validity  RGBA16F  (L0.r, L0.g, L0.b, usable ? 1 : 0)
//   L1_r, L1_g, L1_b  RGBA16F  (c1, c2, c3, 0) of that colour channel
//   L2_0 .. L2_3  RGBA8 UNORM  the 15 values c4..c8 of r, then of g, then of b, 4 per texel in
//                 that order (the 16th byte is 128), each stored as
//                 q = 128 + round(127 v / l2Scale) in [1, 255], read back as
//                 v = (q - 128) / 127 l2Scale: 0 exactly for 0, so a black probe stays black
// Then, when the volume has them (the header lists what is there):
//   offset_filled  RGBA16F  (offset x, y, z, filled ? 1 : 0): with relocation, the offset from
//                 the grid point to where the probe was baked, scene units (a shader's backface
//                 and visibility weights use grid point + offset; trilinear weights the grid
//                 point), and the dilation flag
//   visibility     RGBA32F  an atlas of 8 nx x 8 ny x nz texels: probe (i, j, k)'s octahedral
//                 texel (column c, row r) (probebake/volume/visibility_map.h) is texel
//                 (8 i + c, 8 j + r, k), holding (mean 1/t, mean 1/t^2, rays, 0); 32-bit
//                 because 1/t^2 of a near hit overflows half
//   sky_transfer   RGBA16F  with a sky transfer of order Ls (S = (Ls+1)^2 columns), an atlas of
//                 S nx x 9 ny x nz texels: T[r][s] of probe (i, j, k) (r < 9, the radiance
//                 coefficients the L0..L2 textures hold) is texel (S i + s, 9 j + r, k), holding
//                 (r, g, b, 0). The L0..L2 textures then hold the local lights only: a shader
//                 adds sum_s T[r][s] sky_s (docs/engines.md, probebake_probes.glsl)
// Coefficients are radiance SH in probebake's frame and basis (sh_basis.h): a shader maps its
// normal into probebake's frame first (three: (x, -z, y) of three's; Unity: (x, z, y) of Unity's).
// Probes that are inactive or unusable (validity < 0.5 and not filled) hold 0 everywhere, alpha 0
// in L0_validity.
// Header: {"format": "probebake-probe-textures", "version": 3 (2 stored L2 as
// round(255 (0.5 + v / (2 l2Scale))), which reads 0 as l2Scale / 255; 1 had no optional textures),
// "counts": [nx, ny, nz],
//   "origin": [x, y, z], "spacing": [x, y, z] (probebake frame; texel centres are probes),
//   "l2Scale": s (max |L2| over usable probes, 1 if all are 0), "skyTransferOrder": Ls (0:
//   none), "bin": "<file name>",
//   "textures": [{"name", "format": "RGBA16F" | "RGBA8" | "RGBA32F", "offset", "bytes"}, ...]}
//   ("offset" in bytes; the atlases also have "size").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "probebake/bake/probe_volume.h"
#include "probebake/base/status.h"

namespace probebake {

struct ProbeTextures {
  std::string headerJson;
  std::vector<uint8_t> bin;
  double l2Scale = 1;
};

// Packs `volume` as above (`binName` is recorded in the header). Errors as EngineProbes.
absl::StatusOr<ProbeTextures> PackProbeTextures(const ProbeVolume& volume,
                                                const std::string& binName);

// Writes OUT.json and its binary (both atomically; the binary first). Errors name the path.
absl::Status WriteProbeTextures(const ProbeVolume& volume, const std::string& jsonPath);

// The binary's path for a header path: ".json" replaced by ".bin", else ".bin" appended.
std::string ProbeTexturesBinPath(const std::string& jsonPath);

}  // namespace probebake
