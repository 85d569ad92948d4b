// Materials that vary over a surface (textures, vertex colours), baked against closed forms and
// equivalences: a constant texture is its colour, a fine checker far away is its mean, an emission
// map weights the emitted radiance point by point. Tolerances as in bake_test_util.h.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>

#include "bake_test_util.h"
#include "core/src/bake/surface_material.h"

namespace probebake {
namespace {

using namespace probebake::testing;

const Vec3d kSky{0.2, 0.5, 1.0};
const Vec3d kUp{0, 0, 1}, kDown{0, 0, -1};

// IEC 61966-2-1, written out here independently of the baker's table.
double Srgb(int value) {
  const double c = value / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

std::shared_ptr<const Texture> MakeTexture(int width, int height, std::vector<uint8_t> rgba) {
  auto t = std::make_shared<Texture>();
  t->name = "test.png";
  t->width = width;
  t->height = height;
  t->rgba = std::move(rgba);
  for (size_t k = 3; k < t->rgba.size(); k += 4) t->hasAlpha = t->hasAlpha || t->rgba[k] != 255;
  return t;
}

// A quad a b c d (counter-clockwise seen from the front) whose corners read the image coordinates
// (0, 0), (s, 0), (s, s), (0, s) of every map of its material (a repeat of s times the image).
void AddMappedQuad(Scene* scene, Vec3d a, Vec3d b, Vec3d c, Vec3d d, uint32_t material, float s) {
  AddQuad(scene, a, b, c, d, material);
  TriangleMesh& m = scene->meshes.back();
  const std::vector<std::array<float, 2>> uv = {{0, 0}, {s, 0}, {s, s}, {0, s}};
  const Material& mat = scene->materials[material];
  if (mat.albedoMap.image) m.albedoUv = uv;
  if (mat.emissionMap.image) m.emissionUv = uv;
  if (mat.coverageMap.image) m.coverageUv = uv;
}

// The probe at height 1 over a ground of albedo rho under a uniform sky sees L above and rho L
// below (closed_form_test.cpp's WhiteGroundReflectsTheSkyOnce), up to the 1e6 ground's missing
// horizon.
void ExpectGround(const ProbeResult& r, const Vec3d& rho, double horizon, const std::string& what) {
  const std::vector<double> up = CapProjection(3, kUp, 0), down = CapProjection(3, kDown, 0);
  for (int ch = 0; ch < 3; ++ch) {
    std::vector<double> expected(up.size());
    for (size_t c = 0; c < up.size(); ++c)
      expected[c] = up[c] * kSky[ch] + down[c] * rho[ch] * kSky[ch];
    Vec3d unit;
    unit[ch] = 1;
    ProbeResult channel = r;
    for (size_t c = 0; c < up.size(); ++c) {
      for (int k = 0; k < 3; ++k)
        if (k != ch) channel.radiance[c][k] = 0, channel.stdError[c][k] = 0;
    }
    // The missing horizon: a band of solid angle 2 pi horizon at most, radiance <= the sky's.
    ExpectProjection(channel, expected, unit, what + " channel " + std::to_string(ch),
                     2 * kPi * horizon * 1.5);
  }
}

TEST(AuthoredMaterials, AConstantTextureIsItsColour) {
  // Texel (200, 120, 30) sRGB under an albedo factor 0.9: rho = 0.9 srgb(texel).
  BakeJob job = MakeJob(3, 4096, {0, 0, 1});
  job.scene.environment = {Environment::Kind::kUniform, kSky, nullptr};
  const uint32_t m = AddMaterial(&job.scene, {0.9, 0.9, 0.9});
  job.scene.materials[m].albedoMap.image = MakeTexture(1, 1, {200, 120, 30, 255});
  const double s = 1e6;
  AddMappedQuad(&job.scene, {-s, -s, 0}, {s, -s, 0}, {s, s, 0}, {-s, s, 0}, m, 3.5f);
  const Vec3d rho = Vec3d(Srgb(200), Srgb(120), Srgb(30)) * 0.9;
  ExpectGround(Probe(BakeOrDie(job), 0), rho, 1e-6, "constant texture");
}

TEST(AuthoredMaterials, AFineCheckerFarAwayAveragesAsItsMean) {
  // A 2 x 2 checker repeated every 0.1 units over a 400-unit square under a probe at height 10,
  // the rest of the ground at the checker's mean albedo: bilinear filtering with repeat keeps the
  // mean of the texels, and 10 units up the cells are far below what order 3 resolves.
  const int A[3] = {230, 40, 10}, B[3] = {20, 180, 250};
  BakeJob job = MakeJob(3, 4096, {0, 0, 10});
  job.scene.environment = {Environment::Kind::kUniform, kSky, nullptr};
  const Vec3d mean =
      (Vec3d(Srgb(A[0]), Srgb(A[1]), Srgb(A[2])) + Vec3d(Srgb(B[0]), Srgb(B[1]), Srgb(B[2]))) * 0.5;
  const uint32_t checker = AddMaterial(&job.scene, {1, 1, 1});
  job.scene.materials[checker].albedoMap.image =
      MakeTexture(2, 2,
                  {uint8_t(A[0]), uint8_t(A[1]), uint8_t(A[2]), 255, uint8_t(B[0]), uint8_t(B[1]),
                   uint8_t(B[2]), 255, uint8_t(B[0]), uint8_t(B[1]), uint8_t(B[2]), 255,
                   uint8_t(A[0]), uint8_t(A[1]), uint8_t(A[2]), 255});
  const uint32_t plain = AddMaterial(&job.scene, mean);
  const double c = 200, s = 1e7;
  AddMappedQuad(&job.scene, {-c, -c, 0}, {c, -c, 0}, {c, c, 0}, {-c, c, 0}, checker,
                float(2 * c / 0.1));
  // The ring around it: four quads sharing the square's edges.
  AddQuad(&job.scene, {-s, -s, 0}, {s, -s, 0}, {c, -c, 0}, {-c, -c, 0}, plain);
  AddQuad(&job.scene, {s, -s, 0}, {s, s, 0}, {c, c, 0}, {c, -c, 0}, plain);
  AddQuad(&job.scene, {s, s, 0}, {-s, s, 0}, {-c, c, 0}, {c, c, 0}, plain);
  AddQuad(&job.scene, {-s, s, 0}, {-s, -s, 0}, {-c, -c, 0}, {-c, c, 0}, plain);
  ExpectGround(Probe(BakeOrDie(job), 0), mean, 10 / s, "checker mean");
}

TEST(AuthoredMaterials, VertexColoursMultiplyTheAlbedo) {
  BakeJob job = MakeJob(3, 4096, {0, 0, 1});
  job.scene.environment = {Environment::Kind::kUniform, kSky, nullptr};
  const uint32_t m = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
  job.scene.materials[m].vertexColors = true;
  const double s = 1e6;
  AddQuad(&job.scene, {-s, -s, 0}, {s, -s, 0}, {s, s, 0}, {-s, s, 0}, m);
  job.scene.meshes.back().colors.assign(4, {0.8f, 0.4f, 1.0f, 1.0f});
  ExpectGround(Probe(BakeOrDie(job), 0), Vec3d(0.8f, 0.4f, 1.0f) * 0.5, 1e-6, "vertex colours");
}

TEST(AuthoredMaterials, AnEmissionMapWeightsTheRadiancePointByPoint) {
  // An emissive quad above the probe whose 2 x 1 emission map (clamped) is black on its first
  // texel and white on its second: bilinear between the texel centres at x = 1/4 and 3/4, so the
  // radiance is 0 for x < 1/4, rises linearly to L at 3/4 and stays L after.
  const Vec3d L{3, 2, 1};
  const Vec3d corner{-0.6, -0.5, 0.7}, e1{0, 1, 0}, e2{1.2, 0, 0};  // e1 x e2 = -z: faces down
  BakeJob job = MakeJob(3, 8192);
  const uint32_t m = AddMaterial(&job.scene, {}, L);
  TextureMap& map = job.scene.materials[m].emissionMap;
  map.image = MakeTexture(2, 1, {0, 0, 0, 255, 255, 255, 255, 255});
  map.wrapX = map.wrapY = TextureWrap::kClamp;
  // Corners a, a + e1, a + e1 + e2, a + e2 (counter-clockwise from below) read x along e2.
  AddQuad(&job.scene, corner, corner + e1, corner + e1 + e2, corner + e2, m);
  job.scene.meshes.back().emissionUv = {{0, 0}, {0, 0}, {1, 0}, {1, 0}};
  const auto weight = [&](const Vec3d& q) {
    const double x = Dot(q - corner, e2) / LengthSquared(e2);
    return std::clamp((x - 0.25) / 0.5, 0.0, 1.0);
  };
  // Integrated piecewise (the rule is exact to ~1e-12 on smooth pieces only): the ramp and the
  // white quarter.
  std::vector<double> expected =
      WeightedParallelogramProjection(3, {}, corner + e2 * 0.25, e1, e2 * 0.5, weight);
  const std::vector<double> white =
      ParallelogramProjection(3, {}, corner + e2 * 0.75, e1, e2 * 0.25);
  for (size_t c = 0; c < expected.size(); ++c) expected[c] += white[c];
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, expected, L, "emission map");
}

// Whether two volumes hold the same bits in every coefficient of every probe.
::testing::AssertionResult SameBits(const ProbeVolume& a, const ProbeVolume& b) {
  if (a.CoeffCount() != b.CoeffCount()) return ::testing::AssertionFailure() << "orders differ";
  for (int c = 0; c < a.CoeffCount(); ++c) {
    if (a.radiance[c] != b.radiance[c])
      return ::testing::AssertionFailure() << "coefficient " << c << " differs";
  }
  if (a.stdError != b.stdError || a.validity != b.validity)
    return ::testing::AssertionFailure() << "errors or validity differ";
  return ::testing::AssertionSuccess();
}

// A closed grey room (inward faces) lit by a point light and a small rect light, a probe at its
// centre: the room fixes the scene's bounds (and so the tracer's coordinates) whatever is added
// inside it.
BakeJob Room() {
  BakeJob job = MakeJob(3, 1024, {0, 0, 0});
  job.settings.batches = 8;
  const uint32_t grey = AddMaterial(&job.scene, {0.6, 0.5, 0.4});
  AddBox(&job.scene, {-2, -2, -2}, {2, 2, 2}, grey, /*inward=*/true);
  job.scene.lights.push_back(PointLight{{0.3, 0.2, 1.5}, {5, 5, 5}});
  job.scene.lights.push_back(
      RectLight{{-0.2, -0.2, 1.8}, {0.4, 0, 0}, {0, 0.4, 0}, {8, 8, 8}, true});
  return job;
}

// A cutout quad between the probe and the lights, its coverage `alpha` everywhere.
void AddCutoutQuad(BakeJob* job, double alpha) {
  const uint32_t m = AddMaterial(&job->scene, {0.7, 0.7, 0.7});
  job->scene.materials[m].coverage = alpha;
  job->scene.materials[m].alphaCutoff = 0.5;
  AddQuad(&job->scene, {-1, -1, 0.8}, {1, -1, 0.8}, {1, 1, 0.8}, {-1, 1, 0.8}, m);
}

TEST(AuthoredMaterials, AlphaZeroBakesBitIdenticallyToTheSceneWithoutTheQuad) {
  const BakeJob without = Room();
  BakeJob with = Room();
  AddCutoutQuad(&with, 0);
  EXPECT_TRUE(SameBits(BakeOrDie(without), BakeOrDie(with)));
  // A coverage map of zeros too (the texture path), and vertex alpha.
  BakeJob mapped = Room();
  AddCutoutQuad(&mapped, 1);
  mapped.scene.materials.back().albedoMap.image = MakeTexture(1, 1, {255, 255, 255, 0});
  mapped.scene.meshes.back().albedoUv.assign(4, {0.5f, 0.5f});
  EXPECT_TRUE(SameBits(BakeOrDie(without), BakeOrDie(mapped)));
}

TEST(AuthoredMaterials, AlphaOneIsOpaque) {
  // The same quad without a cutout, then with full coverage: the same bits; and it does block.
  BakeJob opaque = Room();
  AddCutoutQuad(&opaque, 1);
  opaque.scene.materials.back().alphaCutoff = 0;
  BakeJob covered = Room();
  AddCutoutQuad(&covered, 1);
  const ProbeVolume a = BakeOrDie(opaque);
  EXPECT_TRUE(SameBits(a, BakeOrDie(covered)));
  EXPECT_FALSE(SameBits(a, BakeOrDie(Room())));
}

TEST(AuthoredMaterials, AHalfCheckerMaskPassesHalfTheLight) {
  // A small rect light above the probe seen through a mask quad whose alpha is a 2 x 2 checker of
  // 0 and 255 repeated every 1e-4 units: where bilinear filtering puts the alpha below the 0.5
  // cutoff is exactly half of each period (f and 1 - f swap under a shift by one texel), and the
  // light's footprint on the mask spans hundreds of periods, so half of its light passes.
  const Vec3d L{4, 3, 2};
  const Vec3d corner{-0.1, -0.1, 1}, e1{0.2, 0, 0}, e2{0, 0.2, 0};
  BakeJob job = MakeJob(2, 16384);
  job.scene.lights.push_back(RectLight{corner, e1, e2, L, true});
  const uint32_t m = AddMaterial(&job.scene, {});
  job.scene.materials[m].alphaCutoff = 0.5;
  job.scene.materials[m].albedoMap.image =
      MakeTexture(2, 2, {0, 0, 0, 0, 0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 0});
  AddMappedQuad(&job.scene, {-0.5, -0.5, 0.5}, {0.5, -0.5, 0.5}, {0.5, 0.5, 0.5}, {-0.5, 0.5, 0.5},
                m, 1e4f);
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, ParallelogramProjection(2, {}, corner, e1, e2), L * 0.5, "half mask");
}

TEST(AuthoredMaterials, ADoubleSidedPlaneBesideAProbeLeavesItValid) {
  // A large plane 0.1 beside the probe, its back towards it: about half of the validity rays hit
  // its back, above a backface fraction of 0.25, unless it is double-sided.
  for (const bool doubleSided : {false, true}) {
    BakeJob job = MakeJob(1, 64, {0, 0, 0});
    job.grid.placement = Placement::kOutsideGeometry;
    job.settings.backfaceFraction = 0.25;
    job.scene.environment = {Environment::Kind::kUniform, kSky, nullptr};
    const uint32_t m = AddMaterial(&job.scene, {0.5, 0.5, 0.5});
    job.scene.materials[m].doubleSided = doubleSided;
    const double s = 100;  // front +x: away from the probe
    AddQuad(&job.scene, {0.1, -s, -s}, {0.1, s, -s}, {0.1, s, s}, {0.1, -s, s}, m);
    const ProbeVolume v = BakeOrDie(job);
    EXPECT_EQ(v.validity[0], doubleSided ? 1.0f : 0.0f) << doubleSided;
  }
}

TEST(AuthoredMaterials, ADoubleSidedEmitterEmitsFromBothSides) {
  const Vec3d L{4, 3, 2};
  const Vec3d corner{-0.3, -0.6, 0.8}, e1{1, 0, 0}, e2{0, 1.5, 0};  // e1 x e2 = +z: faces away
  BakeJob job = MakeJob(3, 8192);
  const uint32_t m = AddMaterial(&job.scene, {}, L);
  AddQuad(&job.scene, corner, corner + e1, corner + e1 + e2, corner + e2, m);
  for (const Vec3d& c : Probe(BakeOrDie(job), 0).radiance) EXPECT_EQ(MaxComponent(Abs(c)), 0.0);
  job.scene.materials[m].doubleSided = true;
  ExpectProjection(Probe(BakeOrDie(job), 0), ParallelogramProjection(3, {}, corner, e1, e2), L,
                   "double-sided emitter");
}

TEST(AuthoredMaterials, TextureSamplingWrapsAndDecodes) {
  TextureMap map;
  map.image = MakeTexture(2, 1, {0, 0, 0, 0, 255, 255, 255, 255});
  // Texel centres at x = 1/4 and 3/4; halfway between them, half of each (alpha is linear).
  EXPECT_DOUBLE_EQ(SampleTexture(map, 0.5, 0.5)[0], 0.5 * Srgb(255));
  EXPECT_DOUBLE_EQ(SampleTexture(map, 0.5, 0.5)[3], 0.5);
  // Repeat: x = 0 lies between the last texel and the first.
  EXPECT_DOUBLE_EQ(SampleTexture(map, 0.0, 0.5)[3], 0.5);
  EXPECT_DOUBLE_EQ(SampleTexture(map, 1.25, 0.5)[3], 0.0);
  map.wrapX = TextureWrap::kClamp;
  EXPECT_DOUBLE_EQ(SampleTexture(map, 0.0, 0.5)[3], 0.0);
  EXPECT_DOUBLE_EQ(SampleTexture(map, 1e30, 0.5)[3], 1.0);
  map.wrapX = TextureWrap::kMirror;
  EXPECT_DOUBLE_EQ(SampleTexture(map, 1.25, 0.5)[3], 1.0);  // mirrored: the second texel
  EXPECT_DOUBLE_EQ(SampleTexture(map, -0.25, 0.5)[3], 0.0);
  // sRGB decoding of a mid grey, and none for a linear map.
  map.image = MakeTexture(1, 1, {128, 128, 128, 255});
  EXPECT_NEAR(SampleTexture(map, 0.3, 0.3)[0], 0.2158605, 1e-6);
  map.srgb = false;
  EXPECT_DOUBLE_EQ(SampleTexture(map, 0.3, 0.3)[0], 128 / 255.0);
  EXPECT_EQ(SampleTexture(map, std::nan(""), 0.5)[0], 128 / 255.0);
}

}  // namespace
}  // namespace probebake
