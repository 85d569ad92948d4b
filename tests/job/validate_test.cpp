// ValidateJobSpec: every structural rejection names the exact field path (docs/job-format.md).
#include "probebake/job/validate.h"

#include <gtest/gtest.h>

#include <limits>

#include "job/test_util.h"
#include "probebake/job/job_json.h"

namespace probebake {
namespace {

using testing::DataDir;
using testing::HasFieldError;
using testing::Patched;
using testing::ReadText;

std::string Example() {
  return ReadText(DataDir() + "/example.json");
}

// Parse (must succeed) then validate.
absl::Status Check(const std::string& json, const JobLimits& limits = {}) {
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  EXPECT_TRUE(job.ok()) << job.status();
  if (!job.ok()) return absl::InternalError("parse failed");
  return ValidateJobSpec(*job, limits);
}

absl::Status CheckPatched(const std::string& path, const std::string& value,
                          const JobLimits& limits = {}) {
  return Check(Patched(Example(), path, value), limits);
}

TEST(ValidateJobSpec, ExampleIsValid) {
  EXPECT_TRUE(Check(Example()).ok()) << Check(Example());
}

TEST(ValidateJobSpec, LightsBeyondWhatFloatsHoldAreRefused) {
  // An intensity of 1e39 baked to inf in the volume's floats; 1e30 leaves room for projection.
  for (const char* path :
       {"scene.lights[0].point.intensity[1]", "scene.lights[1].spot.intensity[0]",
        "scene.lights[2].directional.irradiance[2]", "scene.lights[3].rect.radiance[0]",
        "scene.lights[4].disk.radiance[1]", "scene.lights[5].sphere.radiance[2]",
        "scene.materials[1].emission[0]", "scene.environment.uniform.radiance[1]"}) {
    EXPECT_TRUE(HasFieldError(CheckPatched(path, "1.5e30"), path, "1.5e+30 is more than 1e30"))
        << path;
    EXPECT_TRUE(CheckPatched(path, "1e30").ok()) << path << ": " << CheckPatched(path, "1e30");
  }
}

TEST(ValidateJobSpec, SpacingTooFineForOpenVdbIsRefused) {
  // OpenVDB's transform needs a voxel volume of 3e-15: 1e-5 on every axis baked, then failed to
  // write. One fine axis is fine.
  auto grid = [](const std::string& spacing) {
    return Patched(Patched(Example(), "grid", R"({"min": [0, 0, 0], "max": [1e-4, 1e-4, 1e-4]})"),
                   "grid.spacing", spacing);
  };
  EXPECT_TRUE(HasFieldError(Check(grid("1e-5")), "grid",
                            "probe spacing (1e-05, 1e-05, 1e-05) is too fine for an OpenVDB grid"));
  EXPECT_TRUE(Check(grid("1.5e-5")).ok()) << Check(grid("1.5e-5"));
  EXPECT_TRUE(Check(grid("[1e-5, 1, 1]")).ok()) << Check(grid("[1e-5, 1, 1]"));
  // A spacing that overflows (max - min past the largest double) is named here, not by the writer.
  EXPECT_TRUE(HasFieldError(
      Check(Patched(Example(), "grid", R"({"min": [-1.7e308, 0, 0], "max": [1.7e308, 1, 1],
                                           "counts": [2, 2, 2]})")),
      "grid", "probe spacing (inf, 1, 1) overflows"));
}

TEST(ValidateJobSpec, NegativeRadianceIntensityIrradianceEmission) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[3].rect.radiance[1]", "-1"),
                            "scene.lights[3].rect.radiance[1]", "negative (-1)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[0].point.intensity[0]", "-0.5"),
                            "scene.lights[0].point.intensity[0]", "negative"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[2].directional.irradiance[2]", "-3"),
                            "scene.lights[2].directional.irradiance[2]", "negative"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.materials[1].emission[0]", "-20"),
                            "scene.materials[1].emission[0]", "negative"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.environment.uniform.radiance[0]", "-0.2"),
                            "scene.environment.uniform.radiance[0]", "negative"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.medium.sigmaS[1]", "-0.05"),
                            "scene.medium.sigmaS[1]", "negative"));
}

TEST(ValidateJobSpec, AlbedoOutsideZeroOne) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.materials[0].albedo[0]", "1.0"),
                            "scene.materials[0].albedo[0]", "1 is outside [0, 1)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.materials[0].albedo[2]", "-0.1"),
                            "scene.materials[0].albedo[2]", "-0.1 is outside [0, 1)"));
  EXPECT_TRUE(CheckPatched("scene.materials[0].albedo[0]", "0.999").ok());
}

TEST(ValidateJobSpec, VectorLengths) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[0].point.position", "[1, 2]"),
                            "scene.lights[0].point.position", "expected 3 numbers, got 2"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[5].sphere.radiance", ""),
                            "scene.lights[5].sphere.radiance", "missing"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[0].transform", "[1, 0, 0, 0]"),
                            "scene.meshes[0].transform", "expected 16 numbers"));
}

TEST(ValidateJobSpec, ZeroAreaRectLights) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[3].rect.edge1", "[0, 0, 0]"),
                            "scene.lights[3].rect.edge1", "zero length"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[3].rect.edge2", "[-2, 0, 0]"),
                            "scene.lights[3].rect.edge2", "parallel to edge1"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[3].rect.edge2", "[1e-200, 1e-200, 0]"),
                            "scene.lights[3].rect", "zero area"));
}

TEST(ValidateJobSpec, ZeroRadiusAndZeroDirections) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[4].disk.radius", "0"),
                            "scene.lights[4].disk.radius", "must be > 0"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[5].sphere.radius", ""),
                            "scene.lights[5].sphere.radius", "must be > 0 (got 0)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[5].sphere.radius", "-1"),
                            "scene.lights[5].sphere.radius", "must be > 0"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[4].disk.normal", "[0, 0, 0]"),
                            "scene.lights[4].disk.normal", "zero length"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[1].spot.direction", "[0, 0, 0]"),
                            "scene.lights[1].spot.direction", "zero length"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[2].directional.direction", "[0, 0, 0]"),
                            "scene.lights[2].directional.direction", "zero length"));
}

TEST(ValidateJobSpec, SpotAnglesAndSunSize) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[1].spot.innerAngleDeg", "40"),
                            "scene.lights[1].spot.innerAngleDeg",
                            "greater than outerAngleDeg (40 > 30)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[1].spot.outerAngleDeg", "190"),
                            "scene.lights[1].spot.outerAngleDeg", "must be in (0, 180]"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[1].spot.innerAngleDeg", "-5"),
                            "scene.lights[1].spot.innerAngleDeg", "must be in [0, 180]"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.lights[2].directional.angularDiameterDeg", "180"),
                            "scene.lights[2].directional.angularDiameterDeg", "[0, 180)"));
}

TEST(ValidateJobSpec, LightWithoutKind) {
  EXPECT_TRUE(
      HasFieldError(CheckPatched("scene.lights[2]", "{}"), "scene.lights[2]", "no light kind"));
}

TEST(ValidateJobSpec, DegenerateTransforms) {
  EXPECT_TRUE(HasFieldError(
      CheckPatched("scene.meshes[0].transform", "[1,0,0,0, 0,1,0,0, 0,0,0,0, 0,0,0,1]"),
      "scene.meshes[0].transform", "singular"));
  EXPECT_TRUE(HasFieldError(
      CheckPatched("scene.meshes[0].transform", "[1,0,0,0, 0,1,0,0, 1,1,0,0, 0,0,0,1]"),
      "scene.meshes[0].transform", "singular"));
  EXPECT_TRUE(HasFieldError(
      CheckPatched("scene.meshes[0].transform", "[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,1,1]"),
      "scene.meshes[0].transform", "last row must be (0, 0, 0, 1)"));
  // Uniform tiny scales and rotations are fine: the test is scale-free.
  EXPECT_TRUE(
      CheckPatched("scene.meshes[0].transform", "[1e-9,0,0,5, 0,1e-9,0,0, 0,0,1e-9,0, 0,0,0,1]")
          .ok());
  EXPECT_TRUE(
      CheckPatched("scene.meshes[0].transform", "[0,-1,0,0, 1,0,0,0, 0,0,1,0, 0,0,0,1]").ok());
}

TEST(ValidateJobSpec, InlineMeshes) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[1].positions", "[0,0,3, 1,0,3, 1,1,3, 0,1]"),
                            "scene.meshes[1].positions", "not a multiple of 3"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[1].indices", "[0,1,2, 0,2,4]"),
                            "scene.meshes[1].indices[5]", "4 is out of range (4 vertices)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[1].indices", "[0,1,2, 0]"),
                            "scene.meshes[1].indices", "not a multiple of 3"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[1].indices", ""), "scene.meshes[1].indices",
                            "missing"));
}

TEST(ValidateJobSpec, MeshSources) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[1].file", "\"panel.obj\""),
                            "scene.meshes[1]", "more than one of file, blob and positions"));
  const std::string noSource =
      Patched(Patched(Example(), "scene.meshes[1].positions", ""), "scene.meshes[1].indices", "");
  EXPECT_TRUE(HasFieldError(Check(noSource), "scene.meshes[1]", "no geometry"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[0].file", "\"room.fbx\""),
                            "scene.meshes[0].file", "unknown mesh format"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[0].file", "\"/abs/room.obj\""),
                            "scene.meshes[0].file", "relative"));
  // A control character in a name is shown escaped: a NUL cut the message short.
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[0].file", "\"room\\u0000.obj\\n\""),
                            "scene.meshes[0].file",
                            "unknown mesh format of \"room\\x00.obj\\x0a\" (expected"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[0].format", "\"stl\""),
                            "scene.meshes[0].format", "unknown format \"stl\""));
  // An explicit format names the reader whatever the extension says.
  EXPECT_TRUE(Check(Patched(Patched(Example(), "scene.meshes[0].file", "\"room.txt\""),
                            "scene.meshes[0].format", "\"OBJ\""))
                  .ok());
  const std::string blob = Patched(Patched(Example(), "scene.meshes[0].file", ""),
                                   "scene.meshes[0].blob", R"({"hash": "ABC", "sizeBytes": -1})");
  EXPECT_TRUE(HasFieldError(Check(blob), "scene.meshes[0].blob.hash", "64 lowercase hex"));
  EXPECT_TRUE(HasFieldError(Check(blob), "scene.meshes[0].blob.sizeBytes", "negative"));
  EXPECT_TRUE(HasFieldError(Check(blob), "scene.meshes[0].format", "required with blob"));
}

TEST(ValidateJobSpec, MaterialNames) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[1].material", "\"lamps\""),
                            "scene.meshes[1].material", "unknown material \"lamps\""));
  // A model file brings its own materials; inline triangles need one.
  EXPECT_TRUE(CheckPatched("scene.meshes[0].material", "").ok());
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.meshes[1].material", ""),
                            "scene.meshes[1].material", "missing"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.materials[1].name", "\"white\""),
                            "scene.materials[1].name",
                            "duplicate name \"white\" (also scene.materials[0])"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.materials[1].name", ""), "scene.materials[1].name",
                            "missing"));
}

TEST(ValidateJobSpec, EnvironmentAndMedium) {
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.environment", "{}"), "scene.environment",
                            "expected one of uniform or map"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.environment", R"({"map": {"scale": 2}})"),
                            "scene.environment.map", "missing file, blob or faces"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.environment", R"({"map": {"file": "sky.exr",
                                                                   "scale": -1}})"),
                            "scene.environment.map.scale", "negative"));
  EXPECT_TRUE(CheckPatched("scene.environment", R"({"map": {"file": "sky.exr", "scale": 0,
                                                    "up": "Z", "rotationDeg": -90}})")
                  .ok());
  EXPECT_TRUE(
      HasFieldError(CheckPatched("scene.medium.g", "1"), "scene.medium.g", "must be in (-1, 1)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("scene.medium.g", "-1.5"), "scene.medium.g",
                            "must be in (-1, 1)"));
  EXPECT_TRUE(
      HasFieldError(CheckPatched("scene.medium.sigmaA", ""), "scene.medium.sigmaA", "missing"));
}

TEST(ValidateJobSpec, EmptyAndInvertedGrids) {
  EXPECT_TRUE(HasFieldError(CheckPatched("grid.max[1]", "-5"), "grid.max[1]",
                            "less than grid.min[1] (-5 < -4)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("grid.counts", ""), "grid", "missing counts or spacing"));
  EXPECT_TRUE(HasFieldError(CheckPatched("grid", ""), "grid", "missing"));
  EXPECT_TRUE(
      HasFieldError(CheckPatched("grid.counts[2]", "0"), "grid.counts[2]", "must be >= 1 (got 0)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("grid.counts", "[9, 9]"), "grid.counts",
                            "expected 3 integers, got 2"));
  EXPECT_TRUE(HasFieldError(CheckPatched("grid.spacing", "1"), "grid", "not both"));
  EXPECT_TRUE(
      HasFieldError(Check(Patched(Patched(Example(), "grid.max[2]", "0.5"), "grid.counts[2]", "4")),
                    "grid.counts[2]", "4 probes on an axis of zero extent"));
  EXPECT_TRUE(HasFieldError(CheckPatched("grid.min", "[0, 0]"), "grid.min", "expected 3 numbers"));
}

TEST(ValidateJobSpec, GridSpacing) {
  const std::string noCounts = Patched(Example(), "grid.counts", "");
  EXPECT_TRUE(Check(Patched(noCounts, "grid.spacing", "0.5")).ok());
  EXPECT_TRUE(Check(Patched(noCounts, "grid.spacing", "[1, 2, 0.5]")).ok());
  EXPECT_TRUE(HasFieldError(Check(Patched(noCounts, "grid.spacing", "-1")), "grid.spacing",
                            "must be > 0 (got -1)"));
  EXPECT_TRUE(
      HasFieldError(Check(Patched(noCounts, "grid.spacing", "0")), "grid.spacing", "must be > 0"));
  EXPECT_TRUE(HasFieldError(Check(Patched(noCounts, "grid.spacing", "[1, -2, 1]")),
                            "grid.spacing[1]", "must be > 0"));
  EXPECT_TRUE(HasFieldError(Check(Patched(noCounts, "grid.spacing", "[1, 2]")), "grid.spacing",
                            "expected a number or 3 numbers"));
  EXPECT_TRUE(HasFieldError(Check(Patched(noCounts, "grid.spacing", "\"1\"")), "grid.spacing",
                            "expected a number"));
  EXPECT_TRUE(HasFieldError(Check(Patched(noCounts, "grid.spacing", "[1, \"NaN\", 1]")),
                            "grid.spacing[1]", "expected a number"));
}

TEST(ValidateJobSpec, NearSurfacesNeedsADistance) {
  EXPECT_TRUE(HasFieldError(CheckPatched("grid.placement", "\"NEAR_SURFACES\""),
                            "grid.surfaceDistance", "must be > 0 with placement NEAR_SURFACES"));
  const std::string near = Patched(Patched(Example(), "grid.placement", "\"NEAR_SURFACES\""),
                                   "grid.surfaceDistance", "0.5");
  EXPECT_TRUE(Check(near).ok());
  // With no meshes nothing is near a surface: refused rather than baked into an empty volume.
  EXPECT_TRUE(HasFieldError(Check(Patched(near, "scene.meshes", "[]")), "grid.placement",
                            "the scene has no meshes"));
}

TEST(ValidateJobSpec, ProbeLimit) {
  EXPECT_TRUE(HasFieldError(CheckPatched("grid.counts", "[10000, 10000, 10000]"), "grid.counts",
                            "1e+12 probes, above the limit of 4194304"));
  const std::string fine = Patched(Patched(Example(), "grid.counts", ""), "grid.spacing", "1e-6");
  EXPECT_TRUE(HasFieldError(Check(fine), "grid.spacing", "above the limit"));
  JobLimits small;
  small.maxProbes = 100;
  EXPECT_TRUE(
      HasFieldError(Check(Example(), small), "grid.counts", "324 probes, above the limit of 100"));
  small.maxProbes = 324;
  EXPECT_TRUE(Check(Example(), small).ok());
  small.maxProbes = 0;  // no limit
  EXPECT_TRUE(CheckPatched("grid.counts", "[1000, 1000, 100]", small).ok());
}

TEST(ValidateJobSpec, SettingsRanges) {
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.shOrder", "9"), "settings.shOrder",
                            "above the highest supported order, 8"));
  EXPECT_TRUE(
      HasFieldError(CheckPatched("settings.shOrder", "-1"), "settings.shOrder", "must be >= 0"));
  JobLimits limits;
  limits.maxShOrder = 4;
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.shOrder", "6", limits), "settings.shOrder",
                            "6 is above the limit of 4"));
  EXPECT_TRUE(CheckPatched("settings.shOrder", "4", limits).ok());
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.samplesPerProbe", "0"),
                            "settings.samplesPerProbe", "must be >= 1"));
  EXPECT_TRUE(
      HasFieldError(CheckPatched("settings.maxDepth", "0"), "settings.maxDepth", "must be >= 1"));
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.targetRelError", "1"), "settings.targetRelError",
                            "[0, 1)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.targetRelError", "-0.1"),
                            "settings.targetRelError", "[0, 1)"));
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.windowWidth", "0"), "settings.windowWidth",
                            "must be > 0"));
  EXPECT_TRUE(
      HasFieldError(CheckPatched("settings.batches", "1"), "settings.batches", "[2, 1024]"));
  EXPECT_TRUE(
      HasFieldError(CheckPatched("settings.batches", "1025"), "settings.batches", "[2, 1024]"));
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.backfaceFraction", "0"),
                            "settings.backfaceFraction", "(0, 1]"));
  EXPECT_TRUE(CheckPatched("settings.backfaceFraction", "1").ok());
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.relocationMaxOffset", "0.6"),
                            "settings.relocationMaxOffset", "[0, 0.5]"));
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.relocationMaxOffset", "-0.1"),
                            "settings.relocationMaxOffset", "[0, 0.5]"));
  EXPECT_TRUE(CheckPatched("settings.relocationMaxOffset", "0.5").ok());
  EXPECT_TRUE(CheckPatched("settings.relocationMaxOffset", "0").ok());
  EXPECT_TRUE(CheckPatched("settings.visibility", "true").ok());
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.rrMinDepth", "0"), "settings.rrMinDepth",
                            "must be >= 1"));
}

TEST(ValidateJobSpec, SampleAndDepthLimitsIncludePresets) {
  JobLimits limits;
  limits.maxSamplesPerProbe = 4096;
  limits.maxDepth = 10;
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.samplesPerProbe", "5000", limits),
                            "settings.samplesPerProbe", "above the limit of 4096"));
  EXPECT_TRUE(HasFieldError(CheckPatched("settings.maxDepth", "11", limits), "settings.maxDepth",
                            "above the limit of 10"));
  // REFERENCE stands for 16384 samples and depth 32 unless numbers are given.
  const std::string reference =
      Patched(Patched(Patched(Example(), "settings.samplesPerProbe", ""), "settings.maxDepth", ""),
              "settings.quality", "\"REFERENCE\"");
  EXPECT_TRUE(HasFieldError(Check(reference, limits), "settings.quality (REFERENCE)",
                            "16384 samples per probe, above the limit of 4096"));
  EXPECT_TRUE(HasFieldError(Check(reference, limits), "settings.quality (REFERENCE)",
                            "maxDepth 32 is above the limit of 10"));
  EXPECT_TRUE(Check(Patched(Patched(reference, "settings.samplesPerProbe", "100"),
                            "settings.maxDepth", "5"),
                    limits)
                  .ok());
}

TEST(ValidateJobSpec, LimitsHoldForTheDefaultsOfSettingsLeftOut) {
  // A job that leaves the numbers out gets order 2, 1024 samples and depth 8: an operator's
  // limits below those must refuse it as they refuse the numbers given.
  JobLimits limits;
  limits.maxShOrder = 1;
  limits.maxSamplesPerProbe = 64;
  limits.maxDepth = 2;
  std::string bare = Example();
  for (const char* field : {"settings.shOrder", "settings.samplesPerProbe", "settings.maxDepth"})
    bare = Patched(bare, field, "");
  const absl::Status refused = Check(bare, limits);
  EXPECT_TRUE(HasFieldError(refused, "settings.shOrder (default)", "2 is above the limit of 1"));
  EXPECT_TRUE(HasFieldError(refused, "settings.samplesPerProbe (default)",
                            "1024 samples per probe, above the limit of 64"));
  EXPECT_TRUE(
      HasFieldError(refused, "settings.maxDepth (default)", "maxDepth 8 is above the limit of 2"));
  // The same job within limits that allow the defaults is fine.
  limits.maxShOrder = 2;
  limits.maxSamplesPerProbe = 1024;
  limits.maxDepth = 8;
  EXPECT_TRUE(Check(bare, limits).ok()) << Check(bare, limits);
}

TEST(ValidateJobSpec, WindowNeedsIrradiance) {
  const std::string noIrradiance = Patched(Example(), "settings.irradiance", "false");
  EXPECT_TRUE(HasFieldError(Check(Patched(noIrradiance, "settings.window", "\"HANNING\"")),
                            "settings.window", "HANNING applies to the irradiance grids"));
  EXPECT_TRUE(Check(Patched(noIrradiance, "settings.window", "\"NONE\"")).ok());
  EXPECT_TRUE(CheckPatched("settings.window", "\"AUTO\"").ok());
}

TEST(ValidateJobSpec, LightLimit) {
  JobLimits limits;
  limits.maxLights = 5;
  EXPECT_TRUE(
      HasFieldError(Check(Example(), limits), "scene.lights", "6 lights, above the limit of 5"));
}

TEST(ValidateJobSpec, InlineTriangleLimit) {
  JobLimits limits;
  limits.maxTriangles = 1;
  EXPECT_TRUE(
      HasFieldError(Check(Example(), limits), "scene.meshes[1].indices", "above the limit of 1"));
}

// Numbers that arrive in binary (gRPC) can be NaN or infinite without any JSON string.
TEST(ValidateJobSpec, NonFiniteNumbersFromBinary) {
  absl::StatusOr<v1::JobSpec> job = ParseJobJson(Example());
  ASSERT_TRUE(job.ok());
  job->mutable_scene()->mutable_lights(3)->mutable_rect()->set_edge1(
      1, std::numeric_limits<double>::quiet_NaN());
  job->mutable_grid()->mutable_min()->Set(2, -std::numeric_limits<double>::infinity());
  job->mutable_settings()->set_window_width(std::numeric_limits<double>::infinity());
  job->mutable_grid()->mutable_spacing()->set_number_value(
      std::numeric_limits<double>::quiet_NaN());
  job->mutable_grid()->clear_counts();
  const absl::Status s = ValidateJobSpec(*job, {});
  EXPECT_TRUE(HasFieldError(s, "scene.lights[3].rect.edge1[1]", "NaN is not allowed"));
  EXPECT_TRUE(HasFieldError(s, "grid.min[2]", "infinity is not allowed"));
  EXPECT_TRUE(HasFieldError(s, "grid.spacing", "NaN is not allowed"));
  EXPECT_TRUE(HasFieldError(s, "settings.windowWidth", "infinity is not allowed"));
  // A non-finite number is reported once, not again by the range checks.
  EXPECT_EQ(std::string(s.message()).find("edge1: "), std::string::npos) << s.message();
}

TEST(ValidateJobSpec, UndefinedEnumNumbersFromBinary) {
  absl::StatusOr<v1::JobSpec> job = ParseJobJson(Example());
  ASSERT_TRUE(job.ok());
  job->mutable_grid()->set_placement(static_cast<v1::Grid::Placement>(17));
  job->mutable_settings()->set_sampler(static_cast<v1::BakeSettings::Sampler>(9));
  const absl::Status s = ValidateJobSpec(*job, {});
  EXPECT_TRUE(HasFieldError(s, "grid.placement", "unknown value 17"));
  EXPECT_TRUE(HasFieldError(s, "settings.sampler", "unknown value 9"));
}

TEST(ValidateJobSpec, ErrorsAreCappedAndFirstComesFirst) {
  absl::StatusOr<v1::JobSpec> job = ParseJobJson(Example());
  ASSERT_TRUE(job.ok());
  for (int i = 0; i < 80; ++i) {
    v1::Light* light = job->mutable_scene()->add_lights();
    light->mutable_sphere()->set_radius(-1);
  }
  const absl::Status s = ValidateJobSpec(*job, {});
  const std::string message(s.message());
  EXPECT_EQ(message.rfind("scene.lights[6].sphere.center: missing", 0), 0u) << message;
  EXPECT_NE(message.find("more errors"), std::string::npos);
  EXPECT_EQ(std::count(message.begin(), message.end(), '\n'), 50) << message;
}

}  // namespace
}  // namespace probebake
