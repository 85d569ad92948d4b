// The file as OpenVDB itself sees it (docs/volume-format.md): grid names and types, one shared
// transform with indexToWorld(i, j, k) = min + spacing * (i, j, k), active voxels = baked probes,
// metadata types; the streamed file equals what openvdb::io::File::write makes of the same grids;
// and ReadProbeVolume's validation of hand-broken files. The only test file that includes OpenVDB.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>
#include <utility>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include "probebake/volume/vdb_io.h"
#include "volume/test_volumes.h"

namespace probebake {
namespace {

namespace vdb = openvdb;
using testing::MakeTestMetadata;
using testing::MakeTestVolume;
using testing::TempDir;
using testing::TestVolumeSpec;

class VdbLayout : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { vdb::initialize(); }

  void SetUp() override {
    spec_.irradiance = true;
    volume_ = MakeTestVolume(spec_);
    path_ = dir_.File("volume.vdb");
    PB_ASSERT_OK(WriteProbeVolume(path_, volume_, MakeTestMetadata()));
  }

  // The grid names in the order WriteProbeVolume writes them.
  std::vector<std::string> ExpectedNames() const {
    std::vector<std::string> names;
    for (int c = 0; c < volume_.CoeffCount(); ++c) names.push_back(RadianceGridName(c));
    for (int c = 0; c < volume_.CoeffCount(); ++c) names.push_back(IrradianceGridName(c));
    names.insert(names.end(), {"validity", "std_error", "std_error_l0", "sample_count"});
    return names;
  }

  // Every grid of the file, in ExpectedNames() order, and the file metadata.
  void ReadAll(const std::string& path, vdb::GridPtrVec* grids, vdb::MetaMap::Ptr* meta) {
    vdb::io::File file(path);
    file.open(false);
    *meta = file.getMetadata();
    for (const std::string& name : ExpectedNames()) grids->push_back(file.readGrid(name));
    file.close();
  }

  // Writes `grids` and `meta` with openvdb::io::File, then returns ReadProbeVolume's status.
  absl::Status WriteAndRead(const vdb::GridPtrVec& grids, const vdb::MetaMap& meta) {
    const std::string path = dir_.File("broken" + std::to_string(broken_++) + ".vdb");
    vdb::io::File(path).write(grids, meta);
    return ReadProbeVolume(path).status();
  }

  static vdb::GridBase::Ptr Find(const vdb::GridPtrVec& grids, const std::string& name) {
    for (const auto& g : grids) {
      if (g->getName() == name) return g;
    }
    return nullptr;
  }

  TestVolumeSpec spec_;
  ProbeVolume volume_;
  TempDir dir_;
  std::string path_;
  int broken_ = 0;
};

TEST_F(VdbLayout, GridsTransformAndActiveVoxelsFollowTheSpec) {
  vdb::io::File file(path_);
  file.open(false);
  std::vector<std::string> names;
  for (auto it = file.beginName(); it != file.endName(); ++it) names.push_back(it.gridName());
  std::vector<std::string> expected = ExpectedNames();
  std::sort(names.begin(), names.end());
  std::sort(expected.begin(), expected.end());
  ASSERT_EQ(names, expected);

  const ProbeGrid& g = volume_.grid;
  int64_t activeProbes = 0;
  for (uint8_t a : volume_.active) activeProbes += a;
  ASSERT_GT(activeProbes, 0);
  ASSERT_LT(activeProbes, g.ProbeCount());

  vdb::math::Transform::Ptr shared;
  for (const std::string& name : expected) {
    SCOPED_TRACE(name);
    const vdb::GridBase::Ptr base = file.readGrid(name);
    const bool isSh = name.find("_sh_") != std::string::npos;
    if (isSh) {
      ASSERT_TRUE(base->isType<vdb::Vec3SGrid>()) << base->type();
      EXPECT_EQ(base->getVectorType(), vdb::VEC_INVARIANT);
      const int c = std::stoi(name.substr(name.size() - 2));
      int l = 0;
      while ((l + 1) * (l + 1) <= c) ++l;
      EXPECT_EQ(base->metaValue<int32_t>("sh_index"), c);
      EXPECT_EQ(base->metaValue<int32_t>("sh_l"), l);
      EXPECT_EQ(base->metaValue<int32_t>("sh_m"), c - l * (l + 1));
    } else {
      ASSERT_TRUE(base->isType<vdb::FloatGrid>()) << base->type();
    }
    EXPECT_FALSE(base->saveFloatAsHalf());
    EXPECT_EQ(base->getGridClass(), vdb::GRID_UNKNOWN);
    EXPECT_EQ(int64_t(base->activeVoxelCount()), activeProbes);
    if (vdb::io::Archive::hasBloscCompression()) {
      EXPECT_NE(base->metaValue<std::string>("file_compression").find("blosc"), std::string::npos);
    }

    // One transform for all, mapping index (i, j, k) to the probe's position exactly.
    if (!shared) shared = base->transformPtr();
    EXPECT_EQ(base->constTransform(), *shared);
    for (int k = 0; k < g.counts[2]; ++k) {
      for (int j = 0; j < g.counts[1]; ++j) {
        for (int i = 0; i < g.counts[0]; ++i) {
          const vdb::Vec3d w = base->indexToWorld(vdb::Coord(i, j, k));
          const Vec3d p = g.Position(i, j, k);
          ASSERT_EQ(w, vdb::Vec3d(p.x, p.y, p.z)) << i << " " << j << " " << k;
        }
      }
    }

    // Active voxels are exactly the active probes, holding their values; background 0.
    const std::vector<float>* values = nullptr;
    if (isSh) {
      const int c = std::stoi(name.substr(name.size() - 2));
      values = name[0] == 'r' ? &volume_.radiance[size_t(c)] : &volume_.irradiance[size_t(c)];
    } else if (name == "validity") {
      values = &volume_.validity;
    } else if (name == "std_error") {
      values = &volume_.stdError;
    } else if (name == "std_error_l0") {
      values = &volume_.stdErrorL0;
    } else {
      values = &volume_.sampleCount;
    }
    for (int k = -1; k <= g.counts[2]; ++k) {
      for (int j = -1; j <= g.counts[1]; ++j) {
        for (int i = -1; i <= g.counts[0]; ++i) {
          const bool inside =
              i >= 0 && j >= 0 && k >= 0 && i < g.counts[0] && j < g.counts[1] && k < g.counts[2];
          const size_t p = inside ? size_t(g.LinearIndex(i, j, k)) : 0;
          const bool active = inside && volume_.active[p];
          const vdb::Coord xyz(i, j, k);
          if (isSh) {
            const auto grid = vdb::gridPtrCast<vdb::Vec3SGrid>(base);
            ASSERT_EQ(grid->tree().isValueOn(xyz), active) << xyz;
            const vdb::Vec3s v = grid->tree().getValue(xyz);
            const vdb::Vec3s want =
                active ? vdb::Vec3s((*values)[3 * p], (*values)[3 * p + 1], (*values)[3 * p + 2])
                       : vdb::Vec3s(0.0f);
            for (int ch = 0; ch < 3; ++ch) {
              const float got = v[ch], wantCh = want[ch];
              ASSERT_EQ(std::memcmp(&got, &wantCh, sizeof(float)), 0)
                  << xyz << " channel " << ch << ": expected " << want[ch] << ", got " << v[ch];
            }
            EXPECT_EQ(grid->background(), vdb::Vec3s(0.0f));
          } else {
            const auto grid = vdb::gridPtrCast<vdb::FloatGrid>(base);
            ASSERT_EQ(grid->tree().isValueOn(xyz), active) << xyz;
            const float want = active ? (*values)[p] : 0.0f;
            const float v = grid->tree().getValue(xyz);
            ASSERT_EQ(std::memcmp(&v, &want, sizeof(float)), 0)
                << xyz << ": expected " << want << ", got " << v;
            EXPECT_EQ(grid->background(), 0.0f);
          }
        }
      }
    }
  }
}

TEST_F(VdbLayout, FileMetadataKeysTypesAndValues) {
  vdb::io::File file(path_);
  file.open(false);
  const vdb::MetaMap::Ptr meta = file.getMetadata();
  const VolumeMetadata m = MakeTestMetadata();
  struct Key {
    const char* name;
    const char* type;
  };
  const Key keys[] = {{"probebake_format", "int32"},
                      {"sh_order", "int32"},
                      {"sh_basis", "string"},
                      {"sh_window", "string"},
                      {"quantity", "string"},
                      {"has_irradiance", "bool"},
                      {"color_space", "string"},
                      {"samples_per_probe", "int64"},
                      {"max_depth", "int32"},
                      {"seed", "int64"},
                      {"scene_digest", "string"},
                      {"settings", "string"},
                      {"generator", "string"},
                      {"stats", "string"},
                      {"grid_counts", "vec3i"},
                      {"grid_min", "vec3d"},
                      {"grid_spacing", "vec3d"},
                      {"grid_placement", "string"},
                      {"grid_surface_distance", "double"},
                      {"has_offset", "bool"},
                      {"has_filled", "bool"},
                      {"visibility_size", "int32"},
                      {"visibility_max_distance", "double"}};
  std::set<std::string> names;
  for (auto it = meta->beginMeta(); it != meta->endMeta(); ++it) names.insert(it->first);
  EXPECT_EQ(names.size(), std::size(keys));
  for (const Key& key : keys) {
    const vdb::Metadata::Ptr value = (*meta)[key.name];
    ASSERT_TRUE(value) << key.name;
    EXPECT_EQ(value->typeName(), key.type) << key.name;
  }
  EXPECT_EQ(meta->metaValue<int32_t>("probebake_format"), 3);
  EXPECT_EQ(meta->metaValue<int32_t>("sh_order"), 2);
  EXPECT_EQ(meta->metaValue<std::string>("sh_basis"), "real-orthonormal-condon-shortley-zpolar");
  EXPECT_EQ(meta->metaValue<std::string>("sh_window"), "HANNING");
  EXPECT_EQ(meta->metaValue<std::string>("quantity"), "radiance");
  EXPECT_TRUE(meta->metaValue<bool>("has_irradiance"));
  EXPECT_EQ(meta->metaValue<std::string>("color_space"), "linear-rec709");
  EXPECT_EQ(meta->metaValue<int64_t>("samples_per_probe"), m.samplesPerProbe);
  EXPECT_EQ(meta->metaValue<int32_t>("max_depth"), m.maxDepth);
  EXPECT_EQ(uint64_t(meta->metaValue<int64_t>("seed")), m.seed);
  EXPECT_EQ(meta->metaValue<std::string>("scene_digest"), m.sceneDigest);
  EXPECT_EQ(meta->metaValue<std::string>("settings"), m.settingsJson);
  EXPECT_EQ(meta->metaValue<vdb::Vec3i>("grid_counts"), vdb::Vec3i(3, 4, 5));
  EXPECT_EQ(meta->metaValue<vdb::Vec3d>("grid_min"), vdb::Vec3d(-3.5, -1, -10.25));
  EXPECT_EQ(meta->metaValue<vdb::Vec3d>("grid_spacing"), vdb::Vec3d(0.5, 1.25, 2));
}

TEST_F(VdbLayout, StreamedFileEqualsOpenVdbFileWriteExceptTheUuid) {
  vdb::GridPtrVec grids;
  vdb::MetaMap::Ptr meta;
  ReadAll(path_, &grids, &meta);
  const std::string again = dir_.File("again.vdb");
  vdb::io::File(again).write(grids, *meta);
  auto bytes = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::vector<char>(std::istreambuf_iterator<char>(in), {});
  };
  std::vector<char> ours = bytes(path_), theirs = bytes(again);
  ASSERT_EQ(ours.size(), theirs.size());
  // Header: magic (8 bytes), file version (4), library version (8), grid offsets flag (1), then
  // the 36-character UUID that OpenVDB draws at random for every file.
  constexpr size_t kUuidOffset = 21, kUuidSize = 36;
  EXPECT_NE(std::string(&ours[kUuidOffset], kUuidSize),
            std::string(&theirs[kUuidOffset], kUuidSize));
  std::fill_n(ours.begin() + kUuidOffset, kUuidSize, 0);
  std::fill_n(theirs.begin() + kUuidOffset, kUuidSize, 0);
  const auto mismatch = std::mismatch(ours.begin(), ours.end(), theirs.begin());
  EXPECT_TRUE(mismatch.first == ours.end())
      << "first difference at byte " << (mismatch.first - ours.begin()) << " of " << ours.size();
}

TEST_F(VdbLayout, ReaderRejectsBrokenFilesNamingTheGridOrKey) {
  vdb::GridPtrVec good;
  vdb::MetaMap::Ptr meta;
  ReadAll(path_, &good, &meta);
  ASSERT_TRUE(WriteAndRead(good, *meta).ok());

  auto expectError = [&](const absl::Status& status, const std::string& name,
                         const std::string& reason) {
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    const std::string message(status.message());
    EXPECT_NE(message.find(name), std::string::npos) << "want " << name << " in: " << message;
    EXPECT_NE(message.find(reason), std::string::npos) << "want " << reason << " in: " << message;
  };
  {  // a missing SH grid
    vdb::GridPtrVec grids = good;
    grids.erase(grids.begin() + 4);
    expectError(WriteAndRead(grids, *meta), "radiance_sh_04", "missing");
  }
  {  // a grid of the wrong type
    vdb::GridPtrVec grids = good;
    auto wrong = vdb::Vec3SGrid::create();
    wrong->setName("validity");
    wrong->setTransform(good[0]->transformPtr());
    std::replace(grids.begin(), grids.end(), Find(good, "validity"), vdb::GridBase::Ptr(wrong));
    expectError(WriteAndRead(grids, *meta), "validity", "type");
  }
  {  // one grid with another transform
    vdb::GridPtrVec grids = good;
    vdb::GridBase::Ptr copy = Find(good, "std_error")->deepCopyGrid();
    copy->setTransform(vdb::math::Transform::createLinearTransform(0.5));
    std::replace(grids.begin(), grids.end(), Find(good, "std_error"), copy);
    expectError(WriteAndRead(grids, *meta), "std_error", "transform");
  }
  {  // a rotated transform everywhere
    vdb::GridPtrVec grids;
    vdb::math::Transform::Ptr rotated = good[0]->transform().copy();
    rotated->preRotate(0.3, vdb::math::Z_AXIS);
    for (const auto& g : good) {
      grids.push_back(g->deepCopyGrid());
      grids.back()->setTransform(rotated);
    }
    expectError(WriteAndRead(grids, *meta), "validity", "transform");
  }
  {  // a format this reader does not know
    vdb::MetaMap::Ptr m = meta->copyMeta();
    m->removeMeta("probebake_format");
    m->insertMeta("probebake_format", vdb::Int32Metadata(5));
    expectError(WriteAndRead(good, *m), "probebake_format", "this reader knows 1 to 4");
  }
  {  // format 1 has no std_error_l0 grid: one is not part of it
    vdb::MetaMap::Ptr m = meta->copyMeta();
    m->removeMeta("probebake_format");
    m->insertMeta("probebake_format", vdb::Int32Metadata(1));
    expectError(WriteAndRead(good, *m), "std_error_l0", "not part of probe volume format 1");
  }
  {  // format 2 without its std_error_l0 grid
    vdb::GridPtrVec grids = good;
    grids.erase(std::find(grids.begin(), grids.end(), Find(good, "std_error_l0")));
    expectError(WriteAndRead(grids, *meta), "std_error_l0", "missing");
  }
  {  // an extra grid
    vdb::GridPtrVec grids = good;
    auto extra = vdb::FloatGrid::create();
    extra->setName("density");
    grids.push_back(extra);
    expectError(WriteAndRead(grids, *meta), "density", "not part of");
  }
  {  // irradiance grids although has_irradiance is false
    vdb::MetaMap::Ptr m = meta->copyMeta();
    m->removeMeta("has_irradiance");
    m->insertMeta("has_irradiance", vdb::BoolMetadata(false));
    expectError(WriteAndRead(good, *m), "irradiance_sh_", "has_irradiance");
  }
  {  // an active voxel where validity has none
    vdb::GridPtrVec grids = good;
    vdb::GridBase::Ptr copy = Find(good, "sample_count")->deepCopyGrid();
    const size_t inactive =
        size_t(std::find(volume_.active.begin(), volume_.active.end(), 0) - volume_.active.begin());
    ASSERT_LT(inactive, volume_.active.size());
    int i, j, k;
    volume_.grid.Coords(int64_t(inactive), &i, &j, &k);
    vdb::gridPtrCast<vdb::FloatGrid>(copy)->tree().setValueOn(vdb::Coord(i, j, k), 1.0f);
    std::replace(grids.begin(), grids.end(), Find(good, "sample_count"), copy);
    expectError(WriteAndRead(grids, *meta), "sample_count", "not active in grid validity");
  }
  {  // an active voxel outside the grid, in every grid
    vdb::GridPtrVec grids;
    for (const auto& g : good) {
      grids.push_back(g->deepCopyGrid());
      if (auto f = vdb::gridPtrCast<vdb::FloatGrid>(grids.back())) {
        f->tree().setValueOn(vdb::Coord(3, 0, 0), 1.0f);
      } else {
        vdb::gridPtrCast<vdb::Vec3SGrid>(grids.back())
            ->tree()
            .setValueOn(vdb::Coord(3, 0, 0), vdb::Vec3s(1.0f));
      }
    }
    expectError(WriteAndRead(grids, *meta), "grid validity", "outside");
  }
  {  // metadata of the wrong type, and a missing key
    vdb::MetaMap::Ptr m = meta->copyMeta();
    m->removeMeta("sh_order");
    m->insertMeta("sh_order", vdb::StringMetadata("2"));
    expectError(WriteAndRead(good, *m), "sh_order", "expected int32");
    m = meta->copyMeta();
    m->removeMeta("stats");
    expectError(WriteAndRead(good, *m), "stats", "missing");
    // stats that are not the documented object.
    const std::pair<const char*, const char*> badStats[] = {
        {"[1,2]", "stats: not a JSON object"},
        {"{\"wallSeconds\":1", "stats: not a JSON object"},
        {"{\"threads\":1,\"probes\":1,\"samples\":1,\"rays\":1,\"invalidProbes\":0}",
         "stats.wallSeconds: missing"},
        {"{\"wallSeconds\":\"1\",\"threads\":1,\"probes\":1,\"samples\":1,\"rays\":1,"
         "\"invalidProbes\":0}",
         "stats.wallSeconds: not a number"},
        {"{\"wallSeconds\":1,\"threads\":1,\"probes\":1,\"samples\":1,\"rays\":1.5,"
         "\"invalidProbes\":0}",
         "stats.rays: not an integer"},
        {"{\"wallSeconds\":1,\"threads\":1,\"probes\":1,\"samples\":9007199254740992,"
         "\"rays\":1,\"invalidProbes\":0}",
         "stats.samples: not an integer"},
        {"{\"wallSeconds\":1,\"threads\":4294967296,\"probes\":1,\"samples\":1,\"rays\":1,"
         "\"invalidProbes\":0}",
         "stats.threads: out of range"},
    };
    for (const auto& [stats, reason] : badStats) {
      m = meta->copyMeta();
      m->removeMeta("stats");
      m->insertMeta("stats", vdb::StringMetadata(stats));
      expectError(WriteAndRead(good, *m), "stats", reason);
    }
    m = meta->copyMeta();
    m->removeMeta("grid_min");
    m->insertMeta("grid_min", vdb::Vec3DMetadata(vdb::Vec3d(0, 0, 0)));
    expectError(WriteAndRead(good, *m), "grid_min", "disagrees");
    m = meta->copyMeta();
    m->removeMeta("grid_spacing");
    m->insertMeta("grid_spacing", vdb::Vec3DMetadata(vdb::Vec3d(0.5, 0, 2)));
    expectError(WriteAndRead(good, *m), "grid_spacing", "must be finite and > 0");
    // Spacing x 0.5 at origin -3.5: the reader allows gamma2 (0.5 + 3.5) + 1e-15 ~ 1.9e-15
    // (TransformScaleTolerance in vdb_read.cpp); 1e-14 is beyond, 1e-15 within.
    m = meta->copyMeta();
    m->removeMeta("grid_spacing");
    m->insertMeta("grid_spacing", vdb::Vec3DMetadata(vdb::Vec3d(0.5 + 1e-14, 1.25, 2)));
    expectError(WriteAndRead(good, *m), "grid_spacing", "disagrees");
    m = meta->copyMeta();
    m->removeMeta("grid_spacing");
    m->insertMeta("grid_spacing", vdb::Vec3DMetadata(vdb::Vec3d(0.5 + 1e-15, 1.25, 2)));
    {
      const std::string path = dir_.File("within.vdb");
      vdb::io::File(path).write(good, *m);
      const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
      ASSERT_TRUE(read.ok()) << read.status();
      EXPECT_EQ(read->volume.grid.spacing.x, 0.5 + 1e-15);  // the metadata is authoritative
    }
  }
}

// Awkward spacings (2/3, 0.1, 1e-3, 1e4/3, per axis) and origins far from 0: OpenVDB's Transform
// constructor re-derives the voxel size as fl(fl(s + t) - t) (math::simplify), so the file's
// transform is the spacing only to within rounding; index (i, j, k) must still map to
// min + spacing * (i, j, k) to within that rounding.
class AwkwardLayout : public ::testing::TestWithParam<testing::AwkwardGrid> {
 protected:
  static void SetUpTestSuite() { vdb::initialize(); }
};

TEST_P(AwkwardLayout, IndexToWorldIsMinPlusSpacingTimesIndexWithinRounding) {
  const testing::AwkwardGrid& c = GetParam();
  TestVolumeSpec spec;
  spec.origin = c.origin;
  spec.spacing = c.spacing;
  for (int a = 0; a < 3; ++a) spec.counts[a] = c.counts[a];
  spec.shOrder = 0;
  const ProbeVolume volume = MakeTestVolume(spec);
  TempDir dir;
  const std::string path = dir.File("awkward.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, volume, MakeTestMetadata()));

  vdb::io::File file(path);
  file.open(false);
  const vdb::GridBase::Ptr grid = file.readGrid("validity");
  file.close();
  const vdb::math::Transform& transform = grid->constTransform();
  ASSERT_TRUE(transform.isLinear());

  // Unit roundoff u = 2^-53 and Higham's gamma2 = 2u / (1 - 2u) bound two roundings.
  constexpr double u = std::numeric_limits<double>::epsilon() / 2;
  constexpr double gamma2 = 2 * u / (1 - 2 * u);
  const ProbeGrid& g = volume.grid;
  double scaleTolerance[3];
  const vdb::Vec3d voxelSize = transform.voxelSize();
  for (int a = 0; a < 3; ++a) {
    // fl(fl(s + t) - t) is within gamma2 (|s| + |t|) of s; OpenVDB then makes the map uniform
    // when the three scales agree within math::Tolerance<double> = 1e-15 (absolute).
    scaleTolerance[a] = gamma2 * (g.spacing[a] + std::abs(g.origin[a])) + 1e-15;
    EXPECT_LE(std::abs(voxelSize[a] - g.spacing[a]), scaleTolerance[a])
        << "axis " << a << ": expected " << g.spacing[a] << ", got " << voxelSize[a];
  }
  for (int k = 0; k < g.counts[2]; ++k) {
    for (int j = 0; j < g.counts[1]; ++j) {
      for (int i = 0; i < g.counts[0]; ++i) {
        const vdb::Vec3d w = transform.indexToWorld(vdb::Coord(i, j, k));
        const Vec3d p = g.Position(i, j, k);
        const int ijk[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          // OpenVDB computes fl(fl(n s') + t), Position fl(fl(n s) + t), |s' - s| <= tau: each
          // is within gamma2 (n |s| + |t|) of its exact value (s' within tau of s), so they
          // differ by at most n tau + gamma2 (n (2 |s| + tau) + 2 |t|).
          const double n = ijk[a], s = g.spacing[a], t = std::abs(g.origin[a]);
          const double tau = scaleTolerance[a];
          const double tolerance = n * tau + gamma2 * (n * (2 * s + tau) + 2 * t);
          ASSERT_LE(std::abs(w[a] - p[a]), tolerance)
              << "(" << i << ", " << j << ", " << k << ") axis " << a << ": expected " << p[a]
              << ", got " << w[a] << ", tolerance " << tolerance;
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Grids, AwkwardLayout, ::testing::ValuesIn(testing::AwkwardGrids()),
                         [](const ::testing::TestParamInfo<testing::AwkwardGrid>& param) {
                           return param.param.name;
                         });

TEST_F(VdbLayout, CountsComeFromTheActiveBoxWithoutGridCounts) {
  // Make the last probe active so the active box reaches the grid's far corner.
  volume_.active.back() = 1;
  PB_ASSERT_OK(WriteProbeVolume(path_, volume_, MakeTestMetadata()));
  vdb::GridPtrVec grids;
  vdb::MetaMap::Ptr meta;
  ReadAll(path_, &grids, &meta);
  meta->removeMeta("grid_counts");
  const std::string path = dir_.File("nocounts.vdb");
  vdb::io::File(path).write(grids, *meta);
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  for (int a = 0; a < 3; ++a) EXPECT_EQ(read->volume.grid.counts[a], volume_.grid.counts[a]);
  EXPECT_EQ(read->volume.active, volume_.active);
}

TEST_F(VdbLayout, ReadsFormatTwoFiles) {
  // A format-2 file: format 3 without its optional grids and their metadata keys. It reads as a
  // volume without offsets, dilation flags or visibility.
  vdb::GridPtrVec grids;
  vdb::MetaMap::Ptr meta;
  ReadAll(path_, &grids, &meta);
  meta->removeMeta("probebake_format");
  meta->insertMeta("probebake_format", vdb::Int32Metadata(2));
  for (const char* key : {"has_offset", "has_filled", "visibility_size", "visibility_max_distance"})
    meta->removeMeta(key);
  const std::string path = dir_.File("format2.vdb");
  vdb::io::File(path).write(grids, *meta);
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->format, 2);
  EXPECT_EQ(read->volume.radiance, volume_.radiance);
  EXPECT_EQ(read->volume.stdError, volume_.stdError);
  EXPECT_TRUE(read->volume.offset.empty());
  EXPECT_TRUE(read->volume.visibility.empty());
}

TEST_F(VdbLayout, ReadsFormatOneFiles) {
  // A format-1 file: the same grids but std_error_l0, its std_error holding the L0 figure
  // (docs/volume-format.md, migration notes). It reads as that figure in stdErrorL0, with the
  // irradiance figure, which format 1 did not record, unknown (+inf) at every active probe.
  vdb::GridPtrVec grids;
  vdb::MetaMap::Ptr meta;
  ReadAll(path_, &grids, &meta);
  grids.erase(std::find(grids.begin(), grids.end(), Find(grids, "std_error_l0")));
  meta->removeMeta("probebake_format");
  meta->insertMeta("probebake_format", vdb::Int32Metadata(1));
  for (const char* key : {"has_offset", "has_filled", "visibility_size", "visibility_max_distance"})
    meta->removeMeta(key);
  const std::string path = dir_.File("format1.vdb");
  vdb::io::File(path).write(grids, *meta);
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->format, 1);
  const ProbeVolume& v = read->volume;
  EXPECT_EQ(v.active, volume_.active);
  EXPECT_EQ(v.radiance, volume_.radiance);
  EXPECT_EQ(v.stdErrorL0, volume_.stdError);  // the file's std_error grid
  ASSERT_EQ(v.stdError.size(), volume_.active.size());
  for (size_t p = 0; p < v.stdError.size(); ++p) {
    if (volume_.active[p]) {
      EXPECT_TRUE(std::isinf(v.stdError[p])) << p;
    } else {
      EXPECT_EQ(v.stdError[p], 0.0f) << p;
    }
  }
  // Written back, it is a format-3 file that says as much.
  const std::string again = dir_.File("format3.vdb");
  PB_ASSERT_OK(WriteProbeVolume(again, v, read->meta));
  const absl::StatusOr<ProbeVolumeFile> reread = ReadProbeVolume(again);
  ASSERT_TRUE(reread.ok()) << reread.status();
  EXPECT_EQ(reread->format, 3);
  EXPECT_EQ(reread->volume.stdErrorL0, volume_.stdError);
}

}  // namespace
}  // namespace probebake
