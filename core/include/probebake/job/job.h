// From a job to a BakeJob (scene.h): validation, assets, world-space scene in double precision,
// the resolved probe grid and settings, and the digests that key the result cache.
//
//   JobSpec --ValidateJobSpec--> assets from an AssetSource --> BakeJob
//
// Meshes are read with assimp from memory (OBJ, PLY, glTF 2.0 .gltf and .glb, referenced files
// through `assets`): polygons triangulated, points and lines ignored, every mesh of the file merged
// with its node transforms applied, then the job's `transform`, all in double. Without a job
// `material`, the file's own materials, textures and lights apply (docs/job-format.md).
// File vertex positions and node transforms carry the file's (assimp's) single precision; the job
// transform and everything after it is double, so translating a scene by 1e4 changes no bit of the
// relative geometry beyond the double rounding of the translation itself. Zero-area triangles are
// dropped (counted and logged at info); a mesh left with no triangle is an error.
//
// Environment maps are OpenEXR lat-long images read as 32-bit float (RGB, or Y as grey) over their
// data window; pixel <-> map direction is Imf::LatLongMap's; `worldFromMap` is
// Rz_or_y(rotationDeg) * Up, with Up = identity for "Y" and (x, y, z) -> (x, -z, y) for "Z", the
// rotation counter-clockwise seen from above (right-handed about the world up axis).
//
// A feature the job does not use costs nothing: a uniform environment of zero radiance, a map of
// scale 0 and a medium whose coefficients are all zero are left out of the Scene.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/limits.h"
#include "probebake/scene/scene.h"
#include "probebake/v1/job.pb.h"

namespace probebake {

// Validates `job` (ValidateJobSpec), reads its assets from `assets`, and builds the BakeJob.
// INVALID_ARGUMENT naming the field for bad specs and bad assets (unreadable, unparsable, past a
// limit); other codes as the AssetSource returns them (e.g. FAILED_PRECONDITION for a missing
// blob).
//
// BakeJob::sceneDigest: sha256 hex of the deterministic binary serialization of v1::Scene with
// every `file` reference replaced by the blob digest of its content (and a mesh's format made
// explicit and lowercase), so a local bake from files and a server bake from uploaded blobs agree,
// and with defaults folded: a field spelled out with its default value, or one that cannot change
// the bake (a mesh's name, a black environment, a medium with zero coefficients), is written as
// if absent.
// BakeJob::jobDigest: sha256 hex of the deterministic serialization of the JobSpec {that canonical
// scene, the grid as given with its defaults folded likewise (placement OUTSIDE_GEOMETRY, a
// surface distance other placements ignore, three equal spacings), SettingsToProto(resolved
// settings)} followed by
// "\nprobebake-baker-version=<kBakerVersion>": the same numbers baked by the same baker give the
// same digest whichever preset or defaults produced them.
// BakeJob::settingsJson: SettingsToJson(resolved settings).
// Medium bounds: the bounding box of the triangles, the finite lights (point, spot, rect, disk,
// sphere) and the probe grid's box, padded by 1e-4 of its diagonal plus 1e-6 of its largest
// coordinate (at least 1e-6).
absl::StatusOr<BakeJob> BuildBakeJob(const v1::JobSpec& job, const AssetSource& assets,
                                     const JobLimits& limits);

// The environment `spec` describes, as BuildBakeJob builds a job's (validated the same way, its
// files read from `assets`): for tools that need a sky without a scene (probebake relight).
// INVALID_ARGUMENT naming the field ("scene.environment...") for bad specs and files.
absl::StatusOr<Environment> LoadEnvironment(const v1::Environment& spec, const AssetSource& assets,
                                            const JobLimits& limits);

// ReadJobFile + BuildBakeJob with LocalAssetSource(JobFileDir(path), "", limits.maxAssetBytes):
// a local bake's whole input step. Every error line starts with "<path>: ".
absl::StatusOr<BakeJob> LoadBakeJob(const std::string& path, const JobLimits& limits);

// Numbers a quality preset stands for (samplesPerProbe / maxDepth / targetRelError), calibrated
// with the accuracy benchmark (tests/bench): PREVIEW 512 / 6 / 0.05, PRODUCTION 4096 / 8 / 0.02,
// REFERENCE 16384 / 32 / 0.
struct QualityPreset {
  int64_t samplesPerProbe;
  int maxDepth;
  double targetRelError;
};
// settings.shOrder when the job leaves it out.
inline constexpr int kDefaultShOrder = 2;

// The preset's numbers; QUALITY_UNSPECIFIED gives the defaults 1024 / 8 / 0 (no adaptive
// sampling).
QualityPreset PresetFor(v1::BakeSettings::Quality quality);

// Settings with every default and preset resolved (job.proto's defaults: shOrder 2,
// samplesPerProbe / maxDepth / targetRelError from the preset unless given, seed 1, irradiance
// false, window NONE, windowWidth shOrder + 1, NEE_MIS, SOBOL, Russian roulette on, rrMinDepth 3,
// batches 4 (64 when targetRelError > 0), backfaceFraction 0.5). `settings` must have passed
// ValidateJobSpec.
BakeSettings ResolveSettings(const v1::BakeSettings& settings);

// `settings` as a v1::BakeSettings with every field explicit (enums never UNSPECIFIED, quality
// unset). ResolveSettings(SettingsToProto(s)) == s.
v1::BakeSettings SettingsToProto(const BakeSettings& settings);

// SettingsToProto(settings) as compact proto3 JSON (lowerCamelCase, fields in .proto order,
// 64-bit integers as strings): the volume's `settings` metadata. It parses back (ParseJobJson's
// rules) into the same settings.
std::string SettingsToJson(const BakeSettings& settings);

// Probe grid from a validated v1::Grid (docs/job-format.md): with counts, spacing
// (max - min) / (n - 1), and an axis with one probe takes the smallest spacing of the other axes
// (1 when every axis has one probe); with spacing, counts floor((max - min) / spacing + tol) + 1,
// tol covering the rounding of the coordinates (at least 1e-9; grid_internal.h). `grid` must have
// passed ValidateJobSpec.
ProbeGrid ResolveGrid(const v1::Grid& grid);

// The environment map orientation of docs/job-format.md: map direction -> world direction for `up`
// and a rotation of `rotationDeg` about the world up axis, counter-clockwise seen from above. Exact
// for multiples of 90 degrees.
Mat3d EnvironmentWorldFromMap(v1::EnvironmentMap::Up up, double rotationDeg);

}  // namespace probebake
