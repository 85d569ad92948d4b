// Probe exports engines read as they are (`probebake export VOLUME --format F -o OUT`,
// docs/engines.md). Each takes EngineProbes' records (usable probes only) and writes JSON.
//
// three.js (kThreeJs): {"probes": [{"position": [x, y, z], "sh": [[r, g, b] x 9]}, ...]}.
//   Frame: three (x, y, z) = probebake (x, z, -y), a proper rotation (-90 degrees about X).
//   "sh" is what THREE.SphericalHarmonics3.fromArray takes (flattened) and THREE.LightProbe
//   expects: radiance coefficients of three's own basis, which is sh_basis.h's without the
//   Condon-Shortley sign, i.e. coefficients 1, 3, 5 and 7 (m = +-1) negated, after rotating the
//   function into three's frame. three's getIrradianceAt(n) then gives the irradiance E(n) (the
//   clamped-cosine band factors folded in); its shaders multiply by albedo / pi.
// Unity (kUnity): {"frame": ..., "sh_convention": ..., "probes": [{"position": [x, y, z],
//   "sh": [27 numbers]}, ...]}, sh[9 * channel + i] = SphericalHarmonicsL2[channel, i] (flat:
//   Unity's JsonUtility reads no nested arrays).
//   Frame: Unity (x, y, z) = probebake (x, z, y) (sh_unity.h: up stays up, a reflection from
//   right- to left-handed). "sh" holds SphericalHarmonicsL2's coefficients: radiance
//   coefficients of sh_basis.h (Condon-Shortley signs, which Unity's ConvertSHConstants and
//   ShadeSH9 assume), so ShadeSH9(n_unity) = E(n) / pi.
#pragma once

#include <array>
#include <span>
#include <string>

#include "probebake/base/status.h"
#include "probebake/engines/engine_probes.h"
#include "probebake/math/mat3.h"

namespace probebake {

// kTextures: 3D textures for shaders, probe_textures.h.
enum class EngineFormat { kThreeJs, kUnity, kTextures };

// "threejs", "unity" or "textures". INVALID_ARGUMENT
// "--format: unknown format '<s>' (threejs, unity, textures)".
absl::StatusOr<EngineFormat> ParseEngineFormat(const std::string& name);

// Direction maps: n_engine = M n_probebake.
Mat3d ThreeJsFromProbebakeAxes();  // rows (1,0,0), (0,0,1), (0,-1,0)

// L2 radiance in probebake's frame and basis -> three's frame and SphericalHarmonics3 basis.
std::array<Vec3d, 9> ThreeJsSh(std::span<const Vec3d, 9> radiance);
// L2 radiance in probebake's frame and basis -> Unity's frame, SphericalHarmonicsL2 layout
// (coefficient i of channel c is sh[c, i]).
std::array<Vec3d, 9> UnitySh(std::span<const Vec3d, 9> radiance);

// The export file's text for `probes` (those with usable == false are left out); kThreeJs or
// kUnity (checked). Numbers are
// printed with 9 significant digits (floats round-trip).
std::string EngineExportJson(std::span<const EngineProbe> probes, EngineFormat format);

// Writes `text` to `path` atomically (base/atomic_file.h). Errors name the path.
absl::Status WriteTextFileAtomically(const std::string& path, const std::string& text);

// Writes the export of `volume` to `path` atomically (kTextures: also the binary beside it). Errors
// name the volume or the path.
absl::Status WriteEngineExport(const ProbeVolume& volume, EngineFormat format,
                               const std::string& path);

}  // namespace probebake
