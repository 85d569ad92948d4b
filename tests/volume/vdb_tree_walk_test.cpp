// The walk over grid bodies (transform, tree topology, leaf buffers) that runs before OpenVDB reads
// a file: every layout OpenVDB's own writer makes of numeric grids passes it and reads back the
// same, and each damage to a grid body is named before OpenVDB copies a byte of it (OpenVDB 10
// copies a chunk marked uncompressed at its declared length into the leaf's buffer first: a heap
// overflow found by volume_read_fuzz, docs/hardening.md finding 9).
#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include "probebake/volume/volume_inspect.h"
#include "volume/test_volumes.h"

namespace probebake {
namespace {

namespace vdb = openvdb;
using testing::TempDir;

// Voxels (0, y, z) of a leaf with bit y * 8 + z set here are active: the leaf's first mask word,
// a pattern no other field of these files holds.
constexpr uint64_t kMaskWord = 0xF0E1D2C3B4A59687ull;
// A root tile far from the leaf, with a value no other field holds.
const vdb::Coord kTileKey(4096 * 3, 0, -4096);
constexpr float kTileValue = 1234.5f;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void WriteAt(const std::string& path, size_t at, const void* bytes, size_t n) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(std::streamoff(at));
  f.write(static_cast<const char*>(bytes), std::streamsize(n));
  ASSERT_TRUE(f.good());
}

template <typename T>
std::string Bytes(const T& value) {
  std::string s(sizeof(T), '\0');
  std::memcpy(s.data(), &value, sizeof(T));
  return s;
}

// A float grid of one leaf whose first mask word is kMaskWord, and one active root tile, written
// by OpenVDB with `compression` (io::COMPRESS_*).
std::string WriteOneLeafGrid(const TempDir& dir, const std::string& name, uint32_t compression) {
  vdb::FloatGrid::Ptr grid = vdb::FloatGrid::create(0.0f);
  grid->setName("density");
  for (int bit = 0; bit < 64; ++bit) {
    if ((kMaskWord >> bit) & 1)
      grid->tree().setValueOn(vdb::Coord(0, bit / 8, bit % 8), 0.5f + float(bit));
  }
  grid->tree().root().addTile(kTileKey, kTileValue, /*active=*/true);
  const std::string path = dir.File(name);
  vdb::io::File file(path);
  file.setCompression(compression);
  file.write({grid});
  return path;
}

struct LeafChunk {
  size_t topologyMask = 0;  // the leaf's mask in the topology
  size_t bufferMask = 0;    // and again before its values
  size_t chunk = 0;         // the values' chunk size (int64), after the metadata byte
};

LeafChunk FindLeaf(const std::string& path) {
  const std::string bytes = ReadAll(path);
  LeafChunk leaf;
  leaf.topologyMask = bytes.find(Bytes(kMaskWord));
  leaf.bufferMask = bytes.find(Bytes(kMaskWord), leaf.topologyMask + 1);
  EXPECT_NE(leaf.topologyMask, std::string::npos);
  EXPECT_NE(leaf.bufferMask, std::string::npos);
  EXPECT_EQ(bytes.find(Bytes(kMaskWord), leaf.bufferMask + 1), std::string::npos);
  leaf.chunk = leaf.bufferMask + 64 + 1;
  return leaf;
}

absl::Status Inspect(const std::string& path) {
  return InspectProbeVolume(path).status();
}

void ExpectProblem(const absl::Status& status, const std::string& phrase) {
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  EXPECT_NE(status.message().find(phrase), absl::string_view::npos) << status;
}

class VdbTreeWalk : public ::testing::Test {
 protected:
  void SetUp() override {
    vdb::initialize();
    ASSERT_TRUE(vdb::io::Archive::hasBloscCompression()) << "probebake writes Blosc volumes";
  }
  TempDir dir_;
};

// The overflow itself: a chunk marked uncompressed (negative size) longer than the leaf.
TEST_F(VdbTreeWalk, AnUncompressedChunkLongerThanTheLeafIsRefused) {
  const std::string path = WriteOneLeafGrid(dir_, "raw.vdb", vdb::io::COMPRESS_BLOSC);
  const LeafChunk leaf = FindLeaf(path);
  const int64_t declared = -4096;  // the leaf holds 512 floats, 2048 bytes
  WriteAt(path, leaf.chunk, &declared, sizeof(declared));
  ExpectProblem(Inspect(path),
                "grid \"density\" leaf 0's values declare an uncompressed chunk of 4096 bytes; "
                "the node holds 2048");
}

TEST_F(VdbTreeWalk, ABloscChunkDecompressingToAnotherSizeIsRefused) {
  const std::string path = WriteOneLeafGrid(dir_, "blosc.vdb", vdb::io::COMPRESS_BLOSC);
  const LeafChunk leaf = FindLeaf(path);
  const std::string bytes = ReadAll(path);
  int64_t declared = 0;
  std::memcpy(&declared, bytes.data() + leaf.chunk, sizeof(declared));
  ASSERT_GT(declared, 16) << "a compressed chunk";
  const uint32_t nbytes = 8192;
  WriteAt(path, leaf.chunk + 8 + 4, &nbytes, sizeof(nbytes));
  ExpectProblem(Inspect(path), "leaf 0's values' Blosc chunk decompresses to 8192 bytes");
  // The chunk's own length in its header must be the file's.
  const std::string again = WriteOneLeafGrid(dir_, "cbytes.vdb", vdb::io::COMPRESS_BLOSC);
  const uint32_t cbytes = uint32_t(declared) + 100;
  WriteAt(again, FindLeaf(again).chunk + 8 + 12, &cbytes, sizeof(cbytes));
  ExpectProblem(Inspect(again), "Blosc chunk says it takes " + std::to_string(cbytes) + " bytes");
}

TEST_F(VdbTreeWalk, AZipChunkPastTheGridIsRefused) {
  const std::string path = WriteOneLeafGrid(dir_, "zip.vdb", vdb::io::COMPRESS_ZIP);
  const int64_t declared = int64_t(1) << 40;
  WriteAt(path, FindLeaf(path).chunk, &declared, sizeof(declared));
  ExpectProblem(Inspect(path), "leaf 0's values declare a compressed chunk of 1099511627776 bytes");
}

TEST_F(VdbTreeWalk, ABufferMaskUnlikeTheTopologysIsRefused) {
  const std::string path = WriteOneLeafGrid(dir_, "mask.vdb", vdb::io::COMPRESS_BLOSC);
  const uint64_t other = kMaskWord ^ 1;
  WriteAt(path, FindLeaf(path).bufferMask, &other, sizeof(other));
  ExpectProblem(Inspect(path), "leaf 0's buffer mask differs from its topology mask");
}

TEST_F(VdbTreeWalk, RootTilesAndChildrenAreChecked) {
  const std::string good = WriteOneLeafGrid(dir_, "good.vdb", vdb::io::COMPRESS_BLOSC);
  const std::string bytes = ReadAll(good);
  // The tile: key (3 int32), value, active flag; the root's tile and child counts just before.
  const size_t tile = bytes.find(Bytes(kTileKey) + Bytes(kTileValue));
  ASSERT_NE(tile, std::string::npos);
  const auto damaged = [&](const std::string& name, size_t at, const std::string& with) {
    const std::string path = dir_.File(name);
    std::filesystem::copy_file(good, path);
    WriteAt(path, at, with.data(), with.size());
    return Inspect(path);
  };
  ExpectProblem(damaged("flag.vdb", tile + 16, std::string(1, '\x02')),
                "root tile 0's active flag holds 2, not 0 or 1");
  ExpectProblem(damaged("children.vdb", tile - 4, Bytes(uint32_t(0x7fffffff))),
                "root declares 2147483647 children");
  ExpectProblem(damaged("tiles.vdb", tile - 8, Bytes(uint32_t(0x10000000))),
                "root declares 268435456 tiles");
  ExpectProblem(damaged("unaligned.vdb", tile, Bytes(vdb::Coord(4096 * 3 + 8, 0, -4096))),
                "root tile 0's origin (12296, 0, -4096) is not a multiple of 4096");
  // The leaf's root child moved onto the tile's key.
  ExpectProblem(damaged("twice.vdb", tile + 17, Bytes(kTileKey)),
                "root child 0's origin (12288, 0, -4096) is used twice");
  // And the untouched file reads.
  EXPECT_TRUE(Inspect(good).ok());
}

TEST_F(VdbTreeWalk, OnlyLinearTransformsAndNumericTreesAreTaken) {
  vdb::FloatGrid::Ptr frustum = vdb::FloatGrid::create();
  frustum->setName("frustum");
  frustum->setTransform(vdb::math::Transform::createFrustumTransform(
      vdb::BBoxd(vdb::Vec3d(0), vdb::Vec3d(10)), 0.5, 2.0, 1.0));
  frustum->tree().setValueOn(vdb::Coord(1, 2, 3), 1.0f);
  const std::string frustumPath = dir_.File("frustum.vdb");
  vdb::io::File(frustumPath).write({frustum});
  ExpectProblem(Inspect(frustumPath),
                "grid \"frustum\"'s transform is a \"NonlinearFrustumMap\", which this reader does "
                "not take");

  vdb::BoolGrid::Ptr flags = vdb::BoolGrid::create();
  flags->setName("flags");
  flags->tree().setValueOn(vdb::Coord(1, 2, 3), true);
  const std::string boolPath = dir_.File("bool.vdb");
  vdb::io::File(boolPath).write({flags});
  ExpectProblem(Inspect(boolPath), "grid \"flags\" has type \"Tree_bool_5_4_3\"");
}

// A tree with every kind of node content OpenVDB's writer distinguishes: leaves whose inactive
// voxels hold no other value, one, two or many (each a different compression metadata), an active
// tile in a lower and in an upper internal node, and an active root tile.
template <typename GridT>
typename GridT::Ptr RichGrid(bool half) {
  using ValueT = typename GridT::ValueType;
  const auto v = [](double x) { return ValueT(vdb::zeroVal<ValueT>() + x); };
  typename GridT::Ptr grid = GridT::create(v(0));
  grid->setName("rich");
  grid->setSaveFloatAsHalf(half);
  auto& tree = grid->tree();
  for (int leaf = 0; leaf < 5; ++leaf) {
    const int x0 = leaf * 8;
    for (int i = 0; i < 512; ++i) {
      const vdb::Coord xyz(x0 + i / 64, (i / 8) % 8, i % 8);
      if (i % 3 == 0) {
        tree.setValueOn(xyz, v(1 + i % 7));
        continue;
      }
      // Inactive voxels: all background, one other value, background and one other, two others,
      // many.
      const double inactive[5] = {0, 5, i % 2 ? 5.0 : 0.0, i % 2 ? 5.0 : 6.0, double(i % 9)};
      tree.setValueOff(xyz, v(inactive[leaf]));
    }
  }
  tree.addTile(/*level=*/1, vdb::Coord(512, 0, 0), v(2), /*active=*/true);
  tree.addTile(/*level=*/2, vdb::Coord(0, 1024, 0), v(3), /*active=*/true);
  tree.addTile(/*level=*/3, vdb::Coord(-4096, 0, 0), v(4), /*active=*/true);
  return grid;
}

template <typename GridT>
void ExpectEveryLayoutReads(const TempDir& dir, const std::string& type) {
  const uint32_t compressions[] = {vdb::io::COMPRESS_NONE,
                                   vdb::io::COMPRESS_ZIP,
                                   vdb::io::COMPRESS_BLOSC,
                                   vdb::io::COMPRESS_ACTIVE_MASK,
                                   vdb::io::COMPRESS_ZIP | vdb::io::COMPRESS_ACTIVE_MASK,
                                   vdb::io::COMPRESS_BLOSC | vdb::io::COMPRESS_ACTIVE_MASK};
  for (const uint32_t compression : compressions) {
    for (const bool half : {false, true}) {
      const auto grid = RichGrid<GridT>(half);
      const std::string path =
          dir.File(type + "_" + std::to_string(compression) + (half ? "_half" : "") + ".vdb");
      vdb::io::File file(path);
      file.setCompression(compression);
      file.write({grid});
      SCOPED_TRACE(path);
      const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path);
      ASSERT_TRUE(report.ok()) << report.status();
      ASSERT_EQ(report->grids.size(), 1u);
      EXPECT_EQ(report->grids[0].activeVoxels, int64_t(grid->activeVoxelCount()));
    }
  }
}

TEST_F(VdbTreeWalk, EveryLayoutOpenVdbWritesOfNumericGridsReads) {
  ExpectEveryLayoutReads<vdb::FloatGrid>(dir_, "float");
  ExpectEveryLayoutReads<vdb::DoubleGrid>(dir_, "double");
  ExpectEveryLayoutReads<vdb::Int32Grid>(dir_, "int32");
  ExpectEveryLayoutReads<vdb::Int64Grid>(dir_, "int64");
  ExpectEveryLayoutReads<vdb::Vec3SGrid>(dir_, "vec3s");
  ExpectEveryLayoutReads<vdb::Vec3DGrid>(dir_, "vec3d");
  ExpectEveryLayoutReads<vdb::Vec3IGrid>(dir_, "vec3i");
}

}  // namespace
}  // namespace probebake
