// WriteProbeVolume: builds the grids of docs/volume-format.md one at a time and streams each into
// the file as soon as it is built, through OpenVDB's own archive writer (openvdb::io::Archive), so
// the file is exactly what openvdb::io::File::write would produce but never holds every grid in
// memory.
#include <cerrno>
#include <fstream>
#include <memory>
#include <mutex>
#include <new>
#include <string>

#include <openvdb/io/Archive.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <openvdb/openvdb.h>

#include "probebake/base/atomic_file.h"
#include "probebake/base/io_error.h"
#include "probebake/base/log.h"
#include "probebake/base/version.h"
#include "probebake/volume/vdb_io.h"
#include "probebake/volume/visibility_map.h"
#include "vdb_format.h"

namespace probebake {
namespace volume_internal {

void InitializeOpenVdbOnce() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

}  // namespace volume_internal

namespace {

using namespace volume_internal;
namespace vdb = openvdb;

// openvdb::io::Archive::write(std::ostream&, grids, ...) unrolled so that grids can be handed
// over one by one: the same header, file metadata, grid count and per-grid records (descriptor,
// compression flags, metadata, transform, topology, buffers) in the same order, with the
// archive's default compression (blosc + active mask when OpenVDB has blosc, else zip).
class StreamingArchive : public vdb::io::Archive {
 public:
  // Writes everything before the first grid. `os` must be seekable (a file).
  void Begin(std::ostream& os, const vdb::MetaMap& fileMetadata, int32_t gridCount) {
    streamMetadata_ = vdb::io::getStreamMetadataPtr(os);
    if (!streamMetadata_) {
      streamMetadata_ = std::make_shared<vdb::io::StreamMetadata>();
      vdb::io::setStreamMetadataPtr(os, streamMetadata_, /*transfer=*/false);
    }
    vdb::io::setDataCompression(os, compression());
    vdb::io::setWriteGridStatsMetadata(os, isGridStatsMetadataEnabled());
    writeHeader(os, /*seekable=*/true);
    fileMetadata.writeMeta(os);
    os.write(reinterpret_cast<const char*>(&gridCount), sizeof(int32_t));
  }

  // Writes one grid; its name must be unique in the file.
  void WriteGrid(std::ostream& os, const vdb::GridBase::ConstPtr& grid) {
    vdb::io::GridDescriptor descriptor(grid->getName(), grid->type(), grid->saveFloatAsHalf());
    writeGrid(descriptor, grid, os, /*seekable=*/true);
    // Some compression flags are per grid; restore the file's before the next grid.
    vdb::io::setDataCompression(os, compression());
  }

 private:
  // The stream refers to this (setStreamMetadataPtr without transfer); it must outlive writing.
  vdb::io::StreamMetadata::Ptr streamMetadata_;
};

vdb::math::Transform::Ptr ProbeTransform(const ProbeGrid& grid) {
  const vdb::Vec3d scale(grid.spacing.x, grid.spacing.y, grid.spacing.z);
  const vdb::Vec3d translation(grid.origin.x, grid.origin.y, grid.origin.z);
  return std::make_shared<vdb::math::Transform>(
      std::make_shared<vdb::math::ScaleTranslateMap>(scale, translation));
}

// A grid whose active voxels are the active probes, with value(probe) at each. Leaves are filled
// directly (no accessor walk per voxel); inactive voxels keep the background 0.
template <typename GridT, typename ValueFn>
typename GridT::Ptr BuildGrid(const ProbeVolume& volume, const std::string& name,
                              const vdb::math::Transform::Ptr& transform, ValueFn value) {
  using ValueT = typename GridT::ValueType;
  using LeafT = typename GridT::TreeType::LeafNodeType;
  constexpr int kDim = int(LeafT::DIM);
  const ValueT background = vdb::zeroVal<ValueT>();
  typename GridT::Ptr grid = GridT::create(background);
  grid->setName(name);
  grid->setTransform(transform);
  grid->setGridClass(vdb::GRID_UNKNOWN);
  grid->setSaveFloatAsHalf(false);
  typename GridT::TreeType& tree = grid->tree();
  const ProbeGrid& g = volume.grid;
  for (int bz = 0; bz < g.counts[2]; bz += kDim) {
    for (int by = 0; by < g.counts[1]; by += kDim) {
      for (int bx = 0; bx < g.counts[0]; bx += kDim) {
        std::unique_ptr<LeafT> leaf;
        const int kEnd = std::min(bz + kDim, g.counts[2]);
        const int jEnd = std::min(by + kDim, g.counts[1]);
        const int iEnd = std::min(bx + kDim, g.counts[0]);
        for (int k = bz; k < kEnd; ++k) {
          for (int j = by; j < jEnd; ++j) {
            int64_t probe = g.LinearIndex(bx, j, k);
            for (int i = bx; i < iEnd; ++i, ++probe) {
              if (!volume.active[size_t(probe)]) continue;
              if (!leaf) leaf = std::make_unique<LeafT>(vdb::Coord(bx, by, bz), background, false);
              leaf->setValueOn(LeafT::coordToOffset(vdb::Coord(i, j, k)), value(size_t(probe)));
            }
          }
        }
        if (leaf) tree.addLeaf(leaf.release());
      }
    }
  }
  return grid;
}

vdb::Vec3SGrid::Ptr BuildShGrid(const ProbeVolume& volume, const std::string& name,
                                const vdb::math::Transform::Ptr& transform,
                                const std::vector<float>& plane, int coefficient) {
  vdb::Vec3SGrid::Ptr grid =
      BuildGrid<vdb::Vec3SGrid>(volume, name, transform, [&plane](size_t probe) {
        return vdb::Vec3s(plane[3 * probe], plane[3 * probe + 1], plane[3 * probe + 2]);
      });
  // RGB does not change under a change of frame.
  grid->setVectorType(vdb::VEC_INVARIANT);
  int l = 0;
  while ((l + 1) * (l + 1) <= coefficient) ++l;
  grid->insertMeta(kKeyShIndex, vdb::Int32Metadata(coefficient));
  grid->insertMeta(kKeyShL, vdb::Int32Metadata(l));
  grid->insertMeta(kKeyShM, vdb::Int32Metadata(coefficient - l * (l + 1)));
  return grid;
}

vdb::FloatGrid::Ptr BuildScalarGrid(const ProbeVolume& volume, const std::string& name,
                                    const vdb::math::Transform::Ptr& transform,
                                    const std::vector<float>& values) {
  return BuildGrid<vdb::FloatGrid>(volume, name, transform,
                                   [&values](size_t probe) { return values[probe]; });
}

vdb::MetaMap FileMetadata(const ProbeVolume& volume, const VolumeMetadata& meta,
                          const std::string& statsJson) {
  const ProbeGrid& g = volume.grid;
  vdb::MetaMap m;
  const bool transfer = volume.skyTransferOrder > 0;
  m.insertMeta(kKeyFormat, vdb::Int32Metadata(kProbeVolumeFormat));
  m.insertMeta(kKeyShOrder, vdb::Int32Metadata(volume.shOrder));
  m.insertMeta(kKeyShBasis, vdb::StringMetadata(kShBasis));
  m.insertMeta(kKeyShWindow, vdb::StringMetadata(volume.window));
  m.insertMeta(kKeyQuantity, vdb::StringMetadata(kQuantity));
  m.insertMeta(kKeyHasIrradiance, vdb::BoolMetadata(!volume.irradiance.empty()));
  m.insertMeta(kKeyColorSpace, vdb::StringMetadata(kColorSpace));
  m.insertMeta(kKeySamplesPerProbe, vdb::Int64Metadata(meta.samplesPerProbe));
  m.insertMeta(kKeyMaxDepth, vdb::Int32Metadata(meta.maxDepth));
  // OpenVDB has no unsigned 64-bit metadata: the seed's bits go into an int64.
  m.insertMeta(kKeySeed, vdb::Int64Metadata(static_cast<int64_t>(meta.seed)));
  m.insertMeta(kKeySceneDigest, vdb::StringMetadata(meta.sceneDigest));
  m.insertMeta(kKeySettings, vdb::StringMetadata(meta.settingsJson));
  if (!meta.ignored.empty()) m.insertMeta(kKeyIgnored, vdb::StringMetadata(meta.ignored));
  m.insertMeta(kKeyGenerator, vdb::StringMetadata(std::string(kGeneratorName) + " " + kVersion));
  m.insertMeta(kKeyStats, vdb::StringMetadata(statsJson));
  m.insertMeta(kKeyGridCounts,
               vdb::Vec3IMetadata(vdb::Vec3i(g.counts[0], g.counts[1], g.counts[2])));
  m.insertMeta(kKeyGridMin, vdb::Vec3DMetadata(vdb::Vec3d(g.origin.x, g.origin.y, g.origin.z)));
  m.insertMeta(kKeyGridSpacing,
               vdb::Vec3DMetadata(vdb::Vec3d(g.spacing.x, g.spacing.y, g.spacing.z)));
  m.insertMeta(kKeyGridPlacement, vdb::StringMetadata(PlacementName(g.placement)));
  m.insertMeta(kKeyGridSurfaceDistance, vdb::DoubleMetadata(g.surfaceDistance));
  m.insertMeta(kKeyHasOffset, vdb::BoolMetadata(!volume.offset.empty()));
  m.insertMeta(kKeyHasFilled, vdb::BoolMetadata(!volume.filled.empty()));
  m.insertMeta(kKeyVisibilitySize,
               vdb::Int32Metadata(volume.visibility.empty() ? 0 : kVisibilityMapSize));
  m.insertMeta(
      kKeyVisibilityMaxDistance,
      vdb::DoubleMetadata(volume.visibility.empty() ? 0.0 : VisibilityMaxDistance(volume.grid)));
  // The sky transfer's keys, only with a sky transfer.
  if (transfer) {
    m.insertMeta(kKeySkyTransferOrder, vdb::Int32Metadata(volume.skyTransferOrder));
    m.insertMeta(kKeySkyTransferPrecision, vdb::StringMetadata(kSkyTransferPrecision));
  }
  return m;
}

// Writes every grid into `os`. When `releasable` is set (it is `volume` itself), each plane is
// freed as soon as its grid is built.
absl::Status WriteGrids(std::ostream& os, const std::string& path, const ProbeVolume& volume,
                        const VolumeMetadata& meta, const std::string& statsJson,
                        ProbeVolume* releasable) {
  const int coefficients = volume.CoeffCount();
  const bool hasIrradiance = !volume.irradiance.empty();
  const int32_t gridCount = coefficients * (hasIrradiance ? 2 : 1) + 4 +
                            (volume.offset.empty() ? 0 : 1) + (volume.filled.empty() ? 0 : 1) +
                            int32_t(volume.visibility.size()) + int32_t(volume.skyTransfer.size());
  const vdb::math::Transform::Ptr transform = ProbeTransform(volume.grid);

  StreamingArchive archive;
  archive.Begin(os, FileMetadata(volume, meta, statsJson), gridCount);
  auto release = [](std::vector<float>* plane) { std::vector<float>().swap(*plane); };
  auto check = [&](const std::string& gridName) -> absl::Status {
    if (os) return absl::OkStatus();
    return IoError(errno != 0 ? errno : EIO, path, "writing grid " + gridName + " failed");
  };
  PB_RETURN_IF_ERROR(check("(file header)"));

  for (int pass = 0; pass < (hasIrradiance ? 2 : 1); ++pass) {
    for (int c = 0; c < coefficients; ++c) {
      const std::string name = pass == 0 ? RadianceGridName(c) : IrradianceGridName(c);
      const std::vector<float>& plane =
          pass == 0 ? volume.radiance[size_t(c)] : volume.irradiance[size_t(c)];
      vdb::GridBase::ConstPtr grid = BuildShGrid(volume, name, transform, plane, c);
      if (releasable != nullptr) {
        release(pass == 0 ? &releasable->radiance[size_t(c)] : &releasable->irradiance[size_t(c)]);
      }
      archive.WriteGrid(os, grid);
      PB_RETURN_IF_ERROR(check(name));
    }
  }
  struct Scalar {
    const char* name;
    const std::vector<float>& values;
    std::vector<float>* releasable;
  };
  for (const Scalar& s :
       {Scalar{kValidityGridName, volume.validity, releasable ? &releasable->validity : nullptr},
        Scalar{kStdErrorGridName, volume.stdError, releasable ? &releasable->stdError : nullptr},
        Scalar{kStdErrorL0GridName, volume.stdErrorL0,
               releasable ? &releasable->stdErrorL0 : nullptr},
        Scalar{kSampleCountGridName, volume.sampleCount,
               releasable ? &releasable->sampleCount : nullptr}}) {
    vdb::GridBase::ConstPtr grid = BuildScalarGrid(volume, s.name, transform, s.values);
    if (s.releasable != nullptr) release(s.releasable);
    archive.WriteGrid(os, grid);
    PB_RETURN_IF_ERROR(check(s.name));
  }
  // Format 3's optional grids.
  auto writeVec3 = [&](const std::string& name, const std::vector<float>& plane,
                       std::vector<float>* releasablePlane) -> absl::Status {
    vdb::Vec3SGrid::Ptr grid =
        BuildGrid<vdb::Vec3SGrid>(volume, name, transform, [&plane](size_t p) {
          return vdb::Vec3s(plane[3 * p], plane[3 * p + 1], plane[3 * p + 2]);
        });
    grid->setVectorType(vdb::VEC_INVARIANT);
    if (releasablePlane != nullptr) release(releasablePlane);
    archive.WriteGrid(os, grid);
    return check(name);
  };
  if (!volume.offset.empty()) {
    // An offset is a world-space displacement: it does not scale with the voxel size.
    PB_RETURN_IF_ERROR(
        writeVec3(kOffsetGridName, volume.offset, releasable ? &releasable->offset : nullptr));
  }
  if (!volume.filled.empty()) {
    vdb::GridBase::ConstPtr grid =
        BuildScalarGrid(volume, kFilledGridName, transform, volume.filled);
    if (releasable != nullptr) release(&releasable->filled);
    archive.WriteGrid(os, grid);
    PB_RETURN_IF_ERROR(check(kFilledGridName));
  }
  for (size_t t = 0; t < volume.visibility.size(); ++t) {
    PB_RETURN_IF_ERROR(writeVec3(VisibilityGridName(int(t)), volume.visibility[t],
                                 releasable ? &releasable->visibility[t] : nullptr));
  }
  // Format 4: the sky transfer, row-major, each grid saved as half floats (OpenVDB's own
  // saveFloatAsHalf, which stock tools read back as floats): the values are half-precision
  // numbers already (the bake rounds them), so nothing is lost.
  const int skyCoefficients = volume.SkyCoeffCount();
  for (size_t e = 0; e < volume.skyTransfer.size(); ++e) {
    const int row = int(e) / skyCoefficients, column = int(e) % skyCoefficients;
    const std::string name = SkyTransferGridName(row, column);
    vdb::Vec3SGrid::Ptr grid = BuildShGrid(volume, name, transform, volume.skyTransfer[e], row);
    grid->setSaveFloatAsHalf(true);
    grid->insertMeta(kKeySkyShIndex, vdb::Int32Metadata(column));
    if (releasable != nullptr) release(&releasable->skyTransfer[e]);
    archive.WriteGrid(os, grid);
    PB_RETURN_IF_ERROR(check(name));
  }
  return absl::OkStatus();
}

absl::Status WriteImpl(const std::string& path, const ProbeVolume& volume,
                       const VolumeMetadata& meta, ProbeVolume* releasable) {
  PB_RETURN_IF_ERROR(ValidateVolume(volume));
  PB_ASSIGN_OR_RETURN(const std::string statsJson, StatsToJson(volume.stats));
  InitializeOpenVdbOnce();
  PB_ASSIGN_OR_RETURN(AtomicFile file, AtomicFile::Create(path));
  absl::Status status;
  try {
    std::ofstream os(file.tempPath(),
                     std::ios_base::out | std::ios_base::binary | std::ios_base::trunc);
    if (!os) return IoError(errno != 0 ? errno : EIO, path, "cannot open " + file.tempPath());
    errno = 0;
    status = WriteGrids(os, path, volume, meta, statsJson, releasable);
    if (status.ok()) {
      os.close();
      if (!os) status = IoError(errno != 0 ? errno : EIO, path, "flushing the file failed");
    }
  } catch (const std::bad_alloc&) {
    status = absl::ResourceExhaustedError(path + ": out of memory while writing the volume");
  } catch (const vdb::Exception& e) {
    status = absl::InternalError(path + ": OpenVDB: " + e.what());
  } catch (const std::exception& e) {
    status = absl::InternalError(path + ": " + e.what());
  }
  if (!status.ok()) {
    file.Abort();
    return status;
  }
  PB_RETURN_IF_ERROR(file.Commit());
  Logger("volume")->debug("wrote {} ({} probes, order {})", path, volume.grid.ProbeCount(),
                          volume.shOrder);
  return absl::OkStatus();
}

}  // namespace

absl::Status WriteProbeVolume(const std::string& path, const ProbeVolume& volume,
                              const VolumeMetadata& meta) {
  return WriteImpl(path, volume, meta, nullptr);
}

absl::Status WriteProbeVolume(const std::string& path, ProbeVolume&& volume,
                              const VolumeMetadata& meta) {
  // Not written to the file: freed before the first grid is built, so the memory they hold (as
  // much as the radiance planes for radianceStdError) is not held while writing.
  std::vector<std::vector<float>>().swap(volume.radianceStdError);
  std::vector<float>().swap(volume.autoWindowT);
  absl::Status status = WriteImpl(path, volume, meta, &volume);
  // Whatever happened, the planes are the caller's no more.
  std::vector<std::vector<float>>().swap(volume.skyTransferStdError);
  for (auto* planes :
       {&volume.radiance, &volume.irradiance, &volume.visibility, &volume.skyTransfer}) {
    std::vector<std::vector<float>>().swap(*planes);
  }
  for (auto* values : {&volume.validity, &volume.stdError, &volume.stdErrorL0, &volume.sampleCount,
                       &volume.offset, &volume.filled}) {
    std::vector<float>().swap(*values);
  }
  return status;
}

absl::Status CheckOutputWritable(const std::string& path) {
  PB_ASSIGN_OR_RETURN(AtomicFile probe, AtomicFile::Create(path));
  probe.Abort();
  return absl::OkStatus();
}

}  // namespace probebake
