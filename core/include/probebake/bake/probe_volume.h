// The result of a bake: per-probe SH radiance (and optionally irradiance), validity, error
// estimates and sample count over a ProbeGrid (docs/volume-format.md). Written to and read from
// .vdb files by probebake/volume/vdb_io.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "probebake/scene/scene.h"

namespace probebake {

struct BakeStats {
  double wallSeconds = 0;
  int threads = 0;
  int64_t probes = 0;         // probes baked (active)
  int64_t samples = 0;        // sample paths, all probes
  int64_t rays = 0;           // every ray traced, shadow rays included
  int64_t invalidProbes = 0;  // baked probes with validity 0
};

struct ProbeVolume {
  ProbeGrid grid;
  int shOrder = 0;
  // Per probe (linear index, ProbeGrid::LinearIndex): 1 if baked (an active voxel), else 0.
  std::vector<uint8_t> active;
  // Coefficient planes: radiance[c][3 * probe + channel] is RGB channel `channel` of SH
  // coefficient c (linear index l(l+1)+m) at `probe`. Planes, not interleaved per probe, so a
  // writer can release each plane once it is stored.
  std::vector<std::vector<float>> radiance;
  // Same layout; empty unless irradiance was requested. The window is applied here only.
  std::vector<std::vector<float>> irradiance;
  // Optional (BakeOptions::coefficientErrors): the standard error of every radiance coefficient
  // and channel, same layout as `radiance`, absolute (radiance units). Not written to files; for
  // tests and the accuracy benchmark.
  std::vector<std::vector<float>> radianceStdError;
  // Per probe, with the AUTO window only: the heat window's t chosen for the probe's irradiance
  // (0: unwindowed). Summarised in `window`; not written as a grid.
  std::vector<float> autoWindowT;
  // Per probe: 1 valid, 0 inside geometry (with relocation: inside and could not be moved).
  std::vector<float> validity;
  // With relocation (BakeSettings::relocationMaxOffset > 0), else empty: per probe 3 floats, the
  // world-space offset (x, y, z) from the grid point to where the probe was baked; 0 for a probe
  // that was not moved.
  std::vector<float> offset;
  // With BakeSettings::visibility, else empty: kVisibilityTexels planes, plane t holding per probe
  // 3 floats (mean 1/t, mean 1/t^2, ray count) of the inverse distances t of the probe's first
  // hits through octahedral texel t (probebake/volume/visibility_map.h).
  std::vector<std::vector<float>> visibility;
  // With dilation (relocation on: probebake/bake/probe_dilation.h), else empty: per probe 1 when
  // its radiance was filled from its neighbours (validity 0), 0 when measured.
  std::vector<float> filled;
  // Per probe, both relative standard errors of luminance estimated from the batch spread
  // (core/src/bake/probe_finish.h, docs/volume-format.md): of the irradiance reconstructed from
  // all coefficients, RMS over the sphere of normals relative to the RMS irradiance; and of the
  // L0 coefficient alone. +inf: unknown.
  std::vector<float> stdError;
  std::vector<float> stdErrorL0;
  std::vector<float> sampleCount;  // per probe: sample paths taken
  // Sky transfer (BakeSettings::skyTransferOrder Ls > 0; docs/volume-format.md), else order 0 and
  // no planes: CoeffCount() x SkyCoeffCount() planes, plane r * SkyCoeffCount() + s holding per
  // probe the RGB of T[r][s], the radiance coefficient r that a sky of radiance Y_s (SH
  // coefficient s = 1, every other 0) adds at the probe. Values are half-precision numbers held as
  // floats (what the file stores). The radiance planes then hold the local lights only:
  // radiance_r + sum_s T[r][s] sky_s is the probe's radiance under the sky sky_s.
  int skyTransferOrder = 0;
  std::vector<std::vector<float>> skyTransfer;
  // Optional (BakeOptions::coefficientErrors with sky transfer): the standard error of every T
  // entry before rounding, same layout. Not written to files; for tests.
  std::vector<std::vector<float>> skyTransferStdError;
  std::string window = "NONE";  // as recorded in the file's sh_window metadata
  BakeStats stats;

  int CoeffCount() const { return (shOrder + 1) * (shOrder + 1); }
  int SkyCoeffCount() const { return (skyTransferOrder + 1) * (skyTransferOrder + 1); }
};

// ProbeVolume::window for the AUTO window: "AUTO(heat exp(-t l(l+1)) per probe; <n> of <m> probes
// windowed, max t=<t>)".
std::string AutoWindowSummary(int64_t windowed, int64_t probes, double maxT);

// Metadata recorded with a volume (docs/volume-format.md) besides what ProbeVolume holds.
struct VolumeMetadata {
  int64_t samplesPerProbe = 0;
  int maxDepth = 0;
  uint64_t seed = 0;
  std::string sceneDigest;
  std::string settingsJson;
  // What the job's files hold that the bake ignored, one item per line ("" when nothing).
  std::string ignored;
};

}  // namespace probebake
