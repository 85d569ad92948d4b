// Write -> read round trips of the probe volume file (docs/volume-format.md), bit for bit, and the
// writer's and reader's error paths that need no hand-made OpenVDB file.
#include "probebake/volume/vdb_io.h"
#include "probebake/volume/visibility_map.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <ostream>
#include <thread>

#include "probebake/base/version.h"
#include "volume/test_volumes.h"

namespace probebake {
namespace {

using testing::MakeTestMetadata;
using testing::MakeTestVolume;
using testing::TempDir;
using testing::TestVolumeSpec;

uint32_t Bits(float x) {
  uint32_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

// Every float equal bit for bit; reports the first difference.
void ExpectSameBits(const std::vector<float>& expected, const std::vector<float>& got,
                    const std::string& what) {
  ASSERT_EQ(expected.size(), got.size()) << what;
  for (size_t i = 0; i < expected.size(); ++i) {
    ASSERT_EQ(Bits(expected[i]), Bits(got[i]))
        << what << "[" << i << "]: expected " << expected[i] << ", got " << got[i];
  }
}

void ExpectSameVolume(const ProbeVolume& expected, const ProbeVolume& got) {
  EXPECT_EQ(expected.grid.origin, got.grid.origin);
  EXPECT_EQ(expected.grid.spacing, got.grid.spacing);
  for (int a = 0; a < 3; ++a) EXPECT_EQ(expected.grid.counts[a], got.grid.counts[a]) << a;
  EXPECT_EQ(expected.grid.placement, got.grid.placement);
  EXPECT_EQ(expected.grid.surfaceDistance, got.grid.surfaceDistance);
  EXPECT_EQ(expected.shOrder, got.shOrder);
  EXPECT_EQ(expected.active, got.active);
  ASSERT_EQ(expected.radiance.size(), got.radiance.size());
  for (size_t c = 0; c < expected.radiance.size(); ++c) {
    ExpectSameBits(expected.radiance[c], got.radiance[c], "radiance[" + std::to_string(c) + "]");
  }
  ASSERT_EQ(expected.irradiance.size(), got.irradiance.size());
  for (size_t c = 0; c < expected.irradiance.size(); ++c) {
    ExpectSameBits(expected.irradiance[c], got.irradiance[c],
                   "irradiance[" + std::to_string(c) + "]");
  }
  ExpectSameBits(expected.validity, got.validity, "validity");
  ExpectSameBits(expected.stdError, got.stdError, "stdError");
  ExpectSameBits(expected.stdErrorL0, got.stdErrorL0, "stdErrorL0");
  ExpectSameBits(expected.sampleCount, got.sampleCount, "sampleCount");
  ExpectSameBits(expected.offset, got.offset, "offset");
  ExpectSameBits(expected.filled, got.filled, "filled");
  ASSERT_EQ(expected.visibility.size(), got.visibility.size());
  for (size_t t = 0; t < expected.visibility.size(); ++t)
    ExpectSameBits(expected.visibility[t], got.visibility[t],
                   "visibility[" + std::to_string(t) + "]");
  EXPECT_EQ(expected.window, got.window);
  EXPECT_EQ(expected.stats.wallSeconds, got.stats.wallSeconds);
  EXPECT_EQ(expected.stats.threads, got.stats.threads);
  EXPECT_EQ(expected.stats.probes, got.stats.probes);
  EXPECT_EQ(expected.stats.samples, got.stats.samples);
  EXPECT_EQ(expected.stats.rays, got.stats.rays);
  EXPECT_EQ(expected.stats.invalidProbes, got.stats.invalidProbes);
}

void ExpectSameMetadata(const VolumeMetadata& expected, const VolumeMetadata& got) {
  EXPECT_EQ(expected.samplesPerProbe, got.samplesPerProbe);
  EXPECT_EQ(expected.maxDepth, got.maxDepth);
  EXPECT_EQ(expected.seed, got.seed);
  EXPECT_EQ(expected.sceneDigest, got.sceneDigest);
  EXPECT_EQ(expected.settingsJson, got.settingsJson);
}

struct RoundTripCase {
  const char* name;
  int counts[3];
  int order;
  bool irradiance;
  int inactiveEvery;
};

std::ostream& operator<<(std::ostream& os, const RoundTripCase& c) {
  return os << c.name;
}

class RoundTrip : public ::testing::TestWithParam<RoundTripCase> {};

TEST_P(RoundTrip, ReadsBackBitIdentical) {
  const RoundTripCase& c = GetParam();
  TestVolumeSpec spec;
  for (int a = 0; a < 3; ++a) spec.counts[a] = c.counts[a];
  spec.shOrder = c.order;
  spec.irradiance = c.irradiance;
  spec.inactiveEvery = c.inactiveEvery;
  const ProbeVolume volume = MakeTestVolume(spec);
  const VolumeMetadata meta = MakeTestMetadata();
  TempDir dir;
  const std::string path = dir.File("volume.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, volume, meta));

  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameVolume(volume, read->volume);
  ExpectSameMetadata(meta, read->meta);
  EXPECT_EQ(dir.List(), std::vector<std::string>{"volume.vdb"});
}

INSTANTIATE_TEST_SUITE_P(
    Volumes, RoundTrip,
    ::testing::Values(RoundTripCase{"L2", {3, 4, 5}, 2, false, 7},
                      RoundTripCase{"L2Irradiance", {3, 4, 5}, 2, true, 7},
                      RoundTripCase{"L8", {3, 4, 5}, 8, false, 7},
                      RoundTripCase{"L8Irradiance", {3, 4, 5}, 8, true, 7},
                      RoundTripCase{"L9SingleProbe", {1, 1, 1}, 9, true, 0},
                      RoundTripCase{"L0SeveralLeaves", {17, 9, 10}, 0, false, 3},
                      RoundTripCase{"L1EveryProbeInactive", {2, 3, 2}, 1, false, 1}),
    [](const ::testing::TestParamInfo<RoundTripCase>& param) { return param.param.name; });

// Format 4's optional grids: relocation offsets, dilation flags and the 64 visibility planes.
TEST(VdbIo, OffsetsFilledFlagsAndVisibilityReadBackBitIdentical) {
  TestVolumeSpec spec;
  ProbeVolume volume = MakeTestVolume(spec);
  const size_t probes = volume.active.size();
  volume.offset.assign(3 * probes, 0.0f);
  volume.filled.assign(probes, 0.0f);
  volume.visibility.assign(kVisibilityTexels, std::vector<float>(3 * probes, 0.0f));
  for (size_t p = 0; p < probes; ++p) {
    if (!volume.active[p]) continue;
    for (int ch = 0; ch < 3; ++ch) volume.offset[3 * p + ch] = 0.01f * float(p) - 0.1f * float(ch);
    volume.filled[p] = float(p % 3 == 0);
    for (int t = 0; t < kVisibilityTexels; ++t) {
      volume.visibility[t][3 * p] = 0.5f + 0.001f * float(t + int(p));
      volume.visibility[t][3 * p + 1] = 0.3f + 0.002f * float(t);
      volume.visibility[t][3 * p + 2] = float(t % 5);
    }
  }
  TempDir dir;
  const std::string path = dir.File("volume.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, volume, MakeTestMetadata()));
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->format, kProbeVolumeFormat);
  EXPECT_EQ(read->rawMetadata.at("visibility_size"), "8");
  EXPECT_EQ(read->rawMetadata.at("has_offset"), "true");
  ExpectSameVolume(volume, read->volume);

  // Without them: no such grids, and the metadata says so.
  ProbeVolume plain = MakeTestVolume(spec);
  PB_ASSERT_OK(WriteProbeVolume(path, plain, MakeTestMetadata()));
  const absl::StatusOr<ProbeVolumeFile> again = ReadProbeVolume(path);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(again->rawMetadata.at("visibility_size"), "0");
  EXPECT_TRUE(again->volume.offset.empty());
  EXPECT_TRUE(again->volume.visibility.empty());
}

// Spacings such as 2/3 = (2 - 0) / (4 - 1) and origins far from 0 read back: the file's
// grid_min and grid_spacing are authoritative and restore the written doubles exactly, the
// transform only has to agree with them (vdb_layout_test checks the transform itself).
class AwkwardSpacing : public ::testing::TestWithParam<testing::AwkwardGrid> {};

TEST_P(AwkwardSpacing, ReadsBackTheExactOriginAndSpacing) {
  const testing::AwkwardGrid& g = GetParam();
  TestVolumeSpec spec;
  spec.origin = g.origin;
  spec.spacing = g.spacing;
  for (int a = 0; a < 3; ++a) spec.counts[a] = g.counts[a];
  spec.shOrder = 0;
  const ProbeVolume volume = MakeTestVolume(spec);
  TempDir dir;
  const std::string path = dir.File("awkward.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, volume, MakeTestMetadata()));
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameVolume(volume, read->volume);
}

INSTANTIATE_TEST_SUITE_P(Grids, AwkwardSpacing, ::testing::ValuesIn(testing::AwkwardGrids()),
                         [](const ::testing::TestParamInfo<testing::AwkwardGrid>& param) {
                           return param.param.name;
                         });

TEST(VdbIo, RawMetadataHoldsEveryKeyAsText) {
  TestVolumeSpec spec;
  spec.irradiance = true;
  const ProbeVolume volume = MakeTestVolume(spec);
  const VolumeMetadata meta = MakeTestMetadata();
  TempDir dir;
  const std::string path = dir.File("v.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, volume, meta));
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  const std::map<std::string, std::string> expected = {
      {"probebake_format", "4"},
      {"has_offset", "false"},
      {"has_filled", "false"},
      {"visibility_size", "0"},
      {"visibility_max_distance", "0"},
      {"sh_order", "2"},
      {"sh_basis", "real-orthonormal-condon-shortley-zpolar"},
      {"sh_window", "HANNING"},
      {"quantity", "radiance"},
      {"has_irradiance", "true"},
      {"color_space", "linear-rec709"},
      {"samples_per_probe", "8589934592"},
      {"max_depth", "8"},
      {"seed", "-5"},  // 2^64 - 5 stored as int64 bits
      {"scene_digest", meta.sceneDigest},
      {"settings", meta.settingsJson},
      {"generator", std::string(kGeneratorName) + " " + kVersion},
      {"grid_counts", "(3, 4, 5)"},
      {"grid_min", "(-3.5, -1, -10.25)"},
      {"grid_spacing", "(0.5, 1.25, 2)"},
      {"grid_placement", "NEAR_SURFACES"},
      {"grid_surface_distance", "0.375"},
  };
  for (const auto& [key, value] : expected) {
    const auto it = read->rawMetadata.find(key);
    ASSERT_NE(it, read->rawMetadata.end()) << key;
    EXPECT_EQ(it->second, value) << key;
  }
  // Compact, keys in ascending order, integers as integer literals, wallSeconds with the 17
  // significant digits it needs to read back (vdb_io.h).
  const std::string expectedStats =
      "{\"invalidProbes\":" + std::to_string(volume.stats.invalidProbes) +
      ",\"probes\":" + std::to_string(volume.stats.probes) + ",\"rays\":1099511627776" +
      ",\"samples\":" + std::to_string(volume.stats.samples) +
      ",\"threads\":2,\"wallSeconds\":12.345678901234567}";
  EXPECT_EQ(read->rawMetadata.at("stats"), expectedStats);
  // Nothing ignored: no `ignored` key (volumes of jobs without file extensions are unchanged).
  EXPECT_EQ(read->rawMetadata.count("ignored"), 0u);
  EXPECT_EQ(read->meta.ignored, "");
}

TEST(VdbIo, WhatTheBakeIgnoredIsRecorded) {
  const ProbeVolume volume = MakeTestVolume(TestVolumeSpec{});
  VolumeMetadata meta = MakeTestMetadata();
  meta.ignored = "scene.meshes[0]: KHR_materials_clearcoat\nscene.meshes[2]: KHR_materials_sheen";
  TempDir dir;
  const std::string path = dir.File("v.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, volume, meta));
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->meta.ignored, meta.ignored);
  EXPECT_EQ(read->rawMetadata.at("ignored"), meta.ignored);
}

// Counts up to 2^53 - 1 and wallSeconds read back exactly, whatever form protobuf prints them in
// (1e15 prints as "1e+15").
TEST(VdbIo, StatsRoundTripUpTo2To53) {
  const int64_t kLargest = (int64_t(1) << 53) - 1;
  struct Case {
    double wallSeconds;
    int threads;
    int64_t probes, samples, rays, invalidProbes;
  };
  const Case cases[] = {
      {0.0, 0, 0, 0, 0, 0},
      {0.1, 1, 1, 1, 1, 0},
      {1.0 / 3.0, 64, 123456789, 1000000000000000, kLargest, 7},
      {1e-300, 2147483647, kLargest, 999999999999999, 1000000000000001, -1},
      {86400.5, 2, 1, -kLargest, int64_t(1) << 52, kLargest},
  };
  TempDir dir;
  int index = 0;
  for (const Case& c : cases) {
    SCOPED_TRACE(index);
    ProbeVolume volume = MakeTestVolume(TestVolumeSpec{});
    volume.stats = {c.wallSeconds, c.threads, c.probes, c.samples, c.rays, c.invalidProbes};
    const std::string path = dir.File(std::to_string(index++) + ".vdb");
    PB_ASSERT_OK(WriteProbeVolume(path, volume, MakeTestMetadata()));
    const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
    ASSERT_TRUE(read.ok()) << read.status();
    const BakeStats& got = read->volume.stats;
    EXPECT_EQ(got.wallSeconds, c.wallSeconds);
    EXPECT_EQ(got.threads, c.threads);
    EXPECT_EQ(got.probes, c.probes);
    EXPECT_EQ(got.samples, c.samples);
    EXPECT_EQ(got.rays, c.rays);
    EXPECT_EQ(got.invalidProbes, c.invalidProbes);
  }
}

// The tracer's optional per-coefficient standard errors and AUTO window t, filled as it does.
void FillTracerExtras(ProbeVolume* v) {
  const size_t probes = size_t(v->grid.ProbeCount());
  v->radianceStdError.assign(size_t(v->CoeffCount()), std::vector<float>(3 * probes, 0.25f));
  v->autoWindowT.assign(probes, 0.125f);
}

TEST(VdbIo, RvalueOverloadWritesTheSameAndReleasesPlanes) {
  TestVolumeSpec spec;
  spec.irradiance = true;
  const ProbeVolume volume = MakeTestVolume(spec);
  ProbeVolume consumed = volume;
  FillTracerExtras(&consumed);
  TempDir dir;
  const std::string path = dir.File("moved.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, std::move(consumed), MakeTestMetadata()));
  EXPECT_TRUE(consumed.radiance.empty());
  EXPECT_TRUE(consumed.irradiance.empty());
  EXPECT_TRUE(consumed.validity.empty());
  EXPECT_TRUE(consumed.stdError.empty());
  EXPECT_TRUE(consumed.stdErrorL0.empty());
  EXPECT_TRUE(consumed.sampleCount.empty());
  EXPECT_TRUE(consumed.radianceStdError.empty()) << consumed.radianceStdError.size();
  EXPECT_TRUE(consumed.autoWindowT.empty()) << consumed.autoWindowT.size();
  EXPECT_EQ(consumed.radianceStdError.capacity(), 0u);
  EXPECT_EQ(consumed.autoWindowT.capacity(), 0u);
  EXPECT_EQ(consumed.active, volume.active);  // kept
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectSameVolume(volume, read->volume);
}

TEST(VdbIo, RvalueOverloadReleasesEvenWhenTheVolumeIsRejected) {
  ProbeVolume consumed = MakeTestVolume(TestVolumeSpec{});
  FillTracerExtras(&consumed);
  consumed.grid.spacing.x = 0;
  TempDir dir;
  const absl::Status status =
      WriteProbeVolume(dir.File("bad.vdb"), std::move(consumed), MakeTestMetadata());
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  EXPECT_TRUE(consumed.radiance.empty());
  EXPECT_TRUE(consumed.radianceStdError.empty());
  EXPECT_TRUE(consumed.autoWindowT.empty());
}

// radianceStdError and autoWindowT are not part of the file: a read gives them empty.
TEST(VdbIo, TracerExtrasAreNotWritten) {
  ProbeVolume volume = MakeTestVolume(TestVolumeSpec{});
  FillTracerExtras(&volume);
  TempDir dir;
  const std::string path = dir.File("extras.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, volume, MakeTestMetadata()));
  EXPECT_FALSE(volume.radianceStdError.empty());  // the const overload keeps them
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_TRUE(read->volume.radianceStdError.empty());
  EXPECT_TRUE(read->volume.autoWindowT.empty());
  ExpectSameVolume(volume, read->volume);
}

// Writing streams grid by grid: the extra memory is about one grid, not a copy of the volume.
// A dense 64^3 L2 volume holds 30 MiB; one coefficient grid ~3.5 MiB (leaf buffers of 12-byte
// voxels plus masks); OpenVDB's first use, blosc and stream buffers add a few MiB (8 MiB measured
// in all). A writer holding every grid at once would add >= 30 MiB: the bound, half the volume,
// separates the two.
TEST(VdbIo, WritingAddsAboutOneGridOfMemoryNotACopy) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "AddressSanitizer keeps freed memory in quarantine: RSS says nothing here";
#endif
  TestVolumeSpec spec;
  spec.counts[0] = spec.counts[1] = spec.counts[2] = 64;
  spec.inactiveEvery = spec.invalidEvery = 0;
  spec.awkwardValues = false;
  const ProbeVolume volume = MakeTestVolume(spec);
  size_t volumeBytes = 0;
  for (const auto& plane : volume.radiance) volumeBytes += 4 * plane.size();
  volumeBytes += 4 * (volume.validity.size() + volume.stdError.size() + volume.stdErrorL0.size() +
                      volume.sampleCount.size());
  TempDir dir;
  for (const bool consume : {false, true}) {
    SCOPED_TRACE(consume ? "rvalue overload" : "const overload");
    ProbeVolume copy = consume ? volume : ProbeVolume{};
    if (!testing::ResetPeakRss()) GTEST_SKIP() << "/proc/self/clear_refs is not writable";
    const int64_t before = testing::CurrentRssBytes();
    const absl::Status status =
        consume ? WriteProbeVolume(dir.File("consumed.vdb"), std::move(copy), MakeTestMetadata())
                : WriteProbeVolume(dir.File("kept.vdb"), volume, MakeTestMetadata());
    ASSERT_TRUE(status.ok()) << status;
    const int64_t extra = testing::PeakRssBytes() - before;
    EXPECT_LT(extra, int64_t(volumeBytes / 2))
        << "peak RSS grew by " << extra / 1048576.0 << " MiB while writing a "
        << volumeBytes / 1048576.0 << " MiB volume";
  }
}

TEST(VdbIo, InconsistentVolumeIsRejectedAndNothingWritten) {
  TempDir dir;
  const std::string path = dir.File("bad.vdb");
  struct Case {
    const char* field;
    void (*breakIt)(ProbeVolume*);
  };
  const Case cases[] = {
      {"volume.radiance[3]", [](ProbeVolume* v) { v->radiance[3].pop_back(); }},
      {"volume.radiance", [](ProbeVolume* v) { v->radiance.pop_back(); }},
      {"volume.irradiance", [](ProbeVolume* v) { v->irradiance.assign(2, {}); }},
      {"volume.active", [](ProbeVolume* v) { v->active.push_back(1); }},
      {"volume.validity", [](ProbeVolume* v) { v->validity.clear(); }},
      {"volume.sampleCount", [](ProbeVolume* v) { v->sampleCount.resize(2); }},
      {"volume.shOrder", [](ProbeVolume* v) { v->shOrder = 10; }},
      {"volume.grid.spacing[1]", [](ProbeVolume* v) { v->grid.spacing.y = 0; }},
      {"volume.grid.counts[2]", [](ProbeVolume* v) { v->grid.counts[2] = 0; }},
      // The stats JSON holds doubles: a NaN has no JSON form, 2^53 would not read back exactly.
      {"volume.stats.wallSeconds",
       [](ProbeVolume* v) { v->stats.wallSeconds = std::numeric_limits<double>::quiet_NaN(); }},
      {"volume.stats.rays", [](ProbeVolume* v) { v->stats.rays = int64_t(1) << 53; }},
      {"volume.stats.samples", [](ProbeVolume* v) { v->stats.samples = INT64_MIN; }},
  };
  for (const Case& c : cases) {
    ProbeVolume volume = MakeTestVolume(TestVolumeSpec{});
    c.breakIt(&volume);
    const absl::Status status = WriteProbeVolume(path, volume, VolumeMetadata{});
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << c.field << ": " << status;
    EXPECT_NE(std::string(status.message()).find(c.field), std::string::npos)
        << "expected the message to name " << c.field << ", got: " << status;
    EXPECT_TRUE(dir.List().empty()) << c.field;
  }
}

TEST(VdbIo, ReadingAMissingFileIsNotFoundNamingThePath) {
  TempDir dir;
  const std::string path = dir.File("absent.vdb");
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  EXPECT_EQ(read.status().code(), absl::StatusCode::kNotFound) << read.status();
  EXPECT_NE(std::string(read.status().message()).find(path), std::string::npos) << read.status();
}

TEST(VdbIo, ReadingANonVdbFileIsAnErrorNamingThePath) {
  TempDir dir;
  const std::string path = dir.File("text.vdb");
  std::ofstream(path) << "not an OpenVDB file\n";
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  EXPECT_EQ(read.status().code(), absl::StatusCode::kInvalidArgument) << read.status();
  EXPECT_NE(std::string(read.status().message()).find(path), std::string::npos) << read.status();
}

// The server writes volumes of several jobs at once: concurrent writers to distinct paths (and
// the first OpenVDB initialisation racing between them) give the same files as serial ones.
TEST(VdbIo, ConcurrentWritersToDistinctPaths) {
  constexpr int kWriters = 6;
  std::vector<ProbeVolume> volumes;
  for (int w = 0; w < kWriters; ++w) {
    TestVolumeSpec spec;
    spec.seed = uint64_t(100 + w);
    spec.shOrder = w % 3;
    spec.irradiance = w % 2 == 1;
    volumes.push_back(MakeTestVolume(spec));
  }
  TempDir dir;
  std::vector<absl::Status> statuses(kWriters);
  std::vector<std::thread> threads;
  for (int w = 0; w < kWriters; ++w) {
    threads.emplace_back([&, w] {
      statuses[size_t(w)] = WriteProbeVolume(dir.File(std::to_string(w) + ".vdb"),
                                             volumes[size_t(w)], MakeTestMetadata());
    });
  }
  for (std::thread& t : threads) t.join();
  for (int w = 0; w < kWriters; ++w) {
    ASSERT_TRUE(statuses[size_t(w)].ok()) << statuses[size_t(w)];
    const absl::StatusOr<ProbeVolumeFile> read =
        ReadProbeVolume(dir.File(std::to_string(w) + ".vdb"));
    ASSERT_TRUE(read.ok()) << read.status();
    ExpectSameVolume(volumes[size_t(w)], read->volume);
  }
  EXPECT_EQ(dir.List().size(), size_t(kWriters));
}

TEST(VdbIo, GridNames) {
  EXPECT_EQ(RadianceGridName(0), "radiance_sh_00");
  EXPECT_EQ(RadianceGridName(8), "radiance_sh_08");
  EXPECT_EQ(RadianceGridName(80), "radiance_sh_80");
  EXPECT_EQ(IrradianceGridName(99), "irradiance_sh_99");
}

}  // namespace
}  // namespace probebake

namespace probebake {
namespace {

// The file with the 4 bytes at `at` replaced by `value` (little-endian).
void Patch(const std::string& path, size_t at, uint32_t value) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(std::streamoff(at));
  const unsigned char bytes[4] = {uint8_t(value), uint8_t(value >> 8), uint8_t(value >> 16),
                                  uint8_t(value >> 24)};
  f.write(reinterpret_cast<const char*>(bytes), 4);
}

// The offset of the first length-prefixed string `s` in the file (its length field).
size_t FindString(const std::string& path, const std::string& s) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string needle(4, '\0');
  for (int i = 0; i < 4; ++i) needle[size_t(i)] = char(uint8_t(s.size() >> (8 * i)));
  const size_t at = bytes.find(needle + s);
  EXPECT_NE(at, std::string::npos) << s;
  return at;
}

// OpenVDB sizes strings by the lengths a file declares and fills them before reading: a damaged
// length must be refused by the walk before OpenVDB sees it (found by volume_read_fuzz: minutes
// spent zeroing gigabytes for a 100 kB file). Each damage is named, and fast.
TEST(VdbIo, DeclaredLengthsPastTheFileAreRefusedBeforeOpenVdbReadsThem) {
  TempDir dir;
  const std::string good = dir.File("good.vdb");
  PB_ASSERT_OK(WriteProbeVolume(good, MakeTestVolume(TestVolumeSpec{}), MakeTestMetadata()));
  const auto damaged = [&](const std::string& name, size_t at, uint32_t value) {
    const std::string path = dir.File(name);
    std::filesystem::copy_file(good, path);
    Patch(path, at, value);
    return ReadProbeVolume(path).status();
  };
  // Header: magic 8, versions 12, offsets flag 1, UUID 36; then the metadata count and the first
  // entry's name length.
  constexpr size_t kMetaCount = 8 + 12 + 1 + 36;
  const absl::Status count = damaged("count.vdb", kMetaCount, 0x7fffffff);
  EXPECT_EQ(count.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(count.message().find("file metadata declares 2147483647 entries"),
            absl::string_view::npos)
      << count;
  const absl::Status name = damaged("name.vdb", kMetaCount + 4, 0xfffffff0);
  EXPECT_NE(name.message().find("file metadata entry 0's name declares 4294967280 bytes"),
            absl::string_view::npos)
      << name;
  // The validity grid's descriptor: its type string follows its name.
  const size_t validity = FindString(good, "validity");
  const absl::Status type = damaged("type.vdb", validity + 4 + 8, 0x40000000);
  EXPECT_NE(type.message().find("grid \"validity\"'s type declares 1073741824 bytes"),
            absl::string_view::npos)
      << type;
  EXPECT_NE(type.message().find(dir.File("type.vdb")), absl::string_view::npos) << type;
  // A fixed-size value declaring another size: OpenVDB reads sizeof(T) and would part from the
  // walk, reading what follows as lengths.
  const size_t gridMin = FindString(good, "grid_min");
  const absl::Status vec = damaged("vec.vdb", gridMin + 4 + 8 + 4 + 5, 13592);
  EXPECT_NE(vec.message().find("file metadata \"grid_min\" (vec3d) declares 13592 bytes, not 24"),
            absl::string_view::npos)
      << vec;
  // A bool holding neither 0 nor 1: OpenVDB loads it as a bool (undefined behaviour; found by
  // volume_read_fuzz under UBSan).
  const size_t local = FindString(good, "is_saved_as_half_float");
  const std::string boolPath = dir.File("bool.vdb");
  std::filesystem::copy_file(good, boolPath);
  {
    std::fstream f(boolPath, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(local + 4 + 22 + 4 + 4 + 4));
    f.put(char(44));
  }
  const absl::Status flag = ReadProbeVolume(boolPath).status();
  EXPECT_NE(flag.message().find("\"is_saved_as_half_float\" (bool) holds 44, not 0 or 1"),
            absl::string_view::npos)
      << flag;
  // And the untouched file still reads.
  EXPECT_TRUE(ReadProbeVolume(good).ok());
}

}  // namespace
}  // namespace probebake
