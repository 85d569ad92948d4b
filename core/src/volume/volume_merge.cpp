#include "probebake/volume/volume_merge.h"

#include "probebake/bake/probe_dilation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace probebake {
namespace {

constexpr const char* kAutoPrefix = "AUTO(";

absl::Status PartError(size_t i, const VolumePart& part, const std::string& field,
                       const std::string& reason) {
  return absl::InvalidArgumentError(
      absl::StrCat("part ", i, " (", part.name, "): ", field, ": ", reason));
}

// The counts in an AUTO window summary: "AUTO(... <n> of <m> probes windowed, max t=<t>)".
bool ParseAutoSummary(const std::string& window, long long* windowed, long long* probes,
                      double* maxT) {
  const size_t semi = window.find("; ");
  if (window.rfind(kAutoPrefix, 0) != 0 || semi == std::string::npos) return false;
  return std::sscanf(window.c_str() + semi, "; %lld of %lld probes windowed, max t=%lf)", windowed,
                     probes, maxT) == 3;
}

// A double as text that tells every double apart.
std::string Exact(double x) {
  return absl::StrFormat("%.17g", x);
}

// Which of a part's fields must equal the first part's: name and the text of each.
std::vector<std::pair<std::string, std::string>> Invariants(const ProbeVolumeFile& f) {
  const ProbeVolume& v = f.volume;
  const bool autoWindow = v.window.rfind(kAutoPrefix, 0) == 0;
  return {
      // Parts of two formats come from two bakers, whose bits differ.
      {"probebake_format", std::to_string(f.format)},
      {"sh_order", std::to_string(v.shOrder)},
      {"has_irradiance", v.irradiance.empty() ? "false" : "true"},
      {"has_offset", v.offset.empty() ? "false" : "true"},
      {"has_filled", v.filled.empty() ? "false" : "true"},
      {"visibility_size", std::to_string(v.visibility.size())},
      {"sky_transfer_order", std::to_string(v.skyTransferOrder)},
      {"sh_window", autoWindow ? "AUTO" : v.window},
      {"grid_placement", std::to_string(int(v.grid.placement))},
      {"grid_surface_distance", Exact(v.grid.surfaceDistance)},
      {"grid_spacing", absl::StrCat(Exact(v.grid.spacing.x), ", ", Exact(v.grid.spacing.y), ", ",
                                    Exact(v.grid.spacing.z))},
      {"samples_per_probe", std::to_string(f.meta.samplesPerProbe)},
      {"max_depth", std::to_string(f.meta.maxDepth)},
      {"seed", std::to_string(f.meta.seed)},
      {"scene_digest", f.meta.sceneDigest},
      {"settings", f.meta.settingsJson},
      {"generator", f.rawMetadata.count("generator") ? f.rawMetadata.at("generator") : ""},
  };
}

bool SameBits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

}  // namespace

absl::StatusOr<ProbeVolumeFile> MergeProbeVolumes(std::vector<VolumePart> parts) {
  if (parts.empty()) return absl::InvalidArgumentError("no volumes to merge");
  const ProbeVolume& first = parts[0].file.volume;
  const auto reference = Invariants(parts[0].file);
  const Vec3d spacing = first.grid.spacing;

  // Each part's offset on the first part's lattice, and the union's bounds in lattice steps.
  std::vector<std::array<int64_t, 3>> offsets(parts.size());
  std::array<int64_t, 3> lo{0, 0, 0}, hi{0, 0, 0};
  std::array<size_t, 3> lowestPart{0, 0, 0};
  for (size_t i = 0; i < parts.size(); ++i) {
    const ProbeVolumeFile& f = parts[i].file;
    const auto fields = Invariants(f);
    for (size_t k = 0; k < fields.size(); ++k) {
      if (fields[k].second != reference[k].second)
        return PartError(
            i, parts[i], fields[k].first,
            "'" + fields[k].second + "' differs from part 0's '" + reference[k].second + "'");
    }
    for (int a = 0; a < 3; ++a) {
      const double steps = (f.volume.grid.origin[a] - first.grid.origin[a]) / spacing[a];
      const double n = std::nearbyint(steps);
      if (!(std::abs(steps - n) <= 1e-6) || std::abs(n) > 1e9)
        return PartError(
            i, parts[i], "grid_min",
            absl::StrCat("not on part 0's lattice (", steps, " steps along axis ", a, ")"));
      offsets[i][a] = int64_t(n);
      if (i == 0 || offsets[i][a] < lo[a]) {
        lo[a] = offsets[i][a];
        lowestPart[a] = i;
      }
      const int64_t last = offsets[i][a] + f.volume.grid.counts[a] - 1;
      if (i == 0 || last > hi[a]) hi[a] = last;
    }
  }

  ProbeVolumeFile merged;
  merged.meta = parts[0].file.meta;
  ProbeVolume& out = merged.volume;
  out.grid = first.grid;
  for (int a = 0; a < 3; ++a) {
    out.grid.origin[a] = parts[lowestPart[a]].file.volume.grid.origin[a];
    const int64_t count = hi[a] - lo[a] + 1;
    if (count > (int64_t(1) << 30))
      return absl::InvalidArgumentError(absl::StrCat("merged grid too large along axis ", a));
    out.grid.counts[a] = int(count);
  }
  const int64_t probeCount = out.grid.ProbeCount();
  // The merged volume is dense over the parts' bounding box: parts far apart would allocate a
  // grid mostly empty (and possibly past memory). Sub-grids of one grid tile it.
  int64_t partProbes = 0;
  for (const VolumePart& part : parts) partProbes += part.file.volume.grid.ProbeCount();
  if (probeCount > 2 * partProbes + (int64_t(1) << 20))
    return absl::InvalidArgumentError(
        absl::StrCat("the parts hold ", partProbes, " probes but their bounding box ", probeCount,
                     ": they are not sub-grids tiling one grid (or far apart on its lattice)"));
  const int coeffs = first.CoeffCount();
  out.shOrder = first.shOrder;
  out.window = first.window;
  out.active.assign(probeCount, 0);
  out.validity.assign(probeCount, 0.0f);
  out.stdError.assign(probeCount, 0.0f);
  out.stdErrorL0.assign(probeCount, 0.0f);
  out.sampleCount.assign(probeCount, 0.0f);
  out.radiance.assign(coeffs, std::vector<float>(3 * probeCount, 0.0f));
  if (!first.irradiance.empty())
    out.irradiance.assign(coeffs, std::vector<float>(3 * probeCount, 0.0f));
  if (!first.offset.empty()) out.offset.assign(3 * probeCount, 0.0f);
  if (!first.filled.empty()) out.filled.assign(probeCount, 0.0f);
  out.visibility.assign(first.visibility.size(), std::vector<float>(3 * probeCount, 0.0f));
  out.skyTransferOrder = first.skyTransferOrder;
  out.skyTransfer.assign(first.skyTransfer.size(), std::vector<float>(3 * probeCount, 0.0f));

  const bool autoWindow = first.window.rfind(kAutoPrefix, 0) == 0;
  long long windowed = 0, autoProbes = 0;
  double maxT = 0;
  for (size_t i = 0; i < parts.size(); ++i) {
    const ProbeVolume& v = parts[i].file.volume;
    for (int64_t p = 0; p < v.grid.ProbeCount(); ++p) {
      if (!v.active[p]) continue;
      int x, y, z;
      v.grid.Coords(p, &x, &y, &z);
      const int64_t q =
          out.grid.LinearIndex(int(x + offsets[i][0] - lo[0]), int(y + offsets[i][1] - lo[1]),
                               int(z + offsets[i][2] - lo[2]));
      // Copies every value of the probe, noting whether an earlier part left other bits there.
      bool same = true;
      auto put = [&](float& to, float from) {
        same = same && SameBits(to, from);
        to = from;
      };
      // Dilated values are recomputed below from the merged neighbours (a part saw only its
      // own): not compared.
      const bool refilled = !out.filled.empty() && !(v.validity[p] >= 0.5f);
      auto putBaked = [&](float& to, float from) {
        if (refilled) {
          to = from;
        } else {
          put(to, from);
        }
      };
      const bool seen = out.active[q] != 0;
      put(out.validity[q], v.validity[p]);
      put(out.stdError[q], v.stdError[p]);
      put(out.stdErrorL0[q], v.stdErrorL0[p]);
      put(out.sampleCount[q], v.sampleCount[p]);
      if (!out.filled.empty()) putBaked(out.filled[q], v.filled[p]);
      for (int ch = 0; ch < 3; ++ch) {
        if (!out.offset.empty()) put(out.offset[3 * q + ch], v.offset[3 * p + ch]);
        for (size_t t = 0; t < out.visibility.size(); ++t)
          put(out.visibility[t][3 * q + ch], v.visibility[t][3 * p + ch]);
        for (size_t e = 0; e < out.skyTransfer.size(); ++e)
          put(out.skyTransfer[e][3 * q + ch], v.skyTransfer[e][3 * p + ch]);
      }
      for (int c = 0; c < coeffs; ++c) {
        for (int ch = 0; ch < 3; ++ch) {
          putBaked(out.radiance[c][3 * q + ch], v.radiance[c][3 * p + ch]);
          if (!out.irradiance.empty())
            putBaked(out.irradiance[c][3 * q + ch], v.irradiance[c][3 * p + ch]);
        }
      }
      if (seen && !same)
        return PartError(i, parts[i], "probe",
                         absl::StrCat("(", x, ", ", y, ", ", z,
                                      ") is also in an earlier part, with different values"));
      if (seen && autoWindow)
        return PartError(i, parts[i], "probe",
                         absl::StrCat("(", x, ", ", y, ", ", z,
                                      ") is also in an earlier part: parts with the AUTO window "
                                      "must not overlap"));
      out.active[q] = 1;
    }
    const BakeStats& s = v.stats;
    out.stats.wallSeconds = std::max(out.stats.wallSeconds, s.wallSeconds);
    out.stats.threads += s.threads;
    out.stats.samples += s.samples;
    out.stats.rays += s.rays;
    if (autoWindow) {
      long long n = 0, m = 0;
      double t = 0;
      if (!ParseAutoSummary(v.window, &n, &m, &t))
        return PartError(i, parts[i], "sh_window", "unreadable AUTO summary '" + v.window + "'");
      windowed += n, autoProbes += m, maxT = std::max(maxT, t);
    }
  }
  if (autoWindow) out.window = AutoWindowSummary(windowed, autoProbes, maxT);
  if (!out.filled.empty()) DilateProbes(&out);
  // As a bake counts them, over the merged volume: parts that overlap hold some probes twice.
  for (int64_t q = 0; q < probeCount; ++q) {
    if (!out.active[q]) continue;
    ++out.stats.probes;
    if (out.validity[q] == 0.0f) ++out.stats.invalidProbes;
  }
  return merged;
}

}  // namespace probebake
