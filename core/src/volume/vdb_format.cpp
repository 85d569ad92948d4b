#include "vdb_format.h"

#include "probebake/volume/visibility_map.h"

#include <cmath>
#include <cstdint>
#include <utility>

#include "probebake/base/check.h"
#include "probebake/volume/vdb_io.h"
#include "proto_json.h"

namespace probebake::volume_internal {

const char* PlacementName(Placement placement) {
  switch (placement) {
    case Placement::kAll:
      return "ALL";
    case Placement::kOutsideGeometry:
      return "OUTSIDE_GEOMETRY";
    case Placement::kNearSurfaces:
      return "NEAR_SURFACES";
  }
  return "ALL";
}

bool ParsePlacement(const std::string& name, Placement* placement) {
  for (Placement p : {Placement::kAll, Placement::kOutsideGeometry, Placement::kNearSurfaces}) {
    if (name == PlacementName(p)) {
      *placement = p;
      return true;
    }
  }
  return false;
}

absl::StatusOr<std::string> StatsToJson(const BakeStats& stats) {
  if (!std::isfinite(stats.wallSeconds)) {
    return FieldError("volume.stats.wallSeconds", "must be finite");
  }
  google::protobuf::Struct object;
  auto& fields = *object.mutable_fields();
  fields["wallSeconds"].set_number_value(stats.wallSeconds);
  for (const auto& [name, count] : {std::pair<const char*, int64_t>{"threads", stats.threads},
                                    {"probes", stats.probes},
                                    {"samples", stats.samples},
                                    {"rays", stats.rays},
                                    {"invalidProbes", stats.invalidProbes}}) {
    // JSON numbers here are doubles: beyond 2^53 a count would not read back exactly.
    if (!(std::abs(double(count)) < kMaxExactJsonInteger)) {
      return FieldError(std::string("volume.stats.") + name,
                        std::to_string(count) + " is not below 2^53 in magnitude");
    }
    fields[name].set_number_value(double(count));
  }
  return ToJson(object);
}

absl::Status StatsFromJson(const std::string& json, BakeStats* stats) {
  const std::optional<google::protobuf::Value> root = ParseJson(json);
  if (!root || root->kind_case() != google::protobuf::Value::kStructValue) {
    return FieldError("stats", "not a JSON object");
  }
  const auto& fields = root->struct_value().fields();
  BakeStats result;
  const auto wall = fields.find("wallSeconds");
  if (wall == fields.end()) return FieldError("stats.wallSeconds", "missing");
  if (wall->second.kind_case() != google::protobuf::Value::kNumberValue) {
    return FieldError("stats.wallSeconds", "not a number");
  }
  result.wallSeconds = wall->second.number_value();
  struct IntField {
    const char* name;
    int64_t* value;
  };
  int64_t threads = 0;
  for (const IntField& field :
       {IntField{"threads", &threads}, IntField{"probes", &result.probes},
        IntField{"samples", &result.samples}, IntField{"rays", &result.rays},
        IntField{"invalidProbes", &result.invalidProbes}}) {
    const std::string path = std::string("stats.") + field.name;
    const auto it = fields.find(field.name);
    if (it == fields.end()) return FieldError(path, "missing");
    const std::optional<int64_t> integer = ExactInteger(it->second);
    if (!integer) return FieldError(path, "not an integer below 2^53 in magnitude");
    *field.value = *integer;
  }
  if (threads < 0 || threads > INT32_MAX) return FieldError("stats.threads", "out of range");
  result.threads = int(threads);
  *stats = result;
  return absl::OkStatus();
}

absl::Status ValidateVolume(const ProbeVolume& volume) {
  const ProbeGrid& grid = volume.grid;
  if (volume.shOrder < 0 || volume.shOrder > kMaxVolumeShOrder) {
    return FieldError("volume.shOrder", "must be in [0, " + std::to_string(kMaxVolumeShOrder) +
                                            "], got " + std::to_string(volume.shOrder));
  }
  for (int a = 0; a < 3; ++a) {
    const std::string axis = std::to_string(a);
    if (grid.counts[a] < 1) {
      return FieldError("volume.grid.counts[" + axis + "]", "must be >= 1");
    }
    if (!(std::isfinite(grid.spacing[a]) && grid.spacing[a] > 0)) {
      return FieldError("volume.grid.spacing[" + axis + "]", "must be finite and > 0");
    }
    if (!std::isfinite(grid.origin[a])) {
      return FieldError("volume.grid.origin[" + axis + "]", "must be finite");
    }
  }
  const size_t probes = size_t(grid.ProbeCount());
  const size_t coefficients = size_t(volume.CoeffCount());
  auto sizeError = [](const std::string& field, size_t got, size_t expected) {
    return FieldError(field,
                      "size " + std::to_string(got) + ", expected " + std::to_string(expected));
  };
  if (volume.active.size() != probes) {
    return sizeError("volume.active", volume.active.size(), probes);
  }
  if (volume.radiance.size() != coefficients) {
    return sizeError("volume.radiance", volume.radiance.size(), coefficients);
  }
  for (size_t c = 0; c < coefficients; ++c) {
    if (volume.radiance[c].size() != 3 * probes) {
      return sizeError("volume.radiance[" + std::to_string(c) + "]", volume.radiance[c].size(),
                       3 * probes);
    }
  }
  if (!volume.irradiance.empty()) {
    if (volume.irradiance.size() != coefficients) {
      return sizeError("volume.irradiance", volume.irradiance.size(), coefficients);
    }
    for (size_t c = 0; c < coefficients; ++c) {
      if (volume.irradiance[c].size() != 3 * probes) {
        return sizeError("volume.irradiance[" + std::to_string(c) + "]",
                         volume.irradiance[c].size(), 3 * probes);
      }
    }
  }
  if (volume.validity.size() != probes) {
    return sizeError("volume.validity", volume.validity.size(), probes);
  }
  if (volume.stdError.size() != probes) {
    return sizeError("volume.stdError", volume.stdError.size(), probes);
  }
  if (volume.stdErrorL0.size() != probes) {
    return sizeError("volume.stdErrorL0", volume.stdErrorL0.size(), probes);
  }
  if (volume.sampleCount.size() != probes) {
    return sizeError("volume.sampleCount", volume.sampleCount.size(), probes);
  }
  if (!volume.offset.empty() && volume.offset.size() != 3 * probes) {
    return sizeError("volume.offset", volume.offset.size(), 3 * probes);
  }
  if (!volume.filled.empty() && volume.filled.size() != probes) {
    return sizeError("volume.filled", volume.filled.size(), probes);
  }
  if (volume.skyTransferOrder < 0 || volume.skyTransferOrder > kMaxVolumeShOrder) {
    return absl::InvalidArgumentError(
        "volume.skyTransferOrder: " + std::to_string(volume.skyTransferOrder) + " is outside [0, " +
        std::to_string(kMaxVolumeShOrder) + "]");
  }
  const size_t transferEntries = volume.skyTransferOrder > 0
                                     ? size_t(volume.CoeffCount()) * size_t(volume.SkyCoeffCount())
                                     : 0;
  if (volume.skyTransfer.size() != transferEntries) {
    return sizeError("volume.skyTransfer", volume.skyTransfer.size(), transferEntries);
  }
  for (size_t e = 0; e < volume.skyTransfer.size(); ++e) {
    if (volume.skyTransfer[e].size() != 3 * probes) {
      return sizeError("volume.skyTransfer[" + std::to_string(e) + "]",
                       volume.skyTransfer[e].size(), 3 * probes);
    }
  }
  if (!volume.visibility.empty()) {
    if (volume.visibility.size() != size_t(kVisibilityTexels)) {
      return sizeError("volume.visibility", volume.visibility.size(), kVisibilityTexels);
    }
    for (size_t t = 0; t < volume.visibility.size(); ++t) {
      if (volume.visibility[t].size() != 3 * probes) {
        return sizeError("volume.visibility[" + std::to_string(t) + "]",
                         volume.visibility[t].size(), 3 * probes);
      }
    }
  }
  return absl::OkStatus();
}

}  // namespace probebake::volume_internal

namespace probebake {

namespace {
std::string ShGridName(const char* prefix, int coefficient) {
  PB_CHECK(coefficient >= 0 && coefficient <= 99);
  std::string name = prefix;
  name.push_back(char('0' + coefficient / 10));
  name.push_back(char('0' + coefficient % 10));
  return name;
}
}  // namespace

std::string RadianceGridName(int coefficient) {
  return ShGridName("radiance_sh_", coefficient);
}
std::string IrradianceGridName(int coefficient) {
  return ShGridName("irradiance_sh_", coefficient);
}
std::string VisibilityGridName(int texel) {
  return ShGridName("visibility_", texel);
}
std::string SkyTransferGridName(int row, int column) {
  return ShGridName("sky_transfer_", row) + ShGridName("_", column);
}

VolumeMetadata VolumeMetadataFor(const BakeJob& job) {
  VolumeMetadata meta;
  meta.samplesPerProbe = job.settings.samplesPerProbe;
  meta.maxDepth = job.settings.maxDepth;
  meta.seed = job.settings.seed;
  meta.sceneDigest = job.sceneDigest;
  meta.settingsJson = job.settingsJson;
  for (const std::string& item : job.ignored)
    meta.ignored += (meta.ignored.empty() ? "" : "\n") + item;
  return meta;
}

}  // namespace probebake
