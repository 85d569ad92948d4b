// `probebake inspect`: what a probe volume file holds, for people (FormatVolumeReport) and for
// scripts (VolumeReportJson). Works on any OpenVDB file; probebake-specific figures (probe count,
// invalid probes) come from the validity grid when there is one.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "probebake/base/status.h"

namespace probebake {

struct MetadataEntry {
  std::string name;
  std::string type;   // OpenVDB's type name: "int32", "int64", "bool", "string", "vec3i", ...
  std::string value;  // as text (see ProbeVolumeFile::rawMetadata)
};

struct GridReport {
  std::string name;
  std::string type;       // OpenVDB's grid type, e.g. "Tree_float_5_4_3", "Tree_vec3s_5_4_3"
  std::string valueType;  // "float", "vec3s", ...
  int64_t activeVoxels = 0;
  // Index-space bounding box of the active voxels, inclusive; meaningless when activeVoxels = 0.
  int bboxMin[3] = {0, 0, 0};
  int bboxMax[3] = {0, 0, 0};
  // Per channel (1 for float grids, 3 for vec3s grids, 0 for other value types) over the active
  // voxels whose every channel is finite: minimum, maximum and mean, accumulated in double; 0
  // when there are none.
  int channels = 0;
  double min[3] = {0, 0, 0};
  double max[3] = {0, 0, 0};
  double mean[3] = {0, 0, 0};
  // Active voxels with a NaN or infinite channel (float and vec3s grids), left out of the above:
  // a probebake volume has none, so any is a sign of a broken bake or file.
  int64_t nonFinite = 0;
};

struct VolumeReport {
  std::string path;
  int64_t fileBytes = 0;
  std::vector<MetadataEntry> metadata;  // sorted by name
  std::vector<GridReport> grids;        // in file order
  // Active voxels of the validity grid (of the first grid when there is none): the baked probes.
  int64_t probes = 0;
  // Active voxels of the validity grid whose value is below 0.5; -1 without a validity grid.
  int64_t invalidProbes = -1;
};

// Reads `path` (every grid, one at a time) and gathers the report. NOT_FOUND when the file does
// not exist, INVALID_ARGUMENT naming the path when it is not a readable OpenVDB file.
absl::StatusOr<VolumeReport> InspectProbeVolume(const std::string& path);

// Multi-line text for a terminal: metadata, probe counts, then one line per grid.
std::string FormatVolumeReport(const VolumeReport& report);

// One JSON object: {"path", "fileBytes", "probes", "invalidProbes", "metadata": {name: value},
// "grids": [{"name", "type", "valueType", "activeVoxels", "bboxMin", "bboxMax", "min", "max",
// "mean", "nonFinite"}]} (bboxMin and bboxMax null for a grid without active voxels). Printed by
// protobuf's JSON mapping from a google.protobuf.Struct: compact, every object's keys in ascending
// order, the same report always giving the same text. Metadata values are JSON numbers for
// int/float types, booleans for bool, arrays for vectors, strings otherwise; string values that
// hold a JSON object or array (settings, stats) are embedded as JSON (re-printed the same way: keys
// sorted, numbers as doubles). Numbers are doubles: an integer of magnitude 2^53 or more (an int64
// seed) is a string of its exact decimal digits instead, as in protobuf's JSON mapping of int64;
// non-finite float metadata is a string ("nan", "inf"), non-finite statistics are null.
// Strings are UTF-8: bytes of the path or metadata that are not well-formed UTF-8 become U+FFFD.
// Statistics of 1-channel grids are still arrays (of one number).
std::string VolumeReportJson(const VolumeReport& report);

}  // namespace probebake
