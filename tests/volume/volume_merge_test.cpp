// Merging the volumes of a sharded bake (volume_merge.h): sub-grids baked on their own and merged
// give the volume of the whole grid, bit for bit; parts that do not belong together are refused
// with the field named.
#include "probebake/volume/volume_merge.h"

#include <gtest/gtest.h>

#include <cstring>

#include "probebake/bake/bake.h"
#include "tests/bake/bake_test_util.h"
#include "tests/volume/test_volumes.h"

namespace probebake {
namespace {

using testing::TempDir;

// A floor, a box and a rect light under a sky; a 4x3x3 grid with a non-binary spacing.
BakeJob WholeJob() {
  BakeJob job = testing::MakeJob(2, 128, {-0.8, -0.8, 0.3});
  job.grid.counts[0] = 4;
  job.grid.counts[1] = 3;
  job.grid.counts[2] = 3;
  job.grid.spacing = {0.8, 0.8, 0.8};
  job.grid.placement = Placement::kOutsideGeometry;
  job.settings.batches = 8;
  job.settings.seed = 11;
  job.settings.irradiance = true;
  job.scene.environment = {Environment::Kind::kUniform, {0.3, 0.4, 0.6}, nullptr};
  const uint32_t white = testing::AddMaterial(&job.scene, {0.7, 0.7, 0.7});
  testing::AddQuad(&job.scene, {-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}, white);
  // A box around one probe, so placement leaves it out of every grid that holds it.
  testing::AddBox(&job.scene, {-0.1, -0.1, 0.2}, {0.1, 0.1, 0.4}, white, false);
  job.scene.lights.push_back(RectLight{{-0.5, -0.5, 2}, {0, 1, 0}, {1, 0, 0}, {5, 5, 5}, false});
  return job;
}

// Bakes `job` over the sub-grid (min, counts) and writes it to `path`.
void BakePart(BakeJob job, const Vec3d& min, std::array<int, 3> counts, const std::string& path) {
  job.grid.origin = min;
  std::copy(counts.begin(), counts.end(), job.grid.counts);
  const ProbeVolume v = testing::BakeOrDie(job, 1);
  PB_ASSERT_OK(WriteProbeVolume(path, v, VolumeMetadataFor(job)));
}

std::vector<VolumePart> ReadParts(const std::vector<std::string>& paths) {
  std::vector<VolumePart> parts;
  for (const std::string& path : paths) {
    absl::StatusOr<ProbeVolumeFile> f = ReadProbeVolume(path);
    EXPECT_TRUE(f.ok()) << f.status();
    if (f.ok()) parts.push_back({path, std::move(*f)});
  }
  return parts;
}

void ExpectSamePlane(const std::vector<float>& a, const std::vector<float>& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(float))) << what;
}

TEST(VolumeMerge, ShardsMergeIntoTheWholeGridBitForBit) {
  const BakeJob whole = WholeJob();
  const ProbeVolume all = testing::BakeOrDie(whole, 2);
  ASSERT_LT(std::count(all.active.begin(), all.active.end(), 1), 36) << "no probe left out";
  TempDir dir;
  // Listed out of order; the mins typed in decimal (1.6 and 1.9 are not -0.8 + 0.8 * 3 and
  // 0.3 + 0.8 * 2 in double).
  BakePart(whole, {1.6, -0.8, 0.3}, {1, 3, 3}, dir.File("b.vdb"));
  BakePart(whole, {-0.8, -0.8, 1.9}, {3, 3, 1}, dir.File("c.vdb"));
  BakePart(whole, {-0.8, -0.8, 0.3}, {3, 3, 2}, dir.File("a.vdb"));
  absl::StatusOr<ProbeVolumeFile> merged =
      MergeProbeVolumes(ReadParts({dir.File("b.vdb"), dir.File("c.vdb"), dir.File("a.vdb")}));
  ASSERT_TRUE(merged.ok()) << merged.status();
  const ProbeVolume& m = merged->volume;
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(m.grid.origin[a], all.grid.origin[a]);
    EXPECT_EQ(m.grid.spacing[a], all.grid.spacing[a]);
    EXPECT_EQ(m.grid.counts[a], all.grid.counts[a]);
  }
  EXPECT_EQ(m.active, all.active);
  for (int c = 0; c < all.CoeffCount(); ++c) {
    ExpectSamePlane(m.radiance[c], all.radiance[c], "radiance");
    ExpectSamePlane(m.irradiance[c], all.irradiance[c], "irradiance");
  }
  ExpectSamePlane(m.validity, all.validity, "validity");
  ExpectSamePlane(m.stdError, all.stdError, "std_error");
  ExpectSamePlane(m.stdErrorL0, all.stdErrorL0, "std_error_l0");
  ExpectSamePlane(m.sampleCount, all.sampleCount, "sample_count");
  EXPECT_EQ(m.stats.probes, all.stats.probes);
  EXPECT_EQ(m.stats.samples, all.stats.samples);
  EXPECT_EQ(merged->meta.seed, whole.settings.seed);

  // A part overlapping the others (its row of probes baked twice) and a part given twice leave
  // the same volume; its probe count is still the volume's, the samples are the work done.
  BakePart(whole, {-0.8, -0.8, 1.9}, {4, 3, 1}, dir.File("d.vdb"));
  absl::StatusOr<ProbeVolumeFile> overlapping =
      MergeProbeVolumes(ReadParts({dir.File("a.vdb"), dir.File("b.vdb"), dir.File("c.vdb"),
                                   dir.File("d.vdb"), dir.File("d.vdb")}));
  ASSERT_TRUE(overlapping.ok()) << overlapping.status();
  EXPECT_EQ(overlapping->volume.active, all.active);
  EXPECT_EQ(overlapping->volume.stats.probes, all.stats.probes);
  EXPECT_EQ(overlapping->volume.stats.invalidProbes, all.stats.invalidProbes);
  EXPECT_GT(overlapping->volume.stats.samples, all.stats.samples);

  // And through a file: what `probebake merge` writes reads back as the same volume.
  PB_ASSERT_OK(WriteProbeVolume(dir.File("merged.vdb"), m, merged->meta));
  const absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(dir.File("merged.vdb"));
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->volume.active, all.active);
  ExpectSamePlane(read->volume.radiance[0], all.radiance[0], "radiance read back");
}

TEST(VolumeMerge, RefusesPartsThatDoNotBelongTogether) {
  const BakeJob whole = WholeJob();
  TempDir dir;
  BakePart(whole, {-0.8, -0.8, 0.3}, {2, 3, 3}, dir.File("a.vdb"));
  BakePart(whole, {0.8, -0.8, 0.3}, {2, 3, 3}, dir.File("b.vdb"));
  BakeJob reseeded = whole;
  reseeded.settings.seed = 12;
  BakePart(reseeded, {0.8, -0.8, 0.3}, {2, 3, 3}, dir.File("seed.vdb"));
  BakePart(whole, {0.85, -0.8, 0.3}, {2, 3, 3}, dir.File("shifted.vdb"));
  BakeJob order3 = whole;
  order3.settings.shOrder = 3;
  BakePart(order3, {0.8, -0.8, 0.3}, {2, 3, 3}, dir.File("order.vdb"));
  // Overlapping a's probes but baked with more samples: the same probes, other values.
  BakeJob more = whole;
  more.settings.samplesPerProbe = 256;
  BakePart(more, {-0.8, -0.8, 0.3}, {1, 3, 3}, dir.File("more.vdb"));

  const struct {
    const char* part;
    const char* field;
  } cases[] = {{"seed.vdb", "seed"},
               {"shifted.vdb", "grid_min"},
               {"order.vdb", "sh_order"},
               {"more.vdb", "samples_per_probe"}};
  for (const auto& c : cases) {
    const absl::StatusOr<ProbeVolumeFile> merged =
        MergeProbeVolumes(ReadParts({dir.File("a.vdb"), dir.File(c.part)}));
    ASSERT_FALSE(merged.ok()) << c.part;
    EXPECT_EQ(merged.status().code(), absl::StatusCode::kInvalidArgument);
    const std::string message(merged.status().message());
    EXPECT_NE(message.find(std::string("part 1 (") + dir.File(c.part) + "): " + c.field),
              std::string::npos)
        << message;
  }
  // The same probes from two parts: fine when identical, refused when not.
  EXPECT_TRUE(MergeProbeVolumes(ReadParts({dir.File("a.vdb"), dir.File("a.vdb")})).ok());
  std::vector<VolumePart> tampered = ReadParts({dir.File("a.vdb"), dir.File("a.vdb")});
  ASSERT_EQ(tampered.size(), 2u);
  const auto& active = tampered[1].file.volume.active;
  const int64_t probe = std::find(active.begin(), active.end(), 1) - active.begin();
  tampered[1].file.volume.radiance[0][3 * probe] += 1;
  const absl::StatusOr<ProbeVolumeFile> bad = MergeProbeVolumes(std::move(tampered));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(std::string(bad.status().message()).find("with different values"), std::string::npos)
      << bad.status();
  EXPECT_FALSE(MergeProbeVolumes({}).ok());

  // A part read from a format-1 file comes from another baker.
  std::vector<VolumePart> formats = ReadParts({dir.File("a.vdb"), dir.File("b.vdb")});
  ASSERT_EQ(formats.size(), 2u);
  formats[1].file.format = kProbeVolumeFormat1;
  const absl::StatusOr<ProbeVolumeFile> mixed = MergeProbeVolumes(std::move(formats));
  ASSERT_FALSE(mixed.ok());
  EXPECT_NE(std::string(mixed.status().message()).find("probebake_format"), std::string::npos)
      << mixed.status();

  // Two small parts a million steps apart would make a dense grid of millions of empty probes.
  std::vector<VolumePart> apart = ReadParts({dir.File("a.vdb"), dir.File("b.vdb")});
  ASSERT_EQ(apart.size(), 2u);
  apart[1].file.volume.grid.origin.x += 0.8 * 1e6;
  const absl::StatusOr<ProbeVolumeFile> sparse = MergeProbeVolumes(std::move(apart));
  ASSERT_FALSE(sparse.ok());
  EXPECT_NE(std::string(sparse.status().message()).find("bounding box"), std::string::npos)
      << sparse.status();
}

}  // namespace
}  // namespace probebake
