// BuildBakeJob on whole jobs: the example job (tests/data/job/example.json), grid and settings
// resolution, digests, file references and asset sources.
#include <gtest/gtest.h>

#include <cmath>

#include "job/test_util.h"
#include "probebake/job/digest.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

namespace probebake {
namespace {

using testing::DataDir;
using testing::HasFieldError;
using testing::Patched;
using testing::ReadText;
using testing::TempDir;

std::string Example() {
  return ReadText(DataDir() + "/example.json");
}

v1::JobSpec Parse(const std::string& json) {
  absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  EXPECT_TRUE(job.ok()) << job.status();
  return job.ok() ? *job : v1::JobSpec();
}

absl::StatusOr<BakeJob> BuildFromData(const std::string& json, const JobLimits& limits = {}) {
  return BuildBakeJob(Parse(json), LocalAssetSource(DataDir()), limits);
}

// A scene-less job: one probe grid, for grid and settings tests.
constexpr char kGridOnly[] =
    R"({"grid": {"min": [0, 0, 0], "max": [4, 2, 1], "counts": [5, 3, 2]}})";

TEST(BuildBakeJob, Sha256KnownAnswers) {
  // FIPS 180-2 test vectors.
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  const v1::Digest d = DigestOf("abc");
  EXPECT_EQ(d.size_bytes(), 3);
  EXPECT_TRUE(IsSha256Hex(d.hash()));
  EXPECT_FALSE(IsSha256Hex("ABC"));
}

TEST(BuildBakeJob, SpecExampleBuilds) {
  const absl::StatusOr<BakeJob> built = LoadBakeJob(DataDir() + "/example.json", {});
  ASSERT_TRUE(built.ok()) << built.status();
  const Scene& scene = built->scene;

  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_EQ(scene.materials[0].albedo, Vec3d(0.8, 0.8, 0.8));
  EXPECT_EQ(scene.materials[1].emission, Vec3d(20, 18, 15));

  ASSERT_EQ(scene.meshes.size(), 2u);
  const TriangleMesh& room = scene.meshes[0];
  EXPECT_EQ(room.name, "room");
  EXPECT_EQ(room.material, 0u);
  EXPECT_EQ(room.TriangleCount(), 12u);  // 6 quads
  // Every triangle of the closed room faces inward: winding survives the import.
  const Vec3d center(0, 0, 2);
  for (size_t t = 0; t < room.TriangleCount(); ++t) {
    const Vec3d a = room.positions[room.indices[3 * t]];
    const Vec3d b = room.positions[room.indices[3 * t + 1]];
    const Vec3d c = room.positions[room.indices[3 * t + 2]];
    EXPECT_GT(Dot(Cross(b - a, c - a), center - a), 0) << "triangle " << t;
    for (const Vec3d& p : {a, b, c}) {
      EXPECT_EQ(std::abs(p.x), 5);
      EXPECT_EQ(std::abs(p.y), 5);
      EXPECT_TRUE(p.z == 0 || p.z == 4) << p;
    }
  }
  const TriangleMesh& panel = scene.meshes[1];
  EXPECT_EQ(panel.material, 1u);
  ASSERT_EQ(panel.TriangleCount(), 2u);
  EXPECT_EQ(panel.positions[2], Vec3d(1, 1, 3));

  ASSERT_EQ(scene.lights.size(), 6u);
  const auto* point = std::get_if<PointLight>(&scene.lights[0]);
  ASSERT_NE(point, nullptr);
  EXPECT_EQ(point->intensity, Vec3d(10, 10, 10));
  const auto* spot = std::get_if<SpotLight>(&scene.lights[1]);
  ASSERT_NE(spot, nullptr);
  EXPECT_EQ(spot->direction, Vec3d(0, 0, -1));
  EXPECT_NEAR(spot->cosInner, std::cos(20 * M_PI / 180), 1e-15);
  EXPECT_NEAR(spot->cosOuter, std::cos(30 * M_PI / 180), 1e-15);
  const auto* sun = std::get_if<DirectionalLight>(&scene.lights[2]);
  ASSERT_NE(sun, nullptr);
  EXPECT_NEAR(Length(sun->direction), 1, 1e-15);
  EXPECT_NEAR(sun->direction.x / sun->direction.z, -0.3, 1e-15);
  EXPECT_NEAR(sun->cosHalfAngle, std::cos(0.265 * M_PI / 180), 1e-15);
  EXPECT_NE(std::get_if<RectLight>(&scene.lights[3]), nullptr);
  const auto* disk = std::get_if<DiskLight>(&scene.lights[4]);
  ASSERT_NE(disk, nullptr);
  EXPECT_EQ(disk->radius, 0.5);
  EXPECT_NE(std::get_if<SphereLight>(&scene.lights[5]), nullptr);

  EXPECT_EQ(scene.environment.kind, Environment::Kind::kUniform);
  EXPECT_EQ(scene.environment.radiance, Vec3d(0.2, 0.25, 0.3));

  // The medium fills the room (the largest extent here), padded by a hair.
  ASSERT_TRUE(scene.medium.has_value());
  EXPECT_EQ(scene.medium->g, 0.3);
  const double pad = 1e-4 * Length(Vec3d(10, 10, 4)) + 1e-6 * 5;
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(scene.medium->boundsMin[a], Vec3d(-5, -5, 0)[a] - pad, 1e-12) << a;
    EXPECT_NEAR(scene.medium->boundsMax[a], Vec3d(5, 5, 4)[a] + pad, 1e-12) << a;
  }

  const ProbeGrid& grid = built->grid;
  EXPECT_EQ(grid.counts[0], 9);
  EXPECT_EQ(grid.counts[1], 9);
  EXPECT_EQ(grid.counts[2], 4);
  EXPECT_EQ(grid.spacing, Vec3d(1, 1, 1));
  EXPECT_EQ(grid.origin, Vec3d(-4, -4, 0.5));
  EXPECT_EQ(grid.Position(8, 8, 3), Vec3d(4, 4, 3.5));
  EXPECT_EQ(grid.placement, Placement::kOutsideGeometry);

  EXPECT_TRUE(built->settings.irradiance);
  EXPECT_EQ(built->settings.shOrder, 2);
  EXPECT_TRUE(IsSha256Hex(built->sceneDigest));
  EXPECT_TRUE(IsSha256Hex(built->jobDigest));
  EXPECT_NE(built->sceneDigest, built->jobDigest);
}

TEST(BuildBakeJob, MissingAssetsAreRejectedWithPathAndFileName) {
  const absl::StatusOr<BakeJob> mesh =
      BuildFromData(Patched(Example(), "scene.meshes[0].file", "\"nope/missing.obj\""));
  EXPECT_TRUE(
      HasFieldError(mesh.status(), "scene.meshes[0].file", "cannot read \"nope/missing.obj\""));
  const absl::StatusOr<BakeJob> env =
      BuildFromData(Patched(Example(), "scene.environment", R"({"map": {"file": "sky.exr"}})"));
  EXPECT_TRUE(HasFieldError(env.status(), "scene.environment.map.file", "cannot read \"sky.exr\""));

  // LoadBakeJob also names the job file.
  TempDir dir;
  const std::string job = dir.Write("job.json", Example());  // room.obj is not next to it
  EXPECT_TRUE(
      HasFieldError(LoadBakeJob(job, {}).status(), job + ": scene.meshes[0].file", "room.obj"));
}

TEST(BuildBakeJob, ValidationRunsFirst) {
  EXPECT_TRUE(HasFieldError(BuildFromData(Patched(Example(), "scene.medium.g", "2")).status(),
                            "scene.medium.g", "(-1, 1)"));
}

TEST(BuildBakeJob, ScenesSpanningMoreThanTheTracerHoldsAreRefused) {
  // kMaxSceneSpan (2e12): the tracer's single-precision geometry about the scene's centre.
  auto withScene = [](const std::string& meshes, const std::string& lights) {
    return BuildFromData(Patched(kGridOnly, "scene",
                                 R"({
        "materials": [{"name": "m", "albedo": [0.5, 0.5, 0.5]}], "meshes": )" +
                                     meshes + R"(, "lights": )" + lights + "}"));
  };
  auto square = [](const std::string& s) {
    return R"([{"name": "floor", "material": "m", "positions": [-)" + s + ", -" + s + ", 0, " + s +
           ", -" + s + ", 0, " + s + ", " + s + ", 0, -" + s + ", " + s +
           R"(, 0], "indices": [0, 1, 2, 0, 2, 3]}])";
  };
  EXPECT_TRUE(withScene(square("1e12"), "[]").ok());  // spans exactly 2e12
  EXPECT_TRUE(HasFieldError(withScene(square("1.5e12"), "[]").status(), "scene.meshes[0]",
                            "spans 3e+12, more than the 2e+12 its single-precision tracer"));
  // A unit room with a point light 1e13 away: the light is named, not the room it displaces.
  const std::string far = R"([{"point": {"position": [0, 0, 1e13], "intensity": [1, 1, 1]}}])";
  EXPECT_TRUE(HasFieldError(withScene(square("1"), far).status(), "scene.lights[0]",
                            "reaches z = 1e+13, and scene.meshes[0] z = 0"));
  // Directional lights have no position: any distance is fine.
  EXPECT_TRUE(withScene(square("1"), R"([{"directional": {"direction": [0, 0, -1],
                                          "irradiance": [1, 1, 1]}}])")
                  .ok());
}

TEST(BuildBakeJob, UnusedFeaturesCostNothing) {
  std::string json = Patched(Example(), "scene.environment.uniform.radiance", "[0, 0, 0]");
  json = Patched(json, "scene.medium", R"({"sigmaA": [0, 0, 0], "sigmaS": [0, 0, 0]})");
  const absl::StatusOr<BakeJob> built = BuildFromData(json);
  ASSERT_TRUE(built.ok()) << built.status();
  EXPECT_EQ(built->scene.environment.kind, Environment::Kind::kNone);
  EXPECT_FALSE(built->scene.medium.has_value());
}

// ---- Grid resolution (docs/job-format.md) ----

ProbeGrid GridOf(const std::string& gridJson) {
  const absl::StatusOr<BakeJob> built = BuildFromData(Patched(kGridOnly, "grid", gridJson));
  EXPECT_TRUE(built.ok()) << built.status();
  return built.ok() ? built->grid : ProbeGrid();
}

TEST(ResolveGrid, Counts) {
  const ProbeGrid g = GridOf(R"({"min": [0, 0, 0], "max": [4, 2, 1], "counts": [5, 3, 2]})");
  EXPECT_EQ(g.spacing, Vec3d(1, 1, 1));
  EXPECT_EQ(g.ProbeCount(), 30);
  const ProbeGrid h = GridOf(R"({"min": [-1, 0, 0], "max": [1, 3, 1], "counts": [3, 4, 5]})");
  EXPECT_EQ(h.spacing, Vec3d(1, 1, 0.25));
  EXPECT_EQ(h.Position(2, 3, 4), Vec3d(1, 3, 1));
}

TEST(ResolveGrid, OneProbeOnAnAxisTakesTheSmallestOtherSpacing) {
  const ProbeGrid g = GridOf(R"({"min": [0, 0, 7], "max": [4, 1, 9], "counts": [5, 3, 1]})");
  EXPECT_EQ(g.spacing, Vec3d(1, 0.5, 0.5));
  EXPECT_EQ(g.Position(0, 0, 0).z, 7);  // the probe sits at min
  const ProbeGrid one = GridOf(R"({"min": [1, 2, 3], "max": [1, 2, 3], "counts": [1, 1, 1]})");
  EXPECT_EQ(one.spacing, Vec3d(1, 1, 1));
  EXPECT_EQ(one.ProbeCount(), 1);
  EXPECT_EQ(one.origin, Vec3d(1, 2, 3));
}

TEST(ResolveGrid, SpacingNumberAndTriple) {
  const ProbeGrid g = GridOf(R"({"min": [0, 0, 0], "max": [2, 1, 0.5], "spacing": 0.5})");
  EXPECT_EQ(g.counts[0], 5);
  EXPECT_EQ(g.counts[1], 3);
  EXPECT_EQ(g.counts[2], 2);
  EXPECT_EQ(g.spacing, Vec3d(0.5, 0.5, 0.5));
  const ProbeGrid t = GridOf(R"({"min": [0, 0, 0], "max": [1, 8, 0], "spacing": [0.3, 0.1, 2]})");
  EXPECT_EQ(t.counts[0], 4);   // 0, 0.3, 0.6, 0.9: max is not reached
  EXPECT_EQ(t.counts[1], 81);  // 8 / 0.1 is 79.99999999999999 in double: the 1e-9 keeps 81
  EXPECT_EQ(t.counts[2], 1);   // zero extent: one probe at min
  EXPECT_EQ(t.spacing, Vec3d(0.3, 0.1, 2));
}

TEST(ResolveGrid, ASpacingGivesTheSameCountsFarFromTheOrigin) {
  // 0.14 .. 0.36 at 0.01 is 23 probes; written around 200000 its extent over the spacing is
  // 21.999999997 in double, which lost the last probe to a fixed 1e-9 tolerance.
  for (const char* whole : {"0", "-1000", "200000", "-200000", "9999999"}) {
    const bool negative = whole[0] == '-';
    const std::string lo = std::string(whole) + (negative ? ".36" : ".14");
    const std::string hi = std::string(whole) + (negative ? ".14" : ".36");
    const ProbeGrid g = GridOf(R"({"min": [)" + lo + ", 0, " + lo + R"(], "max": [)" + hi +
                               ", 1, " + hi + R"(], "spacing": [0.01, 0.3, 0.02]})");
    EXPECT_EQ(g.counts[0], 23) << whole;
    EXPECT_EQ(g.counts[1], 4) << whole;   // 1 / 0.3: max is not reached, near or far
    EXPECT_EQ(g.counts[2], 12) << whole;  // 0.22 / 0.02 = 11
  }
}

TEST(ResolveGrid, ASpacingNearTheCoordinatesPrecisionIsRefusedOrCountedExactly) {
  // At 1e12 a double steps by 1.2e-4. A spacing of 0.001 (8 steps) gained a probe past max from
  // the rounding tolerance and at 1e14 failed in OpenVDB after the bake: refused up front, naming
  // the field. 0.1 (800 steps) is at least 2^-44 of the coordinates: counted exactly.
  const std::string tooFine =
      R"({"min": [1e12, 0, 0], "max": [1000000000001, 1, 1], "spacing": [0.001, 0.5, 0.5]})";
  EXPECT_TRUE(HasFieldError(BuildFromData(Patched(kGridOnly, "grid", tooFine)).status(),
                            "grid.spacing[0]", "probe spacing 0.001 is too fine for coordinates"));
  const std::string tooManyCounts =
      R"({"min": [0, 0, 1e14], "max": [1, 1, 100000000000001], "counts": [2, 2, 1001]})";
  EXPECT_TRUE(HasFieldError(BuildFromData(Patched(kGridOnly, "grid", tooManyCounts)).status(),
                            "grid.counts[2]", "is too fine for coordinates"));
  const ProbeGrid g =
      GridOf(R"({"min": [1e12, 0, 0], "max": [1000000000001, 1, 1], "spacing": [0.1, 0.5, 0.5]})");
  EXPECT_EQ(g.counts[0], 11);
}

TEST(ResolveGrid, Placement) {
  EXPECT_EQ(GridOf(R"({"min": [0, 0, 0], "max": [1, 1, 1], "counts": [2, 2, 2]})").placement,
            Placement::kOutsideGeometry);
  EXPECT_EQ(GridOf(R"({"min": [0, 0, 0], "max": [1, 1, 1], "counts": [2, 2, 2],
                       "placement": "ALL"})")
                .placement,
            Placement::kAll);
  // NEAR_SURFACES needs a mesh to be near.
  const std::string withMesh = Patched(kGridOnly, "scene", R"({
      "materials": [{"name": "m", "albedo": [0.5, 0.5, 0.5]}],
      "meshes": [{"name": "t", "material": "m", "positions": [0, 0, 0, 1, 0, 0, 0, 1, 0],
                  "indices": [0, 1, 2]}]})");
  const absl::StatusOr<BakeJob> near =
      BuildFromData(Patched(withMesh, "grid", R"({"min": [0, 0, 0], "max": [1, 1, 1],
          "counts": [2, 2, 2], "placement": "NEAR_SURFACES", "surfaceDistance": 0.25})"));
  ASSERT_TRUE(near.ok()) << near.status();
  EXPECT_EQ(near->grid.placement, Placement::kNearSurfaces);
  EXPECT_EQ(near->grid.surfaceDistance, 0.25);
}

// ---- Settings ----

BakeSettings SettingsOf(const std::string& settingsJson) {
  const absl::StatusOr<BakeJob> built = BuildFromData(Patched(kGridOnly, "settings", settingsJson));
  EXPECT_TRUE(built.ok()) << built.status();
  return built.ok() ? built->settings : BakeSettings();
}

TEST(ResolveSettings, Defaults) {
  const BakeSettings s = SettingsOf("{}");
  EXPECT_EQ(s.shOrder, 2);
  EXPECT_EQ(s.samplesPerProbe, 1024);
  EXPECT_EQ(s.maxDepth, 8);
  EXPECT_EQ(s.targetRelError, 0);
  EXPECT_EQ(s.seed, 1u);
  EXPECT_FALSE(s.irradiance);
  EXPECT_EQ(s.window, ShWindow::kNone);
  EXPECT_EQ(s.windowWidth, 3);
  EXPECT_EQ(s.estimator, Estimator::kNeeMis);
  EXPECT_EQ(s.sampler, SamplerKind::kSobol);
  EXPECT_TRUE(s.russianRoulette);
  EXPECT_EQ(s.rrMinDepth, 3);
  EXPECT_EQ(s.batches, 4);
  EXPECT_EQ(s.backfaceFraction, 0.5);
  EXPECT_EQ(SettingsOf(R"({"shOrder": 4})").windowWidth, 5);
}

TEST(ResolveSettings, PresetsAndExplicitNumbersWin) {
  const BakeSettings preview = SettingsOf(R"({"quality": "PREVIEW"})");
  EXPECT_EQ(preview.samplesPerProbe, 512);
  EXPECT_EQ(preview.maxDepth, 6);
  EXPECT_EQ(preview.targetRelError, 0.05);
  const BakeSettings production = SettingsOf(R"({"quality": "PRODUCTION"})");
  EXPECT_EQ(production.samplesPerProbe, 4096);
  EXPECT_EQ(production.maxDepth, 8);
  EXPECT_EQ(production.targetRelError, 0.02);
  const BakeSettings reference = SettingsOf(R"({"quality": "REFERENCE"})");
  EXPECT_EQ(reference.samplesPerProbe, 16384);
  EXPECT_EQ(reference.maxDepth, 32);
  EXPECT_EQ(reference.targetRelError, 0);

  const BakeSettings mixed =
      SettingsOf(R"({"quality": "PREVIEW", "samplesPerProbe": 100, "targetRelError": 0})");
  EXPECT_EQ(mixed.samplesPerProbe, 100);
  EXPECT_EQ(mixed.maxDepth, 6);  // from the preset
  EXPECT_EQ(mixed.targetRelError, 0);
}

TEST(ResolveSettings, EveryFieldIsRead) {
  const BakeSettings s = SettingsOf(R"({"shOrder": 8, "samplesPerProbe": "70000", "maxDepth": 3,
      "targetRelError": 0.02, "seed": "12345678901234", "irradiance": true, "window": "HANNING",
      "windowWidth": 6.5, "estimator": "LIGHT_SAMPLING", "sampler": "INDEPENDENT",
      "russianRoulette": false, "rrMinDepth": 2, "batches": 32, "backfaceFraction": 0.25})");
  EXPECT_EQ(s.shOrder, 8);
  EXPECT_EQ(s.samplesPerProbe, 70000);
  EXPECT_EQ(s.maxDepth, 3);
  EXPECT_EQ(s.targetRelError, 0.02);
  EXPECT_EQ(s.seed, 12345678901234u);
  EXPECT_TRUE(s.irradiance);
  EXPECT_EQ(s.window, ShWindow::kHanning);
  EXPECT_EQ(s.windowWidth, 6.5);
  EXPECT_EQ(s.estimator, Estimator::kLightSampling);
  EXPECT_EQ(s.sampler, SamplerKind::kIndependent);
  EXPECT_FALSE(s.russianRoulette);
  EXPECT_EQ(s.rrMinDepth, 2);
  EXPECT_EQ(s.batches, 32);
  EXPECT_EQ(s.backfaceFraction, 0.25);
}

bool SameSettings(const BakeSettings& a, const BakeSettings& b) {
  return a.shOrder == b.shOrder && a.samplesPerProbe == b.samplesPerProbe &&
         a.maxDepth == b.maxDepth && a.targetRelError == b.targetRelError && a.seed == b.seed &&
         a.irradiance == b.irradiance && a.window == b.window && a.windowWidth == b.windowWidth &&
         a.estimator == b.estimator && a.sampler == b.sampler &&
         a.russianRoulette == b.russianRoulette && a.rrMinDepth == b.rrMinDepth &&
         a.batches == b.batches && a.backfaceFraction == b.backfaceFraction &&
         a.relocationMaxOffset == b.relocationMaxOffset && a.visibility == b.visibility &&
         a.skyTransferOrder == b.skyTransferOrder;
}

TEST(SettingsJson, RoundTripsWithEveryFieldExplicit) {
  for (const char* settings :
       {"{}", R"({"quality": "PREVIEW", "irradiance": true, "window": "LANCZOS"})",
        R"({"shOrder": 5, "seed": "18446744073709551615", "targetRelError": 0.125,
            "estimator": "DIRECTION_SAMPLING", "russianRoulette": false, "windowWidth": 0.1})",
        R"({"skyTransfer": {"order": 3}, "visibility": true})"}) {
    const absl::StatusOr<BakeJob> built = BuildFromData(Patched(kGridOnly, "settings", settings));
    ASSERT_TRUE(built.ok()) << built.status();
    const std::string& json = built->settingsJson;
    // Every one of the 16 numeric/enum/bool fields is written, quality never; skyTransfer only
    // when on (so that the settings of bakes without it are as before).
    google::protobuf::Value value;
    ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(json, &value).ok()) << json;
    const bool transfer = built->settings.skyTransferOrder > 0;
    EXPECT_EQ(value.struct_value().fields_size(), transfer ? 17 : 16) << json;
    EXPECT_EQ(value.struct_value().fields().contains("skyTransfer"), transfer) << json;
    EXPECT_FALSE(value.struct_value().fields().contains("quality")) << json;
    EXPECT_TRUE(value.struct_value().fields().contains("targetRelError")) << json;
    EXPECT_TRUE(value.struct_value().fields().contains("irradiance")) << json;

    // Fed back as a job's settings, it resolves to the same settings and the same job digest.
    const absl::StatusOr<BakeJob> again = BuildFromData(Patched(kGridOnly, "settings", json));
    ASSERT_TRUE(again.ok()) << again.status();
    EXPECT_TRUE(SameSettings(again->settings, built->settings)) << json;
    EXPECT_EQ(again->settingsJson, json);
    EXPECT_EQ(again->jobDigest, built->jobDigest);
  }
}

// ---- Digests ----

TEST(Digests, StableAndIndependentOfJsonLayout) {
  const absl::StatusOr<BakeJob> a = BuildFromData(Example());
  const absl::StatusOr<BakeJob> b = BuildFromData(Example());
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->sceneDigest, b->sceneDigest);
  EXPECT_EQ(a->jobDigest, b->jobDigest);
  // Re-serialised JSON (keys reordered, numbers reformatted) is the same job.
  const absl::StatusOr<BakeJob> c = BuildFromData(Patched(Example(), "grid.counts[0]", "9"));
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->sceneDigest, a->sceneDigest);
  EXPECT_EQ(c->jobDigest, a->jobDigest);
}

TEST(Digests, DefaultsSpelledOutAreTheSameJob) {
  const absl::StatusOr<BakeJob> base = BuildFromData(Example());
  ASSERT_TRUE(base.ok()) << base.status();
  // The example spells out an identity transform, a black albedo and the default placement.
  const std::string folded =
      Patched(Patched(Patched(Patched(Example(), "scene.meshes[0].transform", ""),
                              "scene.materials[1].albedo", ""),
                      "grid.placement", ""),
              "scene.meshes[1].name", "\"renamed panel\"");
  const std::string zeroEmission = Patched(folded, "scene.materials[0].emission", "[0, 0, 0]");
  const std::string ignoredDistance = Patched(folded, "grid.surfaceDistance", "0.25");
  for (const std::string& same : {folded, zeroEmission, ignoredDistance}) {
    const absl::StatusOr<BakeJob> built = BuildFromData(same);
    ASSERT_TRUE(built.ok()) << built.status();
    EXPECT_EQ(built->sceneDigest, base->sceneDigest) << same;
    EXPECT_EQ(built->jobDigest, base->jobDigest) << same;
  }
  // A medium that neither absorbs nor scatters is vacuum.
  const absl::StatusOr<BakeJob> vacuum = BuildFromData(Patched(
      Patched(Example(), "scene.medium.sigmaA", "[0, 0, 0]"), "scene.medium.sigmaS", "[0, 0, 0]"));
  const absl::StatusOr<BakeJob> noMedium = BuildFromData(Patched(Example(), "scene.medium", ""));
  ASSERT_TRUE(vacuum.ok() && noMedium.ok());
  EXPECT_FALSE(vacuum->scene.medium.has_value());
  EXPECT_EQ(vacuum->sceneDigest, noMedium->sceneDigest);
  EXPECT_NE(noMedium->sceneDigest, base->sceneDigest);
  // One spacing for every axis, written once or three times.
  const std::string spaced = Patched(Patched(Example(), "grid.counts", ""), "grid.spacing", "1");
  const absl::StatusOr<BakeJob> once = BuildFromData(spaced);
  const absl::StatusOr<BakeJob> thrice =
      BuildFromData(Patched(spaced, "grid.spacing", "[1, 1, 1]"));
  const absl::StatusOr<BakeJob> uneven =
      BuildFromData(Patched(spaced, "grid.spacing", "[1, 1, 0.5]"));
  ASSERT_TRUE(once.ok() && thrice.ok() && uneven.ok());
  EXPECT_EQ(thrice->jobDigest, once->jobDigest);
  EXPECT_NE(uneven->jobDigest, once->jobDigest);
  // What does change the bake still changes the digests.
  const absl::StatusOr<BakeJob> moved = BuildFromData(
      Patched(Example(), "scene.meshes[0].transform", "[1,0,0,0, 0,1,0,0, 0,0,1,0.5, 0,0,0,1]"));
  const absl::StatusOr<BakeJob> all =
      BuildFromData(Patched(Example(), "grid.placement", "\"ALL\""));
  ASSERT_TRUE(moved.ok() && all.ok());
  EXPECT_NE(moved->sceneDigest, base->sceneDigest);
  EXPECT_EQ(all->sceneDigest, base->sceneDigest);
  EXPECT_NE(all->jobDigest, base->jobDigest);
}

TEST(Digests, WhatChangesWhat) {
  const absl::StatusOr<BakeJob> base = BuildFromData(Example());
  ASSERT_TRUE(base.ok());
  const absl::StatusOr<BakeJob> seed = BuildFromData(Patched(Example(), "settings.seed", "2"));
  ASSERT_TRUE(seed.ok());
  EXPECT_EQ(seed->sceneDigest, base->sceneDigest);
  EXPECT_NE(seed->jobDigest, base->jobDigest);
  const absl::StatusOr<BakeJob> light =
      BuildFromData(Patched(Example(), "scene.lights[0].point.intensity[0]", "11"));
  ASSERT_TRUE(light.ok());
  EXPECT_NE(light->sceneDigest, base->sceneDigest);
  EXPECT_NE(light->jobDigest, base->jobDigest);
  const absl::StatusOr<BakeJob> grid = BuildFromData(Patched(Example(), "grid.counts[0]", "5"));
  ASSERT_TRUE(grid.ok());
  EXPECT_EQ(grid->sceneDigest, base->sceneDigest);
  EXPECT_NE(grid->jobDigest, base->jobDigest);
  // The mesh file's bytes enter the digest, not its name.
  TempDir dir;
  std::string room = ReadText(DataDir() + "/room.obj");
  dir.Write("renamed.obj", room);
  dir.Write("changed.obj", room + "\n# a comment changes the bytes\n");
  const LocalAssetSource assets(dir.path());
  const absl::StatusOr<BakeJob> renamed = BuildBakeJob(
      Parse(Patched(Example(), "scene.meshes[0].file", "\"renamed.obj\"")), assets, {});
  const absl::StatusOr<BakeJob> changed = BuildBakeJob(
      Parse(Patched(Example(), "scene.meshes[0].file", "\"changed.obj\"")), assets, {});
  ASSERT_TRUE(renamed.ok() && changed.ok());
  EXPECT_EQ(renamed->sceneDigest, base->sceneDigest);
  EXPECT_NE(changed->sceneDigest, base->sceneDigest);
}

TEST(Digests, PresetAndTheSameExplicitNumbersAgree) {
  const absl::StatusOr<BakeJob> preset =
      BuildFromData(Patched(kGridOnly, "settings", R"({"quality": "PREVIEW"})"));
  const absl::StatusOr<BakeJob> explicitNumbers = BuildFromData(Patched(
      kGridOnly, "settings", R"({"samplesPerProbe": 512, "maxDepth": 6, "targetRelError": 0.05})"));
  ASSERT_TRUE(preset.ok() && explicitNumbers.ok());
  EXPECT_EQ(preset->jobDigest, explicitNumbers->jobDigest);
}

// ---- File references: what the CLI uploads ----

TEST(FileReferences, FileAndBlobReferencesGiveTheSameDigests) {
  std::string json = Patched(Example(), "scene.environment", R"({"map": {"file": "sky.exr"}})");
  v1::JobSpec job = Parse(json);
  const std::vector<FileReference> refs = ListFileReferences(job);
  ASSERT_EQ(refs.size(), 2u);
  EXPECT_EQ(refs[0].kind, FileReference::Kind::kMesh);
  EXPECT_EQ(refs[0].meshIndex, 0);
  EXPECT_EQ(refs[0].fieldPath, "scene.meshes[0].file");
  EXPECT_EQ(refs[0].relativePath, "room.obj");
  EXPECT_EQ(refs[1].kind, FileReference::Kind::kEnvironmentMap);
  EXPECT_EQ(refs[1].fieldPath, "scene.environment.map.file");
  EXPECT_EQ(refs[1].relativePath, "sky.exr");

  // Upload the mesh to a blob folder holding each file under its hash (environment maps are
  // uploaded the same way; environment_test covers their digests).
  TempDir jobDir, blobDir;
  const std::string room = ReadText(DataDir() + "/room.obj");
  jobDir.Write("room.obj", room);
  job.mutable_scene()->clear_environment();
  v1::JobSpec uploaded = job;
  for (const FileReference& ref : ListFileReferences(job)) {
    const std::string bytes = ReadText(jobDir.File(ref.relativePath));
    const v1::Digest digest = DigestOf(bytes);
    blobDir.Write(digest.hash(), bytes);
    ASSERT_TRUE(ReplaceFileWithBlob(ref, digest, &uploaded).ok());
  }
  EXPECT_TRUE(uploaded.scene().meshes(0).file().empty());
  EXPECT_EQ(uploaded.scene().meshes(0).format(), "obj");
  EXPECT_EQ(uploaded.scene().meshes(0).blob().hash(), Sha256Hex(room));
  EXPECT_TRUE(ListFileReferences(uploaded).empty());

  const absl::StatusOr<BakeJob> local = BuildBakeJob(job, LocalAssetSource(jobDir.path()), {});
  const absl::StatusOr<BakeJob> remote =
      BuildBakeJob(uploaded, LocalAssetSource("", blobDir.path()), {});
  ASSERT_TRUE(local.ok()) << local.status();
  ASSERT_TRUE(remote.ok()) << remote.status();
  EXPECT_EQ(local->sceneDigest, remote->sceneDigest);
  EXPECT_EQ(local->jobDigest, remote->jobDigest);
  EXPECT_EQ(local->scene.meshes[0].positions, remote->scene.meshes[0].positions);

  // Without a blob folder, a local bake refuses blob references.
  EXPECT_TRUE(HasFieldError(BuildBakeJob(uploaded, LocalAssetSource(jobDir.path()), {}).status(),
                            "scene.meshes[0].blob", "blob references need a blob store"));
  // A stale reference is not rewritten.
  EXPECT_TRUE(HasFieldError(ReplaceFileWithBlob(refs[0], DigestOf("x"), &uploaded),
                            "scene.meshes[0].file", "no file reference"));
}

TEST(LocalAssetSource, BlobChecks) {
  TempDir blobs;
  const v1::Digest digest = DigestOf("mesh bytes");
  const LocalAssetSource source("", blobs.path());
  const absl::Status missing = source.ReadBlob(digest, "scene.meshes[0].blob").status();
  EXPECT_EQ(missing.code(), absl::StatusCode::kFailedPrecondition) << missing;
  EXPECT_NE(
      std::string(missing.message()).find("scene.meshes[0].blob: missing blob " + digest.hash()),
      std::string::npos)
      << missing;
  blobs.Write(digest.hash(), "other bytes");
  EXPECT_TRUE(HasFieldError(source.ReadBlob(digest, "scene.meshes[0].blob").status(),
                            "scene.meshes[0].blob", "does not match its digest"));
  blobs.Write(digest.hash(), "mesh bytes");
  const absl::StatusOr<std::string> bytes = source.ReadBlob(digest, "scene.meshes[0].blob");
  ASSERT_TRUE(bytes.ok()) << bytes.status();
  EXPECT_EQ(*bytes, "mesh bytes");
}

TEST(LocalAssetSource, FileSizeLimit) {
  TempDir dir;
  dir.Write("big.obj", std::string(2000, '#'));
  const LocalAssetSource source(dir.path(), "", 1000);
  EXPECT_TRUE(HasFieldError(source.ReadFile("big.obj", "scene.meshes[2].file").status(),
                            "scene.meshes[2].file", "2000 bytes, above the limit of 1000"));
  EXPECT_TRUE(HasFieldError(source.ReadFile(".", "scene.meshes[2].file").status(),
                            "scene.meshes[2].file", "not a regular file"));
}

}  // namespace
}  // namespace probebake
