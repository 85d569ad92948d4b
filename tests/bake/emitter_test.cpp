// Each light kind alone (core/src/bake/emitter.h's contract), without LightSet's choice: a sample's
// pdf and radiance are what the ray along it finds (EvalHit, EvalEscaped), importance is 0 only
// where no sample can light the surface, sampled points lie in the light-tree bounds, and the tree
// weight is importance's numerator; the delta kinds' weights and cones.
#include "core/src/bake/emitter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bake_test_util.h"
#include "core/src/bake/environment_light.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/sampling/sampler.h"

namespace probebake {
namespace {

using namespace probebake::testing;

constexpr double kInf = std::numeric_limits<double>::infinity();

// One light alone in a scene, as the bake builds it: its emitter and the tracer that finds it.
struct LoneLight {
  Scene scene;
  std::unique_ptr<TracerScene> tracer;
  std::unique_ptr<EnvironmentLight> environment;
  std::optional<Emitter> emitter;
};

// `make` builds the emitter once the tracer exists.
std::unique_ptr<LoneLight> Build(Scene scene,
                                 const std::function<Emitter(const LoneLight&)>& make) {
  auto light = std::make_unique<LoneLight>();
  light->scene = std::move(scene);
  auto tracer = TracerScene::Build(light->scene, LocalOrigin(light->scene));
  EXPECT_TRUE(tracer.ok()) << tracer.status();
  light->tracer = std::move(*tracer);
  light->environment = std::make_unique<EnvironmentLight>(light->scene.environment);
  light->emitter.emplace(make(*light));
  return light;
}

template <typename Kind, typename SceneLight>
std::unique_ptr<LoneLight> SceneLightAlone(const SceneLight& l) {
  Scene scene;
  scene.lights.push_back(l);
  return Build(scene, [](const LoneLight& lone) {
    const SceneLight& sl = std::get<SceneLight>(lone.scene.lights[0]);
    if constexpr (std::is_constructible_v<Kind, const SceneLight&, const Vec3d&>) {
      return Emitter(Kind(sl, lone.tracer->offset()));
    } else {
      return Emitter(Kind(sl));
    }
  });
}

std::unique_ptr<LoneLight> EmissiveMesh() {
  Scene scene;
  const uint32_t lamp = AddMaterial(&scene, {0, 0, 0}, {3, 2, 1});
  // Two triangles of different areas and orientations: a quad facing down, a smaller one tilted.
  AddQuad(&scene, {-0.5, -0.5, 1}, {-0.5, 0.5, 1}, {0.5, 0.5, 1}, {0.5, -0.5, 1}, lamp);
  AddQuad(&scene, {0.8, -0.2, 0.6}, {0.8, 0.2, 0.6}, {1.0, 0.2, 0.9}, {1.0, -0.2, 0.9}, lamp);
  return Build(scene, [](const LoneLight& lone) {
    std::optional<MeshEmitter> mesh = MeshEmitter::Build(lone.scene, *lone.tracer, 0);
    EXPECT_TRUE(mesh.has_value());
    return Emitter(std::move(*mesh));
  });
}

std::unique_ptr<LoneLight> LoneEnvironment(Environment::Kind kind) {
  Scene scene;
  if (kind == Environment::Kind::kUniform) {
    scene.environment = {kind, {0.3, 0.2, 0.1}, nullptr};
  } else {
    auto map = std::make_shared<EnvironmentMap>();
    map->width = 16;
    map->height = 8;
    map->rgb.resize(3 * 16 * 8);
    for (size_t k = 0; k < 16 * 8; ++k) map->rgb[3 * k] = map->rgb[3 * k + 1] = float(1 + k % 5);
    map->worldFromMap = Mat3d::Rotation(Normalize(Vec3d{1, 2, 3}), 0.4);
    scene.environment = {kind, {}, map};
  }
  return Build(
      scene, [](const LoneLight& lone) { return Emitter(EnvironmentEmitter(*lone.environment)); });
}

struct NamedLight {
  std::string name;
  std::unique_ptr<LoneLight> light;
};

// Every kind that is sampled (not delta), in the shapes that take different paths.
std::vector<NamedLight> SampledLights() {
  std::vector<NamedLight> lights;
  // A square over the shading points' box: sampled by solid angle near it, by area farther.
  lights.push_back({"rect one-sided", SceneLightAlone<RectEmitter>(RectLight{
                                          {-1, -1, 1.5}, {0, 2, 0}, {2, 0, 0}, {4, 4, 4}, false})});
  lights.push_back({"rect two-sided skewed",
                    SceneLightAlone<RectEmitter>(
                        RectLight{{0.5, -1, 0.2}, {0.6, 0, 0.3}, {0.2, 0.7, 0}, {1, 2, 3}, true})});
  lights.push_back({"disk one-sided",
                    SceneLightAlone<DiskEmitter>(DiskLight{
                        {-0.5, 0.5, 1.2}, Normalize(Vec3d{0.2, 0, -1}), 0.4, {2, 2, 2}, false})});
  lights.push_back({"disk two-sided", SceneLightAlone<DiskEmitter>(DiskLight{
                                          {0.5, 0, 0}, Vec3d{1, 0, 0}, 0.3, {1, 3, 2}, true})});
  lights.push_back(
      {"sphere", SceneLightAlone<SphereEmitter>(SphereLight{{0.3, 0.4, 0.5}, 0.3, {5, 4, 3}})});
  lights.push_back({"emissive mesh", EmissiveMesh()});
  lights.push_back({"sun", SceneLightAlone<SunEmitter>(DirectionalLight{
                               Normalize(Vec3d{0.3, 0.2, -1}), {2, 2, 2}, std::cos(0.1)})});
  lights.push_back({"uniform environment", LoneEnvironment(Environment::Kind::kUniform)});
  lights.push_back({"map environment", LoneEnvironment(Environment::Kind::kMap)});
  return lights;
}

// Shading points in a 3 m box around the lights, half with a surface normal.
struct ShadingPoint {
  Vec3d p, nStorage;
  bool hasNormal = false;
  const Vec3d* n() const { return hasNormal ? &nStorage : nullptr; }
};

ShadingPoint PointAt(SobolSampler& sampler, int i, const Vec3d& offset) {
  ShadingPoint s;
  const Vec2d a = sampler.Get2D(), b = sampler.Get2D();
  s.p = Vec3d{-1.5 + 3 * a.x, -1.5 + 3 * a.y, -1.5 + 3 * b.x} - offset;
  s.nStorage = SampleUniformSphere(sampler.Get2D());
  s.hasNormal = i % 2 == 1;
  return s;
}

void ExpectSamplesMatchTheirRays(const LoneLight& lone) {
  const Emitter& light = *lone.emitter;
  SobolSampler sampler(3, 4);
  int checked = 0;
  for (int i = 0; i < 3000; ++i) {
    sampler.StartSample(i);
    const ShadingPoint sp = PointAt(sampler, i, lone.tracer->offset());
    if (!(light.Importance(sp.p, sp.n()) > 0)) continue;
    LightSample s;
    if (!light.Sample(sp.p, sp.n(), sampler.Get2D(), &s)) continue;
    ASSERT_FALSE(s.delta);
    ASSERT_NEAR(Length(s.wi), 1, 1e-12);
    ASSERT_GT(s.pdf, 0);
    LightHit h;
    if (std::isfinite(s.distance)) {
      ASSERT_EQ(light.family(), EmitterFamily::kSurface);
      SurfaceHit hit;
      if (!lone.tracer->Intersect(Vec3f(sp.p), s.wi, kInf, &hit)) continue;  // grazing
      // The float origin can put the ray's hit elsewhere on a light seen edge-on.
      if (std::abs(hit.t - s.distance) > 1e-4 * s.distance) continue;
      ASSERT_TRUE(light.EvalHit(sp.p, s.wi, hit, /*pmf=*/1, &h)) << i;
      // Same formula from Embree's float distance and normal (light_set_test.cpp's tolerance).
      const double grazing = 2 * (8 * 0x1p-24 * 4) / (hit.t * std::abs(Dot(s.wi, hit.ng)));
      EXPECT_NEAR(h.pdf, s.pdf, (1e-5 + grazing) * s.pdf) << i;
    } else {
      ASSERT_EQ(light.family(), EmitterFamily::kDistant);
      ASSERT_TRUE(light.EvalEscaped(sp.p, s.wi, sp.n(), /*pmf=*/1, &h)) << i;
      EXPECT_NEAR(h.pdf, s.pdf, 1e-12 * s.pdf) << i;
    }
    EXPECT_EQ(h.radiance, s.radiance) << i;
    ++checked;
  }
  EXPECT_GT(checked, 500);
}

TEST(Emitter, ASamplesPdfAndRadianceAreWhatTheRayAlongItFinds) {
  for (const NamedLight& named : SampledLights()) {
    SCOPED_TRACE(named.name);
    ExpectSamplesMatchTheirRays(*named.light);
  }
}

// Importance may be 0 only where the light cannot contribute: every sample then fails or arrives
// from below the surface. Returns the number of such points.
int ExpectZeroImportanceOnlyWhereUnlit(const LoneLight& lone) {
  const Emitter& light = *lone.emitter;
  SobolSampler sampler(5, 6);
  int zero = 0;
  for (int i = 0; i < 3000; ++i) {
    sampler.StartSample(i);
    const ShadingPoint sp = PointAt(sampler, i, lone.tracer->offset());
    if (light.Importance(sp.p, sp.n()) > 0) continue;
    ++zero;
    for (int k = 0; k < 16; ++k) {
      LightSample s;
      if (!light.Sample(sp.p, sp.n(), sampler.Get2D(), &s)) continue;
      EXPECT_TRUE(sp.n() && Dot(s.wi, *sp.n()) <= 0)
          << "point " << i << " has importance 0 but sample " << k << " lights it";
    }
  }
  return zero;
}

TEST(Emitter, ImportanceIsZeroOnlyWhereNoSampleLightsTheSurface) {
  for (const NamedLight& named : SampledLights()) {
    SCOPED_TRACE(named.name);
    const int zero = ExpectZeroImportanceOnlyWhereUnlit(*named.light);
    // Every light but the environment has surfaces facing away from it.
    if (named.name.find("environment") == std::string::npos) {
      EXPECT_GT(zero, 0);
    }
  }
}

void ExpectTreeItemBoundsAndWeighs(const LoneLight& lone) {
  const Emitter& light = *lone.emitter;
  LightTree::Item item;
  if (light.family() == EmitterFamily::kDistant) {
    EXPECT_FALSE(light.TreeItem(&item)) << "lights at infinity stay in the linear choice";
    return;
  }
  ASSERT_TRUE(light.TreeItem(&item));
  const Vec3d slack = Vec3d{1, 1, 1} * 1e-12 * (1 + MaxComponent(Abs(item.hi - item.lo)));
  SobolSampler sampler(7, 8);
  for (int i = 0; i < 2000; ++i) {
    sampler.StartSample(i);
    const ShadingPoint sp = PointAt(sampler, i, lone.tracer->offset());
    LightSample s;
    if (!light.Sample(sp.p, nullptr, sampler.Get2D(), &s)) continue;
    for (int a = 0; a < 3; ++a) {
      ASSERT_GE(s.point[a], item.lo[a] - slack[a]) << i;
      ASSERT_LE(s.point[a], item.hi[a] + slack[a]) << i;
    }
  }
  // Far away on the emitting side, importance is W / d^2 to the bounds (light_tree.h).
  const Vec3d centre = (item.lo + item.hi) * 0.5;
  const Vec3d away = item.thetaO < 1 ? item.axis : Normalize(Vec3d{0.3, -0.4, 0.8});
  const Vec3d p = centre + away * 1e4;
  EXPECT_NEAR(light.Importance(p, nullptr), item.weight / LengthSquared(p - centre),
              1e-3 * item.weight / LengthSquared(p - centre));
}

TEST(Emitter, SampledPointsLieInTheTreeBoundsAndTheTreeWeightIsImportancesNumerator) {
  for (const NamedLight& named : SampledLights()) {
    SCOPED_TRACE(named.name);
    ExpectTreeItemBoundsAndWeighs(*named.light);
  }
}

TEST(Emitter, PointLightsWeighIntensityByInverseSquaredDistance) {
  const auto lone = SceneLightAlone<PointEmitter>(PointLight{{1, 2, 3}, {4, 5, 6}});
  const Emitter& light = *lone->emitter;
  const Vec3d at = Vec3d{1, 2, 3} - lone->tracer->offset();
  const Vec3d p = at - Vec3d{0, 0, 2};
  LightSample s;
  ASSERT_TRUE(light.EvalDelta(p, &s));
  EXPECT_TRUE(s.delta);
  EXPECT_EQ(s.pdf, 1);
  EXPECT_EQ(s.wi, (Vec3d{0, 0, 1}));
  EXPECT_EQ(s.distance, 2);
  EXPECT_EQ(s.radiance, (Vec3d{1, 1.25, 1.5}));
  const Vec3d up{0, 0, 1}, down{0, 0, -1};
  EXPECT_DOUBLE_EQ(light.Importance(p, &up), Luminance(Vec3d{4, 5, 6}) / 4);
  EXPECT_EQ(light.Importance(p, &down), 0);
  EXPECT_FALSE(light.EvalDelta(at, &s)) << "at the light itself";
}

TEST(Emitter, SpotLightsFallOffBetweenTheirConesAndAreDarkOutside) {
  const double cosInner = std::cos(0.2), cosOuter = std::cos(0.4);
  const auto lone =
      SceneLightAlone<SpotEmitter>(SpotLight{{0, 0, 2}, {0, 0, -1}, {3, 3, 3}, cosInner, cosOuter});
  const Emitter& light = *lone->emitter;
  const Vec3d apex = Vec3d{0, 0, 2} - lone->tracer->offset();
  // Points 2 m from the apex at angles 0.1 (inside the inner cone), 0.3 (between), 0.5 (outside).
  const auto at = [&](double angle) {
    return apex + Vec3d{std::sin(angle), 0, -std::cos(angle)} * 2.0;
  };
  LightSample s;
  ASSERT_TRUE(light.EvalDelta(at(0.1), &s));
  EXPECT_NEAR(s.radiance.x, 3.0 / 4, 1e-12);
  ASSERT_TRUE(light.EvalDelta(at(0.3), &s));
  EXPECT_GT(s.radiance.x, 0);
  EXPECT_LT(s.radiance.x, 3.0 / 4);
  EXPECT_NEAR(light.Importance(at(0.3), nullptr), Luminance(s.radiance), 1e-12);
  EXPECT_FALSE(light.EvalDelta(at(0.5), &s));
  EXPECT_EQ(light.Importance(at(0.5), nullptr), 0);
  LightTree::Item item;
  ASSERT_TRUE(light.TreeItem(&item));
  EXPECT_NEAR(item.thetaE, 0.4, 1e-12) << "emits within its outer cone";
}

TEST(Emitter, DirectionalLightsArriveFromTheirDirectionWithTheirIrradiance) {
  const Vec3d direction = Normalize(Vec3d{1, 0, -1});
  const auto lone = SceneLightAlone<DirectionalEmitter>(DirectionalLight{direction, {2, 2, 2}, 1});
  const Emitter& light = *lone->emitter;
  LightSample s;
  ASSERT_TRUE(light.EvalDelta({}, &s));
  EXPECT_EQ(s.wi, -direction);
  EXPECT_EQ(s.distance, kInf);
  EXPECT_EQ(s.radiance, (Vec3d{2, 2, 2}));
  const Vec3d facing{0, 0, 1}, away{0, 0, -1};
  EXPECT_EQ(light.Importance({}, &facing), 2);
  EXPECT_EQ(light.Importance({}, &away), 0);
  LightTree::Item item;
  EXPECT_FALSE(light.TreeItem(&item));
}

TEST(Emitter, TheSunsDiskGivesItsIrradianceToAFacingSurface) {
  // E = integral of L cos over the cap: by the sun's own samples, L cos / pdf averaged.
  const Vec3d direction = Normalize(Vec3d{0.2, 0.1, -1});
  const auto lone =
      SceneLightAlone<SunEmitter>(DirectionalLight{direction, {3, 2, 1}, std::cos(0.05)});
  const Emitter& light = *lone->emitter;
  SobolSampler sampler(1, 2);
  Vec3d irradiance;
  constexpr int kN = 4096;
  for (int i = 0; i < kN; ++i) {
    sampler.StartSample(i);
    LightSample s;
    ASSERT_TRUE(light.Sample({}, nullptr, sampler.Get2D(), &s));
    irradiance += s.radiance * (Dot(s.wi, -direction) / s.pdf / kN);
  }
  EXPECT_NEAR(irradiance.x, 3, 1e-5);
  EXPECT_NEAR(irradiance.y, 2, 1e-5);
  EXPECT_NEAR(irradiance.z, 1, 1e-5);
  LightHit h;
  EXPECT_FALSE(light.EvalEscaped(Vec3d{}, Normalize(-direction + Vec3d{0.1, 0, 0}), nullptr, 1, &h))
      << "a direction outside the disk";
}

}  // namespace
}  // namespace probebake
