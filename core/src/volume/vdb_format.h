// Names and encodings of the probe volume format shared by the writer and the reader
// (docs/volume-format.md; documented in probebake/volume/vdb_io.h). No OpenVDB types here. Private
// to the volume module.
#pragma once

#include <string>

#include "probebake/bake/probe_volume.h"
#include "probebake/base/status.h"

namespace probebake::volume_internal {

// File metadata keys.
inline constexpr const char* kKeyFormat = "probebake_format";
inline constexpr const char* kKeyShOrder = "sh_order";
inline constexpr const char* kKeyShBasis = "sh_basis";
inline constexpr const char* kKeyShWindow = "sh_window";
inline constexpr const char* kKeyQuantity = "quantity";
inline constexpr const char* kKeyHasIrradiance = "has_irradiance";
inline constexpr const char* kKeyColorSpace = "color_space";
inline constexpr const char* kKeySamplesPerProbe = "samples_per_probe";
inline constexpr const char* kKeyMaxDepth = "max_depth";
inline constexpr const char* kKeySeed = "seed";
inline constexpr const char* kKeySceneDigest = "scene_digest";
inline constexpr const char* kKeySettings = "settings";
// Optional (written when non-empty): what the job's files hold that the bake ignored.
inline constexpr const char* kKeyIgnored = "ignored";
inline constexpr const char* kKeyGenerator = "generator";
inline constexpr const char* kKeyStats = "stats";
inline constexpr const char* kKeyGridCounts = "grid_counts";
inline constexpr const char* kKeyGridMin = "grid_min";
inline constexpr const char* kKeyGridSpacing = "grid_spacing";
inline constexpr const char* kKeyGridPlacement = "grid_placement";
inline constexpr const char* kKeyGridSurfaceDistance = "grid_surface_distance";
inline constexpr const char* kKeyHasOffset = "has_offset";
inline constexpr const char* kKeyHasFilled = "has_filled";
inline constexpr const char* kKeyVisibilitySize = "visibility_size";
inline constexpr const char* kKeyVisibilityMaxDistance = "visibility_max_distance";
inline constexpr const char* kKeySkyTransferOrder = "sky_transfer_order";
inline constexpr const char* kKeySkyTransferPrecision = "sky_transfer_precision";
inline constexpr const char* kSkyTransferPrecision = "half";

// Per-grid metadata of SH grids.
inline constexpr const char* kKeyShIndex = "sh_index";
inline constexpr const char* kKeyShL = "sh_l";
inline constexpr const char* kKeyShM = "sh_m";
// Of sky transfer grids: the sky's coefficient (column s; sh_index, sh_l and sh_m give the row).
inline constexpr const char* kKeySkyShIndex = "sky_sh_index";

inline constexpr const char* kShBasis = "real-orthonormal-condon-shortley-zpolar";
inline constexpr const char* kQuantity = "radiance";
inline constexpr const char* kColorSpace = "linear-rec709";

// "ALL", "OUTSIDE_GEOMETRY", "NEAR_SURFACES".
const char* PlacementName(Placement placement);
// Inverse of PlacementName; false for an unknown name.
bool ParsePlacement(const std::string& name, Placement* placement);

// The stats JSON object of the volume format (compact, keys sorted, through protobuf's JSON
// mapping; see proto_json.h) and back; wallSeconds and the counts round-trip exactly.
// INVALID_ARGUMENT "volume.stats.<field>: <reason>" when wallSeconds is not finite or a count's
// magnitude is not below 2^53 (JSON numbers are doubles).
absl::StatusOr<std::string> StatsToJson(const BakeStats& stats);
// INVALID_ARGUMENT "stats: <reason>" when `json` is not such an object (every key present,
// counts integral numbers below 2^53 in magnitude, threads in int range).
absl::Status StatsFromJson(const std::string& json, BakeStats* stats);

// INVALID_ARGUMENT naming the field when `volume`'s sizes, order or grid are inconsistent.
absl::Status ValidateVolume(const ProbeVolume& volume);

// Calls openvdb::initialize() exactly once per process, from any thread.
void InitializeOpenVdbOnce();

}  // namespace probebake::volume_internal
