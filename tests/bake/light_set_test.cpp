// Light sampling consistency through LightSet's choice: MIS is unbiased only if the pdf a light
// reports when sampled equals the pdf recomputed when a direction-sampled ray finds the same light.
#include <gtest/gtest.h>

#include <cmath>

#include "bake_test_util.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/sampling/sampler.h"

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
      lights.ForEachEscaped(p, n, importance, total, s.wi, [&](const LightHit& h) {
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

TEST(LightSet, ScaleAtSurfacesScalesASurfacesChoiceAndNotTheProbes) {
  // RoomWithOpening's lights: the rect light (0), the sun (1), the sky. A sun scaled by 0.1 at
  // surfaces keeps its importance at a probe (no normal) and has a tenth of it at a surface, and
  // the choice's pmf there follows.
  const Scene scene = RoomWithOpening();
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  LightSet lights(scene, **tracer);
  const Vec3d p{0.5, 1.5, 1}, n{0, 0, 1};
  std::vector<double> atProbe(lights.ImportanceSize()), atSurface(lights.ImportanceSize());
  std::vector<double> probeScaled(atProbe.size()), surfaceScaled(atSurface.size());
  lights.Importance(p, nullptr, /*includeDelta=*/true, atProbe);
  const double total = lights.Importance(p, &n, /*includeDelta=*/true, atSurface);
  ASSERT_GT(atSurface[1], 0);
  lights.ScaleAtSurfaces(1, 0.1);
  lights.Importance(p, nullptr, /*includeDelta=*/true, probeScaled);
  const double scaledTotal = lights.Importance(p, &n, /*includeDelta=*/true, surfaceScaled);
  EXPECT_EQ(probeScaled, atProbe);
  EXPECT_EQ(surfaceScaled[1], atSurface[1] * 0.1);
  EXPECT_EQ(surfaceScaled[0], atSurface[0]);
  EXPECT_DOUBLE_EQ(scaledTotal, total - 0.9 * atSurface[1]);
  EXPECT_DOUBLE_EQ(lights.SelectionPmf(1, p, &n, surfaceScaled, scaledTotal),
                   surfaceScaled[1] / scaledTotal);
}

}  // namespace
}  // namespace probebake
