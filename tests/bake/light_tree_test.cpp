// The light tree's choice (light_tree.h through LightSet): its probabilities are a distribution,
// the choice follows them exactly, it reaches exactly the lights the linear choice reaches, and
// bakes through it match the closed form, also with radiances 20 orders of magnitude apart.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "bake_test_util.h"
#include "core/src/bake/light_set.h"
#include "core/src/bake/tracer_scene.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// Many lights of every finite kind spread through a 10 m box, plus a sun and a sky.
Scene ClutteredScene(int count) {
  Scene scene;
  const uint32_t lamp = AddMaterial(&scene, {0, 0, 0}, {2, 1, 1});
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> pos(-5, 5), size(0.05, 0.5), power(0.1, 10);
  const auto direction = [&] { return Normalize(Vec3d{pos(rng), pos(rng), pos(rng)}); };
  for (int i = 0; i < count; ++i) {
    const Vec3d c{pos(rng), pos(rng), pos(rng)};
    const Vec3d L{power(rng), power(rng), power(rng)};
    switch (i % 6) {
      case 0:
        scene.lights.push_back(
            RectLight{c, {size(rng), 0, 0}, {0, size(rng), 0.1}, L, i % 12 == 0});
        break;
      case 1:
        scene.lights.push_back(DiskLight{c, direction(), size(rng), L, false});
        break;
      case 2:
        scene.lights.push_back(SphereLight{c, size(rng), L});
        break;
      case 3:
        scene.lights.push_back(PointLight{c, L});
        break;
      case 4:
        scene.lights.push_back(SpotLight{c, direction(), L, 0.9, 0.7});
        break;
      case 5: {
        const double s = size(rng);
        AddQuad(&scene, c, c + Vec3d{s, 0, 0}, c + Vec3d{s, s, 0}, c + Vec3d{0, s, 0}, lamp);
        break;
      }
    }
  }
  scene.lights.push_back(
      DirectionalLight{Normalize(Vec3d{0.3, 0.2, -1}), {2, 2, 2}, std::cos(0.1)});
  scene.environment = {Environment::Kind::kUniform, {0.1, 0.1, 0.1}, nullptr};
  return scene;
}

struct ShadingPoint {
  Vec3d p, nStorage;
  bool hasNormal = false;
  const Vec3d* n() const { return hasNormal ? &nStorage : nullptr; }
};

std::vector<ShadingPoint> ShadingPoints(const Vec3d& offset, int count) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-6, 6);
  std::vector<ShadingPoint> points;
  for (int i = 0; i < count; ++i) {
    ShadingPoint s;
    s.p = Vec3d{u(rng), u(rng), u(rng)} - offset;
    s.nStorage = Normalize(Vec3d{u(rng), u(rng), u(rng)});
    s.hasNormal = i % 3 != 0;
    points.push_back(s);
  }
  return points;
}

TEST(LightTree, ChoiceProbabilitiesFormADistributionThatTheChoiceFollowsExactly) {
  const Scene scene = ClutteredScene(120);
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  const LightSet lights(scene, **tracer, /*treeMinLights=*/1);
  ASSERT_EQ(lights.TreeLightCount(), 120u) << "every finite light should be in a tree";
  std::vector<double> importance(lights.ImportanceSize());
  for (const ShadingPoint& s : ShadingPoints((*tracer)->offset(), 40)) {
    for (bool includeDelta : {false, true}) {
      const double total = lights.Importance(s.p, s.n(), includeDelta, importance);
      ASSERT_GT(total, 0);
      double sum = 0;
      std::vector<double> pmf(lights.Count());
      for (uint32_t i = 0; i < lights.Count(); ++i) {
        pmf[i] = lights.SelectionPmf(i, s.p, s.n(), importance, total);
        sum += pmf[i];
      }
      // Products of at most ~10 rounded ratios per light, summed over 121 lights. Below 1 by
      // the mass of walks that end at a node whose children cannot light p.
      EXPECT_LE(sum, 1.0 + 1e-12);
      // Stratified u: each light's u form one interval (nested remapping), so its count is within
      // 2 of M pmf, and the pmf reported with the choice is SelectionPmf's to the bit.
      constexpr int kM = 1 << 16;
      std::vector<int> count(lights.Count(), 0);
      int failed = 0;
      for (int k = 0; k < kM; ++k) {
        uint32_t light;
        double p;
        if (!lights.Choose(s.p, s.n(), importance, total, (k + 0.5) / kM, &light, &p)) {
          ++failed;
          continue;
        }
        ++count[light];
        ASSERT_EQ(p, pmf[light]) << "light " << light;
      }
      for (uint32_t i = 0; i < lights.Count(); ++i)
        EXPECT_LE(std::abs(count[i] - kM * pmf[i]), 2.0) << "light " << i;
      // Dead ends are a union of at most one interval per tree node.
      EXPECT_LE(std::abs(failed - kM * (1 - sum)), 2.0 * lights.Count());
    }
  }
}

TEST(LightTree, ReachesExactlyTheLightsTheLinearChoiceReaches) {
  const Scene scene = ClutteredScene(120);
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  const LightSet tree(scene, **tracer, /*treeMinLights=*/1);
  const LightSet linear(scene, **tracer, /*treeMinLights=*/1000);
  ASSERT_EQ(tree.TreeLightCount(), 120u);
  ASSERT_EQ(linear.TreeLightCount(), 0u);
  std::vector<double> a(tree.ImportanceSize()), b(linear.ImportanceSize());
  int positive = 0, zero = 0;
  for (const ShadingPoint& s : ShadingPoints((*tracer)->offset(), 200)) {
    const double ta = tree.Importance(s.p, s.n(), true, a);
    const double tb = linear.Importance(s.p, s.n(), true, b);
    for (uint32_t i = 0; i < tree.Count(); ++i) {
      const bool reachedByTree = tree.SelectionPmf(i, s.p, s.n(), a, ta) > 0;
      const bool reachedLinearly = linear.SelectionPmf(i, s.p, s.n(), b, tb) > 0;
      ASSERT_EQ(reachedByTree, reachedLinearly) << "light " << i;
      (reachedLinearly ? positive : zero)++;
    }
  }
  // Both outcomes occur (lights behind one-sided emitters and below surfaces are unreachable).
  EXPECT_GT(positive, 1000);
  EXPECT_GT(zero, 1000);
}

// 96 disks facing the origin on a spherical Fibonacci lattice (neighbours about 20 degrees apart),
// 1.2 to 3 m away, each subtending 6.8 degrees: no two caps overlap. Disk i has grey radiance
// radiance(i); returns the exact projection of their sum.
template <typename Radiance>
std::vector<double> AddDiskLattice(BakeJob* job, int order, int disks, Radiance&& radiance) {
  std::vector<double> exact(ShCoeffCount(order), 0.0);
  for (int i = 0; i < disks; ++i) {
    const double z = 1 - (2 * i + 1.0) / disks, r = std::sqrt(1 - z * z);
    const double phi = i * kPi * (3 - std::sqrt(5.0));
    const Vec3d axis{r * std::cos(phi), r * std::sin(phi), z};
    const double h = 1.2 + 1.8 * (i % 5) / 4.0, a = 0.12 * h;
    const double L = radiance(i);
    job->scene.lights.push_back(DiskLight{axis * h, -axis, a, {L, L, L}, false});
    const std::vector<double> cap = CapProjection(order, axis, h / std::sqrt(h * h + a * a));
    for (size_t k = 0; k < exact.size(); ++k) exact[k] += L * cap[k];
  }
  return exact;
}

// Fails the test unless every light of the job's scene is chosen through a light tree by default.
void ExpectEveryLightInATree(const BakeJob& job) {
  auto tracer = TracerScene::Build(job.scene, LocalOrigin(job.scene));
  ASSERT_TRUE(tracer.ok()) << tracer.status();
  EXPECT_EQ(LightSet(job.scene, **tracer).TreeLightCount(), job.scene.lights.size());
}

TEST(Extremes, DiskLightsFromOneTenBillionthToTenBillionThroughTheLightTree) {
  // Radiances 10^-10 .. 10^10 in one light tree: cluster weights span 20 orders of magnitude and
  // the walk's ratios must neither underflow to a dead end nor overflow.
  BakeJob job = MakeJob(2, 8192);
  const std::vector<double> exact =
      AddDiskLattice(&job, 2, 96, [](int i) { return std::pow(10.0, double(i % 21) - 10); });
  ExpectEveryLightInATree(job);
  const ProbeVolume v = BakeOrDie(job);
  const ProbeResult r = Probe(v, 0);
  for (const Vec3d& c : r.radiance) ASSERT_TRUE(std::isfinite(c.x + c.y + c.z));
  ExpectProjection(r, exact, {1, 1, 1}, "disks of 1e-10 to 1e10");
}

TEST(LightTree, ManyDiskLightsMatchTheirCapsThroughABake) {
  // The radiance is the sum of the disks' caps (closed_form_test.cpp); 96 disks are enough for
  // the default threshold.
  static_assert(96 >= kLightTreeMinLights);
  BakeJob job = MakeJob(3, 8192);
  const std::vector<double> exact = AddDiskLattice(&job, 3, 96, [](int) { return 1.5; });
  ExpectEveryLightInATree(job);
  ExpectProjection(Probe(BakeOrDie(job), 0), exact, {1, 1, 1}, "96 disk lights");
}

}  // namespace
}  // namespace probebake
