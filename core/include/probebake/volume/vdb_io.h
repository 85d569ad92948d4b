// The probe volume file (docs/volume-format.md): one OpenVDB file per bake, readable by stock
// OpenVDB tools and by pyopenvdb. This header exposes no OpenVDB type; OpenVDB lives in two source
// files.
//
// Layout written by WriteProbeVolume (format 2):
// - Grids, in this order: radiance_sh_00 ... radiance_sh_NN (NN = (L+1)^2 - 1, two digits, so
//   L <= 9), Vec3SGrid holding the RGB of SH coefficient i; irradiance_sh_00 ... likewise when
//   ProbeVolume::irradiance is non-empty; validity, std_error, std_error_l0 and sample_count,
//   FloatGrid. No other grids. Values are stored as 32-bit floats exactly as given (never as half),
//   background 0, grid class "unknown", Vec3 grids with vector type "invariant" (RGB does not
//   transform). Each SH grid also carries int32 metadata sh_index, sh_l and sh_m (OpenVDB adds its
//   own file_bbox_min/max, file_voxel_count, file_mem_bytes and file_compression).
// - One transform shared by every grid: a linear scale-translate map with voxel size = probe
//   spacing per axis, so index (i, j, k) maps to world origin + spacing * (i, j, k): integer
//   index coordinates are voxel centres, and voxel centres are probes. The translation is the
//   origin exactly, the voxel size the spacing up to rounding: OpenVDB's Transform constructor
//   re-derives the scale s of a map with translation t as fl(fl(s + t) - t), and makes the map
//   uniform (the x scale on every axis) when the three agree to within 1e-15. So the stored voxel
//   size is within gamma2 (|s| + |t|) + 1e-15 of the spacing, gamma2 = 2u / (1 - 2u), u = 2^-53
//   (e.g. 2/3 at origin 1e5 is stored as 0.6666666666715173). grid_min and grid_spacing below
//   hold the exact doubles.
// - Active voxels are exactly the baked probes (ProbeVolume::active), identical in every grid;
//   inactive voxels hold the background 0: values of unbaked probes are not stored, and read back
//   as 0.
// - Compression: OpenVDB's default for files, blosc + active-mask compression (this OpenVDB build
//   has blosc; zip would be its fallback). Lossless.
// - File metadata (name: OpenVDB metadata type, all readable by pyopenvdb):
//     probebake_format: int32 (4)          sh_order: int32 (L)
//     sh_basis: string ("real-orthonormal-condon-shortley-zpolar")
//     sh_window: string (ProbeVolume::window, e.g. "NONE")
//     quantity: string ("radiance")        has_irradiance: bool
//     color_space: string ("linear-rec709")
//     samples_per_probe: int64             max_depth: int32
//     seed: int64 (the uint64 seed's bits: seeds >= 2^63 read as seed - 2^64 in Python;
//           ReadProbeVolume restores the uint64 exactly)
//     scene_digest: string                 settings: string (JSON, VolumeMetadata::settingsJson)
//     generator: string ("probebake <kVersion>")
//     stats: string (JSON object: wallSeconds (number), threads, probes, samples, rays,
//            invalidProbes (integers)), printed by protobuf's JSON mapping from a
//            google.protobuf.Struct: compact, keys in ascending order, e.g.
//            {"invalidProbes":3,"probes":51,"rays":1099511627776,"samples":26115,"threads":2,
//            "wallSeconds":12.345678901234567}. Struct numbers are doubles: counts must be
//            below 2^53 in magnitude (the writer rejects others; real counts never get near),
//            and print as integer literals below 10^15, possibly in exponent form ("1e+15",
//            still exact) from there to 2^53. wallSeconds must be finite.
//   plus extra keys so a reader can rebuild the ProbeGrid without guessing:
//     grid_counts: vec3i (probes per axis)   grid_min: vec3d   grid_spacing: vec3d
//     grid_placement: string ("ALL", "OUTSIDE_GEOMETRY" or "NEAR_SURFACES")
//     grid_surface_distance: double
// - Not written: ProbeVolume::radianceStdError and ProbeVolume::autoWindowT (the tracer's optional
//   per-coefficient standard errors and per-probe AUTO window t; the format has no grids for them,
//   and sh_window records the window). ReadProbeVolume gives them empty.
// - Atomic: written to a hidden temporary file in the destination's directory, flushed and
//   fsynced, renamed over `path`, then the directory is fsynced. A failed write leaves `path` as it
//   was (absent or the previous file) and no temporary file.
// - Bytes: identical to what openvdb::io::File::write produces for the same grids (written grid
//   by grid through OpenVDB's own archive writer), except the header's random UUID (36
//   characters), which OpenVDB draws anew for every file: the same volume written twice gives
//   files that differ in those bytes only.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "probebake/bake/probe_volume.h"
#include "probebake/base/status.h"

namespace probebake {

// The format written (docs/volume-format.md, "Versions and migration notes"), and the older ones
// ReadProbeVolume still reads (format 3's visibility moments, of distances, are not read).
inline constexpr int kProbeVolumeFormat = 4;
// Format 4 also holds the optional sky transfer (sky_transfer_order > 0, its grids and keys).
inline constexpr int kProbeVolumeFormat4 = 4;
inline constexpr int kProbeVolumeFormat3 = 3;
inline constexpr int kProbeVolumeFormat2 = 2;
inline constexpr int kProbeVolumeFormat1 = 1;
// Largest SH order whose coefficient indices fit the two-digit grid names.
inline constexpr int kMaxVolumeShOrder = 9;

inline constexpr const char* kValidityGridName = "validity";
inline constexpr const char* kStdErrorGridName = "std_error";
inline constexpr const char* kStdErrorL0GridName = "std_error_l0";
inline constexpr const char* kSampleCountGridName = "sample_count";
// Formats 3 and 4, optional: relocation offsets (has_offset), dilation flags (has_filled) and
// the visibility moments (visibility_size > 0: visibility_00 ... one grid per octahedral texel;
// format 4's of 1/t, format 3's of t).
inline constexpr const char* kOffsetGridName = "offset";
inline constexpr const char* kFilledGridName = "filled";
// "visibility_07" for texel 7; texel in [0, 99].
std::string VisibilityGridName(int texel);

// Format 4: "sky_transfer_07_03" for T[7][3] (radiance coefficient 7 from sky coefficient 3);
// both in [0, 99].
std::string SkyTransferGridName(int row, int column);

// "radiance_sh_07" for coefficient 7; coefficient in [0, 99].
std::string RadianceGridName(int coefficient);
// "irradiance_sh_07" for coefficient 7; coefficient in [0, 99].
std::string IrradianceGridName(int coefficient);

// The metadata a volume of `job` records (docs/volume-format.md): the same for a local, a server
// and a merged bake.
VolumeMetadata VolumeMetadataFor(const BakeJob& job);

// Writes `volume` to `path` as described above. Errors: INVALID_ARGUMENT when the volume is
// inconsistent (plane sizes, order > kMaxVolumeShOrder, non-positive spacing, stats that the
// stats JSON cannot hold exactly), naming the field;
// NOT_FOUND / RESOURCE_EXHAUSTED (disk full) / INTERNAL for I/O failures
// (probebake/base/io_error.h), with `path` in the message. Thread safe for distinct paths.
//
// Memory: grids are built, written and freed one at a time, so the extra memory while writing is
// about one grid (one coefficient plane), not a copy of the volume. Measured on a dense 128^3 L2
// volume (242 MiB in memory, a 226 MiB file): +10 to +18 MiB peak resident memory with either
// overload (tests/volume/volume_bench.cpp).
absl::Status WriteProbeVolume(const std::string& path, const ProbeVolume& volume,
                              const VolumeMetadata& meta);
// As above, and releases each coefficient plane of `volume` (radiance, irradiance, validity,
// stdError, sampleCount) as soon as its grid is built, so memory falls while writing;
// radianceStdError and autoWindowT, which are not written, are released before anything else.
// On return, successful or not, those vectors are empty (radiance, irradiance and
// radianceStdError hold no planes) and their memory freed; grid, shOrder, active, window and
// stats are kept.
absl::Status WriteProbeVolume(const std::string& path, ProbeVolume&& volume,
                              const VolumeMetadata& meta);

// Whether a volume could be written to `path` now: its directory exists and takes a new file (a
// temporary one is created and removed), and `path` is not a directory. For callers about to spend
// minutes or hours on what they will write there, so a mistyped path fails first; the write can
// still fail later (a full disk). Errors name the path.
absl::Status CheckOutputWritable(const std::string& path);

// A probe volume file read back.
struct ProbeVolumeFile {
  ProbeVolume volume;
  VolumeMetadata meta;
  int format = kProbeVolumeFormat;  // probebake_format of the file
  // Every file-level metadata entry, its value as text: strings as they are, integers in decimal,
  // bools as "true"/"false", floating point with round-trip precision, vectors as "(x, y, z)".
  std::map<std::string, std::string> rawMetadata;
};

// Reads a file written by WriteProbeVolume, bit for bit: every float, the active mask, the grid
// and the metadata. The grid's origin and spacing are grid_min and grid_spacing, which are
// authoritative (exactly the doubles written); the transform must agree with them: translation
// exactly, voxel size to within the rounding bound above. Without those keys they come from the
// transform. Counts come from grid_counts, or from the active bounding box when that key is
// absent. Validates the format: missing, unexpected or mistyped grids, a transform that is not an
// axis-aligned positive scale + translation or differs between grids, a transform that disagrees
// with grid_min / grid_spacing, active voxels that differ between grids or lie outside the grid,
// metadata of the wrong type. Errors are INVALID_ARGUMENT "<path>: <grid or key>: <reason>"
// (NOT_FOUND when the file does not exist).
// Also reads format 1 (no std_error_l0 grid; its std_error held the L0 figure): that grid goes to
// ProbeVolume::stdErrorL0, and stdError, which format 1 did not record, is +inf (unknown) at
// every active probe. Format 2 is format 3 without its optional grids; format 3 is format 4 with
// moments of distances instead of inverse distances, which are dropped (a volume without
// visibility), and without a sky transfer. With a sky transfer (sky_transfer_order > 0) its grids
// are read into ProbeVolume::skyTransfer as stored, i.e. half-precision values. Other formats are
// refused.
absl::StatusOr<ProbeVolumeFile> ReadProbeVolume(const std::string& path);

}  // namespace probebake
