// ReadProbeVolume and InspectProbeVolume: the OpenVDB reading side of the probe volume file.
#include <sys/stat.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <new>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include "absl/strings/numbers.h"
#include "probebake/volume/vdb_io.h"
#include "probebake/volume/visibility_map.h"
#include "probebake/volume/volume_inspect.h"
#include "proto_json.h"
#include "vdb_file_walk.h"
#include "vdb_format.h"

namespace probebake {
namespace {

using namespace volume_internal;
namespace vdb = openvdb;

std::string NumberText(double x) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, x);
  return ec == std::errc() ? std::string(buffer, end) : std::string("?");
}

template <typename VecT>
std::string VecText(const VecT& v) {
  return "(" + NumberText(double(v[0])) + ", " + NumberText(double(v[1])) + ", " +
         NumberText(double(v[2])) + ")";
}

// A metadata value as text, exact for the types pyopenvdb knows.
std::string MetadataText(const vdb::Metadata& m) {
  const std::string type = m.typeName();
  if (type == vdb::BoolMetadata::staticTypeName()) {
    return static_cast<const vdb::BoolMetadata&>(m).value() ? "true" : "false";
  }
  if (type == vdb::Int32Metadata::staticTypeName()) {
    return std::to_string(static_cast<const vdb::Int32Metadata&>(m).value());
  }
  if (type == vdb::Int64Metadata::staticTypeName()) {
    return std::to_string(static_cast<const vdb::Int64Metadata&>(m).value());
  }
  if (type == vdb::FloatMetadata::staticTypeName()) {
    return NumberText(static_cast<const vdb::FloatMetadata&>(m).value());
  }
  if (type == vdb::DoubleMetadata::staticTypeName()) {
    return NumberText(static_cast<const vdb::DoubleMetadata&>(m).value());
  }
  if (type == vdb::StringMetadata::staticTypeName()) {
    return static_cast<const vdb::StringMetadata&>(m).value();
  }
  if (type == vdb::Vec3IMetadata::staticTypeName()) {
    return VecText(static_cast<const vdb::Vec3IMetadata&>(m).value());
  }
  if (type == vdb::Vec3SMetadata::staticTypeName()) {
    return VecText(static_cast<const vdb::Vec3SMetadata&>(m).value());
  }
  if (type == vdb::Vec3DMetadata::staticTypeName()) {
    return VecText(static_cast<const vdb::Vec3DMetadata&>(m).value());
  }
  return m.str();
}

bool FileExists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

// An open OpenVDB file; errors name the path.
absl::StatusOr<std::unique_ptr<vdb::io::File>> OpenFile(const std::string& path) {
  if (!FileExists(path)) return absl::NotFoundError(path + ": no such file");
  if (const std::string problem = VdbFileProblem(path); !problem.empty())
    return absl::InvalidArgumentError(path + ": not a readable OpenVDB file: " + problem);
  InitializeOpenVdbOnce();
  auto file = std::make_unique<vdb::io::File>(path);
  try {
    file->open(/*delayLoad=*/false);
  } catch (const vdb::Exception& e) {
    return absl::InvalidArgumentError(path + ": not a readable OpenVDB file: " + e.what());
  }
  return file;
}

// Typed access to file metadata; errors "<path>: <key>: <reason>".
class MetaReader {
 public:
  MetaReader(const std::string& path, const vdb::MetaMap& meta) : path_(path), meta_(meta) {}

  bool Has(const std::string& key) const { return bool(meta_[key]); }

  template <typename T>
  absl::Status Get(const std::string& key, T* value) const {
    const vdb::Metadata::ConstPtr m = meta_[key];
    if (!m) return Error(key, "missing");
    const auto* typed = dynamic_cast<const vdb::TypedMetadata<T>*>(m.get());
    if (typed == nullptr) {
      return Error(
          key, "type " + m->typeName() + ", expected " + vdb::TypedMetadata<T>::staticTypeName());
    }
    *value = typed->value();
    return absl::OkStatus();
  }

  // Get() for a string key that must hold `expected`.
  absl::Status Expect(const std::string& key, const std::string& expected) const {
    std::string value;
    PB_RETURN_IF_ERROR(Get(key, &value));
    if (value != expected) return Error(key, "\"" + value + "\", expected \"" + expected + "\"");
    return absl::OkStatus();
  }

  absl::Status Error(const std::string& key, const std::string& reason) const {
    return absl::InvalidArgumentError(path_ + ": " + key + ": " + reason);
  }

 private:
  const std::string& path_;
  const vdb::MetaMap& meta_;
};

absl::Status GridError(const std::string& path, const std::string& grid,
                       const std::string& reason) {
  return absl::InvalidArgumentError(path + ": grid " + grid + ": " + reason);
}

// Calls fn(coord, value) for every active voxel, expanding active tiles.
template <typename GridT, typename Fn>
void ForEachActiveVoxel(const GridT& grid, Fn fn) {
  for (auto it = grid.cbeginValueOn(); it; ++it) {
    if (it.isVoxelValue()) {
      fn(it.getCoord(), *it);
    } else {
      const vdb::CoordBBox box = it.getBoundingBox();
      for (auto c = box.begin(); c; ++c) fn(*c, *it);
    }
  }
}

struct Layout {
  ProbeGrid grid;
  vdb::Mat4d matrix;  // the shared transform's affine matrix (row vectors: world = index * M)
};

// Origin and spacing from a transform that must be an axis-aligned positive scale + translation.
absl::Status GridFromTransform(const std::string& path, const std::string& gridName,
                               const vdb::math::Transform& transform, Layout* layout) {
  if (!transform.isLinear()) return GridError(path, gridName, "transform is not linear");
  const vdb::Mat4d m = transform.baseMap()->getAffineMap()->getMat4();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (r != c && m(r, c) != 0) {
        return GridError(path, gridName,
                         "transform rotates or shears (not an axis-aligned scale + translation)");
      }
    }
    if (!(m(r, r) > 0) || !std::isfinite(m(r, r))) {
      return GridError(path, gridName, "transform's scale is not positive on every axis");
    }
  }
  layout->matrix = m;
  layout->grid.spacing = {m(0, 0), m(1, 1), m(2, 2)};
  layout->grid.origin = {m(3, 0), m(3, 1), m(3, 2)};
  return absl::OkStatus();
}

// How far the voxel size of a grid written by WriteProbeVolume may be from the spacing it was
// given, on an axis with spacing s > 0 and origin t. Every openvdb::math::Transform built from a
// linear map is "simplified" by its constructor (math::simplify): the translation is taken as
// applyMap(0, 0, 0) = t, exactly, but the scale as applyMap(1, 1, 1) - applyMap(0, 0, 0) =
// fl(fl(s + t) - t). Two roundings (unit roundoff u = 2^-53) give |fl(fl(s + t) - t) - s| <=
// u |s + t| (1 + u) + u |s| <= gamma2 (|s| + |t|), gamma2 = 2u / (1 - 2u). When the three
// re-derived scales then agree to within math::Tolerance<double> (1e-15, absolute), the map
// becomes a uniform one holding the x scale on every axis, moving the y and z scales by up to
// that much more. Hence gamma2 (|s| + |t|) + 1e-15; a spacing of 2/3 at origin 1e5 moves by
// ~5e-12, which this bound (~2.2e-11) covers.
double TransformScaleTolerance(double spacing, double origin) {
  constexpr double u = std::numeric_limits<double>::epsilon() / 2;
  constexpr double gamma2 = 2 * u / (1 - 2 * u);
  return gamma2 * (std::abs(spacing) + std::abs(origin)) + vdb::math::Tolerance<double>::value();
}

struct ExpectedGrid {
  std::string name;
  bool vec3;  // Vec3SGrid, else FloatGrid
};

absl::StatusOr<ProbeVolumeFile> ReadImpl(const std::string& path) {
  PB_ASSIGN_OR_RETURN(std::unique_ptr<vdb::io::File> file, OpenFile(path));
  ProbeVolumeFile result;
  ProbeVolume& volume = result.volume;

  const vdb::MetaMap::Ptr fileMeta = file->getMetadata();
  for (auto it = fileMeta->beginMeta(); it != fileMeta->endMeta(); ++it) {
    result.rawMetadata[it->first] = MetadataText(*it->second);
  }
  const MetaReader meta(path, *fileMeta);

  int32_t format = 0;
  PB_RETURN_IF_ERROR(meta.Get(kKeyFormat, &format));
  if (format < kProbeVolumeFormat1 || format > kProbeVolumeFormat) {
    return meta.Error(kKeyFormat, std::to_string(format) + ", this reader knows " +
                                      std::to_string(kProbeVolumeFormat1) + " to " +
                                      std::to_string(kProbeVolumeFormat));
  }
  result.format = format;
  PB_RETURN_IF_ERROR(meta.Expect(kKeyShBasis, kShBasis));
  PB_RETURN_IF_ERROR(meta.Expect(kKeyQuantity, kQuantity));
  PB_RETURN_IF_ERROR(meta.Expect(kKeyColorSpace, kColorSpace));
  int32_t order = 0;
  PB_RETURN_IF_ERROR(meta.Get(kKeyShOrder, &order));
  if (order < 0 || order > kMaxVolumeShOrder) {
    return meta.Error(kKeyShOrder, std::to_string(order) + " is outside [0, " +
                                       std::to_string(kMaxVolumeShOrder) + "]");
  }
  volume.shOrder = order;
  bool hasIrradiance = false;
  PB_RETURN_IF_ERROR(meta.Get(kKeyHasIrradiance, &hasIrradiance));
  PB_RETURN_IF_ERROR(meta.Get(kKeyShWindow, &volume.window));
  std::string stats;
  PB_RETURN_IF_ERROR(meta.Get(kKeyStats, &stats));
  if (absl::Status s = StatsFromJson(stats, &volume.stats); !s.ok()) {
    return absl::InvalidArgumentError(path + ": " + std::string(s.message()));
  }
  VolumeMetadata& vm = result.meta;
  PB_RETURN_IF_ERROR(meta.Get(kKeySamplesPerProbe, &vm.samplesPerProbe));
  int32_t maxDepth = 0;
  PB_RETURN_IF_ERROR(meta.Get(kKeyMaxDepth, &maxDepth));
  vm.maxDepth = maxDepth;
  int64_t seed = 0;
  PB_RETURN_IF_ERROR(meta.Get(kKeySeed, &seed));
  vm.seed = static_cast<uint64_t>(seed);
  PB_RETURN_IF_ERROR(meta.Get(kKeySceneDigest, &vm.sceneDigest));
  PB_RETURN_IF_ERROR(meta.Get(kKeySettings, &vm.settingsJson));
  if (meta.Has(kKeyIgnored)) PB_RETURN_IF_ERROR(meta.Get(kKeyIgnored, &vm.ignored));

  // The grids the format has, and no others.
  std::vector<ExpectedGrid> expected;
  const int coefficients = volume.CoeffCount();
  for (int c = 0; c < coefficients; ++c) expected.push_back({RadianceGridName(c), true});
  if (hasIrradiance) {
    for (int c = 0; c < coefficients; ++c) expected.push_back({IrradianceGridName(c), true});
  }
  expected.push_back({kValidityGridName, false});
  expected.push_back({kStdErrorGridName, false});
  if (format != kProbeVolumeFormat1) expected.push_back({kStdErrorL0GridName, false});
  expected.push_back({kSampleCountGridName, false});
  // Format 3's and 4's optional grids, announced by their metadata.
  bool hasOffset = false, hasFilled = false;
  int32_t visibilitySize = 0;
  if (format >= kProbeVolumeFormat3) {
    PB_RETURN_IF_ERROR(meta.Get(kKeyHasOffset, &hasOffset));
    PB_RETURN_IF_ERROR(meta.Get(kKeyHasFilled, &hasFilled));
    PB_RETURN_IF_ERROR(meta.Get(kKeyVisibilitySize, &visibilitySize));
    if (visibilitySize != 0 && visibilitySize != kVisibilityMapSize) {
      return meta.Error(kKeyVisibilitySize, std::to_string(visibilitySize) +
                                                ", this reader knows 0 (none) and " +
                                                std::to_string(kVisibilityMapSize));
    }
  }
  if (hasOffset) expected.push_back({kOffsetGridName, true});
  if (hasFilled) expected.push_back({kFilledGridName, false});
  const int visibilityTexels = visibilitySize * visibilitySize;
  for (int t = 0; t < visibilityTexels; ++t) expected.push_back({VisibilityGridName(t), true});
  // Format 4's optional sky transfer, announced by its order.
  if (format >= kProbeVolumeFormat4 && meta.Has(kKeySkyTransferOrder)) {
    int32_t skyOrder = 0;
    PB_RETURN_IF_ERROR(meta.Get(kKeySkyTransferOrder, &skyOrder));
    if (skyOrder < 1 || skyOrder > kMaxVolumeShOrder) {
      return meta.Error(kKeySkyTransferOrder, std::to_string(skyOrder) + " is outside [1, " +
                                                  std::to_string(kMaxVolumeShOrder) + "]");
    }
    PB_RETURN_IF_ERROR(meta.Expect(kKeySkyTransferPrecision, kSkyTransferPrecision));
    volume.skyTransferOrder = skyOrder;
  }
  const int skyCoefficients = volume.skyTransferOrder > 0 ? volume.SkyCoeffCount() : 0;
  for (int r = 0; r < (skyCoefficients > 0 ? coefficients : 0); ++r)
    for (int s = 0; s < skyCoefficients; ++s) expected.push_back({SkyTransferGridName(r, s), true});
  std::map<std::string, vdb::GridBase::Ptr> headers;  // metadata and transform only
  const vdb::GridPtrVecPtr allHeaders = file->readAllGridMetadata();
  for (const vdb::GridBase::Ptr& header : *allHeaders) {
    const std::string name = header->getName();
    if (!headers.emplace(name, header).second) {
      return GridError(path, name, "appears more than once");
    }
  }
  for (const ExpectedGrid& e : expected) {
    auto it = headers.find(e.name);
    if (it == headers.end()) {
      return GridError(path, e.name, "missing");
    }
    const std::string wantType = e.vec3 ? vdb::Vec3SGrid::gridType() : vdb::FloatGrid::gridType();
    if (it->second->type() != wantType) {
      return GridError(path, e.name,
                       "type " + it->second->type() + ", expected " + wantType +
                           (e.vec3 ? " (Vec3SGrid)" : " (FloatGrid)"));
    }
  }
  if (headers.size() != expected.size()) {
    for (const auto& entry : headers) {
      const std::string& name = entry.first;  // (clang 14 cannot capture a structured binding)
      const bool known = std::any_of(expected.begin(), expected.end(),
                                     [&name](const ExpectedGrid& e) { return e.name == name; });
      if (!known) {
        return GridError(path, name,
                         name.rfind("irradiance_sh_", 0) == 0 && !hasIrradiance
                             ? "present although has_irradiance is false"
                             : "not part of probe volume format " + std::to_string(format));
      }
    }
  }

  // One shared transform, an axis-aligned scale + translation.
  Layout layout;
  PB_RETURN_IF_ERROR(GridFromTransform(path, kValidityGridName,
                                       headers[kValidityGridName]->constTransform(), &layout));
  for (const ExpectedGrid& e : expected) {
    const vdb::Mat4d m = headers[e.name]->constTransform().baseMap()->getAffineMap()->getMat4();
    if (!headers[e.name]->constTransform().isLinear() || m != layout.matrix) {
      return GridError(path, e.name,
                       std::string("transform differs from grid ") + kValidityGridName + "'s");
    }
  }
  ProbeGrid& grid = layout.grid;
  // grid_min and grid_spacing, when present, are authoritative: they hold the doubles the writer
  // was given, whereas the transform holds OpenVDB's re-derivation of them (see
  // TransformScaleTolerance). The transform must agree with them.
  if (meta.Has(kKeyGridMin)) {
    vdb::Vec3d min;
    PB_RETURN_IF_ERROR(meta.Get(kKeyGridMin, &min));
    for (int a = 0; a < 3; ++a) {
      if (!std::isfinite(min[a])) return meta.Error(kKeyGridMin, VecText(min) + " is not finite");
      // The translation is stored exactly (only the sign of a zero may be lost).
      if (min[a] != grid.origin[a]) {
        return meta.Error(kKeyGridMin, VecText(min) + " disagrees with the grids' translation " +
                                           VecText(grid.origin));
      }
    }
    grid.origin = {min[0], min[1], min[2]};
  }
  if (meta.Has(kKeyGridSpacing)) {
    vdb::Vec3d spacing;
    PB_RETURN_IF_ERROR(meta.Get(kKeyGridSpacing, &spacing));
    for (int a = 0; a < 3; ++a) {
      if (!(std::isfinite(spacing[a]) && spacing[a] > 0)) {
        return meta.Error(kKeyGridSpacing, VecText(spacing) + " must be finite and > 0");
      }
      const double tolerance = TransformScaleTolerance(spacing[a], grid.origin[a]);
      if (!(std::abs(grid.spacing[a] - spacing[a]) <= tolerance)) {
        return meta.Error(kKeyGridSpacing,
                          VecText(spacing) + " disagrees with the grids' voxel size " +
                              VecText(grid.spacing) + " on axis " + std::to_string(a) +
                              " by more than OpenVDB's rounding (" + NumberText(tolerance) + ")");
      }
    }
    grid.spacing = {spacing[0], spacing[1], spacing[2]};
  }
  if (meta.Has(kKeyGridPlacement)) {
    std::string placement;
    PB_RETURN_IF_ERROR(meta.Get(kKeyGridPlacement, &placement));
    if (!ParsePlacement(placement, &grid.placement)) {
      return meta.Error(kKeyGridPlacement, "unknown placement \"" + placement + "\"");
    }
  } else {
    grid.placement = Placement::kAll;
  }
  if (meta.Has(kKeyGridSurfaceDistance)) {
    PB_RETURN_IF_ERROR(meta.Get(kKeyGridSurfaceDistance, &grid.surfaceDistance));
  }

  // Validity first: its active voxels are the probes; every other grid must match them.
  const vdb::FloatGrid::Ptr validity =
      vdb::gridPtrCast<vdb::FloatGrid>(file->readGrid(kValidityGridName));
  if (meta.Has(kKeyGridCounts)) {
    vdb::Vec3i counts;
    PB_RETURN_IF_ERROR(meta.Get(kKeyGridCounts, &counts));
    for (int a = 0; a < 3; ++a) {
      if (counts[a] < 1) return meta.Error(kKeyGridCounts, VecText(counts) + " must be >= 1");
      grid.counts[a] = counts[a];
    }
  } else {
    // Without the key the grid ends at the last active voxel.
    const vdb::CoordBBox box = validity->evalActiveVoxelBoundingBox();
    if (box.empty()) {
      return meta.Error(kKeyGridCounts, "missing, and no active voxel to infer the counts from");
    }
    for (int a = 0; a < 3; ++a) grid.counts[a] = box.max()[a] + 1;
  }
  if (grid.ProbeCount() > (int64_t(1) << 34)) {
    return meta.Error(kKeyGridCounts,
                      "too many probes (" + std::to_string(grid.ProbeCount()) + ")");
  }
  volume.grid = grid;
  const size_t probes = size_t(grid.ProbeCount());

  // The linear index of an active voxel, or -1 outside the grid.
  auto indexOf = [&grid](const vdb::Coord& c) -> int64_t {
    for (int a = 0; a < 3; ++a) {
      if (c[a] < 0 || c[a] >= grid.counts[a]) return -1;
    }
    return grid.LinearIndex(c[0], c[1], c[2]);
  };
  auto outside = [&](const std::string& name, const vdb::Coord& c) {
    return GridError(path, name,
                     "active voxel (" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " +
                         std::to_string(c[2]) + ") outside the grid's " +
                         std::to_string(grid.counts[0]) + "x" + std::to_string(grid.counts[1]) +
                         "x" + std::to_string(grid.counts[2]) + " probes");
  };

  volume.active.assign(probes, 0);
  volume.validity.assign(probes, 0.0f);
  int64_t activeCount = 0;
  {
    vdb::Coord bad;
    bool ok = true;
    ForEachActiveVoxel(*validity, [&](const vdb::Coord& c, float v) {
      const int64_t i = indexOf(c);
      if (i < 0) {
        if (ok) bad = c;
        ok = false;
        return;
      }
      volume.active[size_t(i)] = 1;
      volume.validity[size_t(i)] = v;
      ++activeCount;
    });
    if (!ok) return outside(kValidityGridName, bad);
  }

  // Reads `name` into `values` (`channels` floats per probe), checking its active voxels.
  auto readInto = [&](const std::string& name, auto* typedGrid, int channels,
                      std::vector<float>* values) -> absl::Status {
    using GridT = std::remove_pointer_t<decltype(typedGrid)>;
    const typename GridT::Ptr g = vdb::gridPtrCast<GridT>(file->readGrid(name));
    if (!g) return GridError(path, name, "cannot be read as " + GridT::gridType());
    values->assign(size_t(channels) * probes, 0.0f);
    int64_t count = 0;
    bool ok = true;
    vdb::Coord bad;
    ForEachActiveVoxel(*g, [&](const vdb::Coord& c, const typename GridT::ValueType& v) {
      const int64_t i = indexOf(c);
      if (i < 0 || !volume.active[size_t(i)]) {
        if (ok) bad = c;
        ok = false;
        return;
      }
      ++count;
      if constexpr (std::is_same_v<GridT, vdb::Vec3SGrid>) {
        for (int ch = 0; ch < 3; ++ch) (*values)[3 * size_t(i) + size_t(ch)] = v[ch];
      } else {
        (*values)[size_t(i)] = v;
      }
    });
    if (!ok) {
      if (indexOf(bad) < 0) return outside(name, bad);
      return GridError(path, name,
                       "active voxel (" + std::to_string(bad[0]) + ", " + std::to_string(bad[1]) +
                           ", " + std::to_string(bad[2]) + ") is not active in grid " +
                           kValidityGridName);
    }
    if (count != activeCount) {
      return GridError(path, name,
                       std::to_string(count) + " active voxels, grid " + kValidityGridName +
                           " has " + std::to_string(activeCount));
    }
    return absl::OkStatus();
  };

  vdb::Vec3SGrid* vecTag = nullptr;
  vdb::FloatGrid* floatTag = nullptr;
  volume.radiance.resize(size_t(coefficients));
  for (int c = 0; c < coefficients; ++c) {
    PB_RETURN_IF_ERROR(readInto(RadianceGridName(c), vecTag, 3, &volume.radiance[size_t(c)]));
  }
  if (hasIrradiance) {
    volume.irradiance.resize(size_t(coefficients));
    for (int c = 0; c < coefficients; ++c) {
      PB_RETURN_IF_ERROR(readInto(IrradianceGridName(c), vecTag, 3, &volume.irradiance[size_t(c)]));
    }
  }
  if (format == kProbeVolumeFormat1) {
    // Format 1's std_error is the L0 figure; the irradiance figure was not recorded: unknown.
    PB_RETURN_IF_ERROR(readInto(kStdErrorGridName, floatTag, 1, &volume.stdErrorL0));
    volume.stdError.assign(probes, 0.0f);
    for (size_t i = 0; i < probes; ++i)
      if (volume.active[i]) volume.stdError[i] = std::numeric_limits<float>::infinity();
  } else {
    PB_RETURN_IF_ERROR(readInto(kStdErrorGridName, floatTag, 1, &volume.stdError));
    PB_RETURN_IF_ERROR(readInto(kStdErrorL0GridName, floatTag, 1, &volume.stdErrorL0));
  }
  PB_RETURN_IF_ERROR(readInto(kSampleCountGridName, floatTag, 1, &volume.sampleCount));
  if (hasOffset) PB_RETURN_IF_ERROR(readInto(kOffsetGridName, vecTag, 3, &volume.offset));
  if (hasFilled) PB_RETURN_IF_ERROR(readInto(kFilledGridName, floatTag, 1, &volume.filled));
  volume.visibility.resize(size_t(visibilityTexels));
  for (int t = 0; t < visibilityTexels; ++t) {
    PB_RETURN_IF_ERROR(readInto(VisibilityGridName(t), vecTag, 3, &volume.visibility[size_t(t)]));
  }
  volume.skyTransfer.resize(size_t(coefficients) * size_t(skyCoefficients));
  for (size_t e = 0; e < volume.skyTransfer.size(); ++e) {
    PB_RETURN_IF_ERROR(
        readInto(SkyTransferGridName(int(e) / skyCoefficients, int(e) % skyCoefficients), vecTag, 3,
                 &volume.skyTransfer[e]));
  }
  // Format 3's moments are of distances, which no sampler here reads: a volume without them.
  if (format == kProbeVolumeFormat3) volume.visibility.clear();
  return result;
}

// Statistics over the active voxels of one grid.
template <typename GridT>
void GatherStats(const GridT& grid, int channels, GridReport* report) {
  report->channels = channels;
  double sum[3] = {0, 0, 0};
  for (int ch = 0; ch < channels; ++ch) {
    report->min[ch] = std::numeric_limits<double>::infinity();
    report->max[ch] = -std::numeric_limits<double>::infinity();
  }
  int64_t count = 0;
  for (auto it = grid.cbeginValueOn(); it; ++it) {
    const int64_t n = int64_t(it.getVoxelCount());
    double values[3];
    bool finite = true;
    for (int ch = 0; ch < channels; ++ch) {
      if constexpr (std::is_same_v<GridT, vdb::Vec3SGrid>) {
        values[ch] = double((*it)[ch]);
      } else {
        values[ch] = double(*it);
      }
      finite = finite && std::isfinite(values[ch]);
    }
    if (!finite) {
      report->nonFinite += n;
      continue;
    }
    for (int ch = 0; ch < channels; ++ch) {
      const double v = values[ch];
      report->min[ch] = std::min(report->min[ch], v);
      report->max[ch] = std::max(report->max[ch], v);
      sum[ch] += v * double(n);
    }
    count += n;
  }
  for (int ch = 0; ch < channels; ++ch) {
    if (count == 0) {
      report->min[ch] = report->max[ch] = report->mean[ch] = 0;
    } else {
      report->mean[ch] = sum[ch] / double(count);
    }
  }
}

absl::StatusOr<VolumeReport> InspectImpl(const std::string& path) {
  PB_ASSIGN_OR_RETURN(std::unique_ptr<vdb::io::File> file, OpenFile(path));
  VolumeReport report;
  report.path = path;
  report.fileBytes = int64_t(file->getSize());
  const vdb::MetaMap::Ptr fileMeta = file->getMetadata();
  for (auto it = fileMeta->beginMeta(); it != fileMeta->endMeta(); ++it) {
    report.metadata.push_back({it->first, it->second->typeName(), MetadataText(*it->second)});
  }
  std::vector<std::string> names;
  for (auto it = file->beginName(); it != file->endName(); ++it) names.push_back(it.gridName());
  std::sort(names.begin(), names.end());
  bool haveValidity = false;
  for (const std::string& name : names) {
    const vdb::GridBase::Ptr base = file->readGrid(name);
    GridReport g;
    g.name = name;
    g.type = base->type();
    g.valueType = base->valueType();
    g.activeVoxels = int64_t(base->activeVoxelCount());
    if (g.activeVoxels > 0) {
      const vdb::CoordBBox box = base->evalActiveVoxelBoundingBox();
      for (int a = 0; a < 3; ++a) {
        g.bboxMin[a] = box.min()[a];
        g.bboxMax[a] = box.max()[a];
      }
    }
    if (const auto f = vdb::gridPtrCast<vdb::FloatGrid>(base)) {
      GatherStats(*f, 1, &g);
      if (name == kValidityGridName) {
        haveValidity = true;
        report.probes = g.activeVoxels;
        report.invalidProbes = 0;
        for (auto it = f->cbeginValueOn(); it; ++it) {
          if (*it < 0.5f) report.invalidProbes += int64_t(it.getVoxelCount());
        }
      }
    } else if (const auto v = vdb::gridPtrCast<vdb::Vec3SGrid>(base)) {
      GatherStats(*v, 3, &g);
    }
    report.grids.push_back(std::move(g));
  }
  if (!haveValidity && !report.grids.empty()) report.probes = report.grids.front().activeVoxels;
  std::sort(report.metadata.begin(), report.metadata.end(),
            [](const MetadataEntry& a, const MetadataEntry& b) { return a.name < b.name; });
  return report;
}

// Runs `fn`, turning exceptions from OpenVDB and allocation into a status naming `path`.
template <typename Fn>
auto Guarded(const std::string& path, Fn fn) -> decltype(fn()) {
  try {
    return fn();
  } catch (const std::bad_alloc&) {
    return absl::ResourceExhaustedError(path + ": out of memory while reading");
  } catch (const vdb::Exception& e) {
    return absl::InvalidArgumentError(path + ": OpenVDB: " + e.what());
  } catch (const std::exception& e) {
    return absl::InternalError(path + ": " + e.what());
  }
}

std::string Fixed(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", x);
  return buffer;
}

}  // namespace

absl::StatusOr<ProbeVolumeFile> ReadProbeVolume(const std::string& path) {
  return Guarded(path, [&] { return ReadImpl(path); });
}

absl::StatusOr<VolumeReport> InspectProbeVolume(const std::string& path) {
  return Guarded(path, [&] { return InspectImpl(path); });
}

std::string FormatVolumeReport(const VolumeReport& report) {
  std::string out = "file: " + report.path + " (" + std::to_string(report.fileBytes) + " bytes)\n";
  out += "probes: " + std::to_string(report.probes);
  if (report.invalidProbes >= 0) out += " (invalid: " + std::to_string(report.invalidProbes) + ")";
  out += "\nmetadata:\n";
  for (const MetadataEntry& m : report.metadata) {
    out += "  " + m.name + " (" + m.type + "): " + m.value;
    // The seed is a uint64 stored in int64 bits (OpenVDB has no unsigned metadata).
    int64_t bits = 0;
    if (m.name == kKeySeed && m.type == "int64" && absl::SimpleAtoi(m.value, &bits) && bits < 0) {
      out += " (seed " + std::to_string(static_cast<uint64_t>(bits)) + ")";
    }
    out += "\n";
  }
  out += "grids (" + std::to_string(report.grids.size()) + "):\n";
  for (const GridReport& g : report.grids) {
    char line[256];
    std::snprintf(line, sizeof line, "  %-18s %-6s active %-9lld ", g.name.c_str(),
                  g.valueType.c_str(), static_cast<long long>(g.activeVoxels));
    out += line;
    if (g.activeVoxels > 0) {
      std::snprintf(line, sizeof line, "bbox [%d,%d,%d]..[%d,%d,%d]", g.bboxMin[0], g.bboxMin[1],
                    g.bboxMin[2], g.bboxMax[0], g.bboxMax[1], g.bboxMax[2]);
      out += line;
    } else {
      out += "bbox empty";
    }
    auto channels = [&g](const double* v) {
      if (g.channels == 1) return Fixed(v[0]);
      std::string s = "(";
      for (int ch = 0; ch < g.channels; ++ch) {
        if (ch) s += ", ";
        s += Fixed(v[ch]);
      }
      return s + ")";
    };
    if (g.channels > 0) {
      out += "  min " + channels(g.min) + "  max " + channels(g.max) + "  mean " + channels(g.mean);
    }
    if (g.nonFinite > 0) {
      out += "  NON-FINITE " + std::to_string(g.nonFinite) + " (left out of min, max, mean)";
    }
    out += "\n";
  }
  return out;
}

std::string VolumeReportJson(const VolumeReport& report) {
  namespace pb = google::protobuf;
  auto list = [](auto&& values) {
    pb::Value value;
    pb::ListValue* items = value.mutable_list_value();
    for (pb::Value& v : values) *items->add_values() = std::move(v);
    return value;
  };
  // "(x, y, z)" as three finite numbers, or nullopt.
  auto vectorValue = [&list](const std::string& text) -> std::optional<pb::Value> {
    if (text.size() < 2 || text.front() != '(' || text.back() != ')') return std::nullopt;
    std::vector<pb::Value> components;
    const char* p = text.data() + 1;
    const char* end = text.data() + text.size() - 1;
    while (true) {
      double x = 0;
      const auto [next, ec] = std::from_chars(p, end, x);
      if (ec != std::errc() || !std::isfinite(x)) return std::nullopt;
      components.push_back(NumberValue(x));
      if (next == end) break;
      if (end - next < 2 || next[0] != ',' || next[1] != ' ') return std::nullopt;
      p = next + 2;
    }
    return list(std::move(components));
  };
  auto metadataValue = [&vectorValue](const MetadataEntry& m) -> pb::Value {
    if (m.type == "bool" && (m.value == "true" || m.value == "false")) {
      pb::Value value;
      value.set_bool_value(m.value == "true");
      return value;
    }
    if (m.type == "int32" || m.type == "int64") {
      int64_t n = 0;
      const auto [end, ec] = std::from_chars(m.value.data(), m.value.data() + m.value.size(), n);
      if (ec == std::errc() && end == m.value.data() + m.value.size()) return IntegerValue(n);
    }
    if (m.type == "float" || m.type == "double") {
      double x = 0;
      const auto [end, ec] = std::from_chars(m.value.data(), m.value.data() + m.value.size(), x);
      // Non-finite values are not JSON numbers: they stay text.
      if (ec == std::errc() && end == m.value.data() + m.value.size() && std::isfinite(x)) {
        return NumberValue(x);
      }
    }
    if (m.type == "vec3i" || m.type == "vec3s" || m.type == "vec3d") {
      if (std::optional<pb::Value> v = vectorValue(m.value)) return *std::move(v);
    }
    if (m.type == "string") {
      std::optional<pb::Value> v = ParseJson(ValidUtf8(m.value));
      if (v && (v->has_struct_value() || v->has_list_value())) return *std::move(v);
    }
    return StringValue(m.value);
  };
  auto numbers = [&list](const double* v, int n) {
    std::vector<pb::Value> values;
    for (int i = 0; i < n; ++i) values.push_back(NumberValue(v[i]));
    return list(std::move(values));
  };
  auto box = [&list](bool present, const int* v) {
    pb::Value value;
    if (!present) {
      value.set_null_value(pb::NULL_VALUE);
      return value;
    }
    std::vector<pb::Value> values;
    for (int a = 0; a < 3; ++a) values.push_back(IntegerValue(v[a]));
    return list(std::move(values));
  };

  pb::Struct root;
  auto& fields = *root.mutable_fields();
  fields["path"] = StringValue(report.path);
  fields["fileBytes"] = IntegerValue(report.fileBytes);
  fields["probes"] = IntegerValue(report.probes);
  fields["invalidProbes"] = IntegerValue(report.invalidProbes);
  auto& metadata = *fields["metadata"].mutable_struct_value()->mutable_fields();
  for (const MetadataEntry& m : report.metadata) metadata[m.name] = metadataValue(m);
  pb::ListValue* grids = fields["grids"].mutable_list_value();
  for (const GridReport& g : report.grids) {
    auto& grid = *grids->add_values()->mutable_struct_value()->mutable_fields();
    grid["name"] = StringValue(g.name);
    grid["type"] = StringValue(g.type);
    grid["valueType"] = StringValue(g.valueType);
    grid["activeVoxels"] = IntegerValue(g.activeVoxels);
    grid["bboxMin"] = box(g.activeVoxels > 0, g.bboxMin);
    grid["bboxMax"] = box(g.activeVoxels > 0, g.bboxMax);
    grid["min"] = numbers(g.min, g.channels);
    grid["max"] = numbers(g.max, g.channels);
    grid["mean"] = numbers(g.mean, g.channels);
    grid["nonFinite"] = IntegerValue(g.nonFinite);
  }
  return ToJson(root);
}

}  // namespace probebake
