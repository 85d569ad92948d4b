// Light sampling consistency: MIS is unbiased only if the pdf a light reports when sampled equals
// the pdf recomputed when a direction-sampled ray finds the same light. Also the environment map's
// pixel mapping against OpenEXR's own Imf::LatLongMap, and its pdf's normalisation.
#include <gtest/gtest.h>

#include <OpenEXR/ImfEnvmap.h>

#include <cmath>

#include "bake_test_util.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

using namespace probebake::testing;

Scene ManyLights() {
  Scene scene;
  const uint32_t grey = AddMaterial(&scene, {0.5, 0.5, 0.5});
  const uint32_t lamp = AddMaterial(&scene, {0, 0, 0}, {3, 2, 1});
  AddQuad(&scene, {-4, -4, -1}, {4, -4, -1}, {4, 4, -1}, {-4, 4, -1}, grey);
  AddQuad(&scene, {1, 1, 2}, {1.5, 1, 2.2}, {1.5, 1.5, 2.2}, {1, 1.5, 2}, lamp);  // faces ~down? no
  AddQuad(&scene, {-1, 1, 2}, {-1, 1.5, 2}, {-1.5, 1.5, 2}, {-1.5, 1, 2}, lamp);
  // 4 m^2 at 1 to 2 m above the shading points: sampled by solid angle from the points near it,
  // by area from the others (area_emitters.cpp's threshold, area / d^2 = 1).
  scene.lights.push_back(RectLight{{-1, -2.5, 1.5}, {0, 2, 0}, {2, 0, 0}, {4, 4, 4}, false});
  scene.lights.push_back(RectLight{{2, -2, 0.5}, {0.5, 0, 0.3}, {0.2, 0.6, 0}, {1, 1, 1}, true});
  scene.lights.push_back(
      DiskLight{{-2, -1, 1.2}, Normalize(Vec3d{0.2, 0, -1}), 0.4, {2, 2, 2}, true});
  scene.lights.push_back(SphereLight{{2, 2, 0.5}, 0.3, {5, 5, 5}});
  scene.lights.push_back(
      DirectionalLight{Normalize(Vec3d{0.3, 0.2, -1}), {2, 2, 2}, std::cos(0.1)});
  scene.lights.push_back(PointLight{{0, 0, 3}, {1, 1, 1}});
  scene.environment = {Environment::Kind::kUniform, {0.1, 0.1, 0.1}, nullptr};
  return scene;
}

// treeMinLights = 1: every finite light is chosen through a light tree.
void ExpectSampledPdfsEqualThePdfsOfTheRaysThatFindTheLights(size_t treeMinLights) {
  const Scene scene = ManyLights();
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  const LightSet lights(scene, **tracer, treeMinLights);
  if (treeMinLights == 1) {
    ASSERT_EQ(lights.TreeLightCount(), 7u);
  }
  std::vector<double> importance(lights.ImportanceSize());
  SobolSampler sampler(3, 4);
  int checked = 0, escapedChecked = 0;
  for (int i = 0; i < 4000; ++i) {
    sampler.StartSample(i);
    // A shading point above the floor, with and without a surface normal.
    const Vec2d a = sampler.Get2D();
    const Vec3d p = Vec3d{-3 + 6 * a.x, -3 + 6 * a.y, -0.5 + sampler.Get1D()} - (*tracer)->offset();
    const Vec3d nStorage = Normalize(Vec3d{0.1, -0.2, 1});
    const Vec3d* n = (i % 2) ? &nStorage : nullptr;
    const double total = lights.Importance(p, n, /*includeDelta=*/true, importance);
    ASSERT_GT(total, 0);
    LightSample s;
    if (!lights.Sample(p, n, importance, total, sampler.Get1D(), sampler.Get2D(), &s) || s.delta)
      continue;
    SurfaceHit hit;
    const Vec3f origin(p);
    if ((*tracer)->Intersect(origin, s.wi, std::numeric_limits<double>::infinity(), &hit)) {
      // Another surface in front of the sampled point: nothing to compare.
      if (!std::isfinite(s.distance) || hit.t < s.distance * (1 - 1e-4)) continue;
      LightHit h;
      ASSERT_TRUE(lights.EvalSurfaceHit(p, n, importance, total, s.wi, hit, &h))
          << "sample " << i << " light " << s.light;
      ASSERT_EQ(h.light, s.light);
      // Same formula from a float hit distance and a double one. Embree's distance t is off the
      // double one by the float rounding of the light's plane and of the origin (a few 2^-24 of
      // coordinates up to ~4 here), divided by the cosine at the light: the pdf's d^2 doubles
      // that. So 1e-5 where the ray meets the light square on, more at grazing angles (a sample
      // at cos 9e-4 read 6e-5).
      const double cosLight = std::abs(Dot(s.wi, hit.ng));
      const double grazing = 2 * (8 * 0x1p-24 * 4) / (hit.t * cosLight);
      EXPECT_NEAR(h.pdf, s.pdf, (1e-5 + grazing) * s.pdf) << "sample " << i << " light " << s.light;
      EXPECT_EQ(h.radiance, s.radiance);
      ++checked;
    } else {
      ASSERT_FALSE(std::isfinite(s.distance)) << "a finite light sample found nothing";
      double pdf = 0;
      lights.ForEachEscaped(n, importance, total, s.wi, [&](const LightHit& h) {
        if (h.light == s.light) pdf = h.pdf;
      });
      EXPECT_NEAR(pdf, s.pdf, 1e-9 * s.pdf) << "sample " << i << " light " << s.light;
      ++escapedChecked;
    }
  }
  EXPECT_GT(checked, 500);
  EXPECT_GT(escapedChecked, 100);
}

TEST(LightSet, SampledPdfEqualsThePdfOfTheRayThatFindsTheLight) {
  ExpectSampledPdfsEqualThePdfsOfTheRaysThatFindTheLights(kLightTreeMinLights);
}

TEST(LightSet, SampledPdfEqualsThePdfOfTheRayThatFindsTheLightThroughLightTrees) {
  ExpectSampledPdfsEqualThePdfsOfTheRaysThatFindTheLights(1);
}

TEST(EnvironmentLight, CellsFollowImfLatLongMap) {
  // The pixel our lookup picks for a direction is the nearest one to LatLongMap's continuous
  // position of that direction (float library vs double code: compare away from cell borders).
  auto map = std::make_shared<EnvironmentMap>();
  map->width = 24;
  map->height = 12;
  map->rgb.resize(3 * 24 * 12);
  for (size_t k = 0; k < 24 * 12; ++k) map->rgb[3 * k] = float(k + 1);  // red = pixel index + 1
  Environment env{Environment::Kind::kMap, {}, map};
  const EnvironmentLight light(env);
  const Imath::Box2i window({0, 0}, {23, 11});
  SobolSampler sampler(1, 2);
  int compared = 0;
  for (int i = 0; i < 2000; ++i) {
    sampler.StartSample(i);
    const Vec3d w = SampleUniformSphere(sampler.Get2D());
    const Imath::V2f pos = Imf::LatLongMap::pixelPosition(window, Imath::V3f(w.x, w.y, w.z));
    const double fx = pos.x - std::floor(pos.x), fy = pos.y - std::floor(pos.y);
    if (std::abs(fx - 0.5) < 1e-3 || std::abs(fy - 0.5) < 1e-3) continue;
    const int ix = int(std::lround(pos.x)), iy = int(std::lround(pos.y));
    EXPECT_EQ(light.Radiance(w).x, double(iy * 24 + ix + 1)) << w;
    ++compared;
  }
  EXPECT_GT(compared, 1900);
}

// A w x h map of grey levels 1 to 13 in a hashed pattern, rotated off the axes.
std::shared_ptr<const EnvironmentMap> GreyNoiseMap(int w, int h) {
  auto map = std::make_shared<EnvironmentMap>();
  map->width = w;
  map->height = h;
  map->rgb.resize(3 * size_t(w) * h);
  for (size_t k = 0; k < size_t(w) * h; ++k)
    map->rgb[3 * k] = map->rgb[3 * k + 1] = map->rgb[3 * k + 2] = float(1 + (k * 7919) % 13);
  map->worldFromMap = Mat3d::Rotation(Normalize(Vec3d{1, 2, 3}), 0.4);
  return map;
}

TEST(EnvironmentLight, PdfIntegratesToOneAndMatchesSampling) {
  const std::shared_ptr<const EnvironmentMap> map = GreyNoiseMap(16, 8);
  const EnvironmentLight light({Environment::Kind::kMap, {}, map});
  // Integral of the pdf over the sphere by a fine product rule: the pdf is piecewise constant, so
  // the rule's error comes from cells cut by its nodes: O(1/n) with n = 2048 -> < 1e-2.
  const auto rule = SphereProductQuadrature(1024, 2048);
  double integral = 0;
  for (const auto& node : rule) integral += node.weight * light.Pdf(node.direction, nullptr);
  EXPECT_NEAR(integral, 1.0, 1e-2);
  // Sampled directions report the pdf and radiance of the cell they land in.
  SobolSampler sampler(5, 6);
  for (int i = 0; i < 1000; ++i) {
    sampler.StartSample(i);
    Vec3d wi;
    double pdf = 0;
    const Vec3d radiance = light.Sample(sampler.Get2D(), nullptr, &wi, &pdf);
    EXPECT_NEAR(Length(wi), 1.0, 1e-12);
    EXPECT_NEAR(light.Pdf(wi, nullptr), pdf, 1e-9 * pdf);
    EXPECT_EQ(light.Radiance(wi), radiance);
  }
}

// Given a normal, Sample rejects (pdf 0) exactly the samples below the surface it can tell from
// their row or cell; every other sample is the one drawn without a normal, the same bits. (The
// cell test without its radius, or the row test's maximum taken at the band's middle, fails.)
TEST(EnvironmentLight, SamplesBelowTheSurfaceAreRejectedEarlyAndOnlyThey) {
  const std::shared_ptr<const EnvironmentMap> map = GreyNoiseMap(32, 16);
  const EnvironmentLight light({Environment::Kind::kMap, {}, map});
  std::vector<Vec3d> normals;
  for (int a = 0; a < 3; ++a) {
    for (double sign : {-1.0, 1.0}) {
      Vec3d axis;
      axis[a] = sign;
      normals.push_back(map->worldFromMap * axis);  // the map's poles and horizon, exactly
    }
  }
  SobolSampler normalSampler(7, 8), sampler(5, 6);
  for (int i = 0; i < 500; ++i) {
    normalSampler.StartSample(i);
    normals.push_back(SampleUniformSphere(normalSampler.Get2D()));
  }
  int rejected = 0, kept = 0, nearHorizon = 0;
  for (const Vec3d& n : normals) {
    for (int i = 0; i < 400; ++i) {
      sampler.StartSample(i);
      const Vec2d u = sampler.Get2D();
      Vec3d wiSphere, wiSurface;
      double pdfSphere = 0, pdfSurface = 0;
      const Vec3d radianceSphere = light.Sample(u, nullptr, &wiSphere, &pdfSphere);
      const Vec3d radianceSurface = light.Sample(u, &n, &wiSurface, &pdfSurface);
      ASSERT_GT(pdfSphere, 0);
      nearHorizon += std::abs(Dot(wiSphere, n)) < 0.05;
      if (pdfSurface == 0) {
        ASSERT_LE(Dot(wiSphere, n), 0) << "n " << n << " wi " << wiSphere;
        ++rejected;
      } else {
        ASSERT_EQ(pdfSurface, pdfSphere);
        ASSERT_EQ(wiSurface, wiSphere);
        ASSERT_EQ(radianceSurface, radianceSphere);
        ++kept;
      }
    }
  }
  // About half the sphere lies below each normal, less the cells the horizon cuts.
  const int total = rejected + kept;
  EXPECT_GT(rejected, total / 3);
  EXPECT_GT(kept, total / 3);
  EXPECT_GT(nearHorizon, total / 100);
}

}  // namespace
}  // namespace probebake
