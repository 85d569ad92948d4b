// Probe sites (probe_site.h): a probe's traced position and stream key depend on its world
// position alone, robustly to last-bit differences in how a (sub-)grid computed it.
#include <gtest/gtest.h>

#include <cmath>

#include "bake_test_util.h"
#include "core/src/bake/probe_site.h"
#include "core/src/bake/tracer_scene.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// A floor of half-size `extent` centred at `centre`.
Scene SceneOfExtent(double extent, const Vec3d& centre = {}) {
  Scene scene;
  const uint32_t white = AddMaterial(&scene, {0.5, 0.5, 0.5});
  AddQuad(&scene, centre + Vec3d{-extent, -extent, 0}, centre + Vec3d{extent, -extent, 0},
          centre + Vec3d{extent, extent, 0}, centre + Vec3d{-extent, extent, 0}, white);
  return scene;
}

ProbeSites SitesOf(const Scene& scene) {
  return ProbeSites(scene, LocalOrigin(scene));
}

TEST(ProbeSite, PositionsAFewUlpsApartShareASite) {
  const ProbeSites sites = SitesOf(SceneOfExtent(4));
  int checked = 0, differing = 0;
  for (int n = -40; n <= 40; ++n) {
    // The same lattice point computed from different mins: 0.1 * n against an offset min.
    const double a = 0.1 * n;
    const double b = (-2.3 + 0.1 * (n + 23));
    differing += a != b ? 1 : 0;
    for (const Vec3d& p : {Vec3d{a, 0.3, 1.7}, Vec3d{0.3, a, -1.1}}) {
      const Vec3d q = p.x == a ? Vec3d{b, 0.3, 1.7} : Vec3d{0.3, b, -1.1};
      const ProbeSite s = sites.At(p), t = sites.At(q);
      EXPECT_EQ(s.key, t.key) << a << " vs " << b;
      EXPECT_EQ(s.local.x, t.local.x);
      EXPECT_EQ(s.local.y, t.local.y);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 162);
  EXPECT_GT(differing, 20) << "the two computations should disagree in the last bits";
  // -0 and +0 are one position.
  EXPECT_EQ(sites.At({-0.0, 1, 1}).key, sites.At({0.0, 1, 1}).key);
  // Values on either side of a power of two, where the quantum changes, meet at it.
  EXPECT_EQ(sites.At({std::nextafter(2.0, 0.0), 0, 0}).key, sites.At({2.0, 0, 0}).key);
  EXPECT_EQ(sites.At({std::nextafter(2.0, 3.0), 0, 0}).key, sites.At({2.0, 0, 0}).key);
}

TEST(ProbeSite, DistinctProbesKeepDistinctKeysAndBarelyMove) {
  for (double extent : {1e-3, 1.0, 4.0, 1e4}) {
    for (const Vec3d& centre : {Vec3d{}, Vec3d{1e5, -1e5, 1e5}}) {
      const Scene scene = SceneOfExtent(extent, centre);
      const Vec3d offset = LocalOrigin(scene);
      const ProbeSites sites(scene, offset);
      // Probes a millionth of the extent apart stay apart; every snapped local position is
      // within 2^-31 of max(|x|, extent) of the given one (the analysis in probe_site.h).
      const double step = extent * 1e-6;
      for (int n = 0; n < 1000; ++n) {
        const Vec3d p = centre + Vec3d{extent * 0.37 + step * n, -extent * 0.11, extent * 2.5};
        const ProbeSite s = sites.At(p), t = sites.At(p + Vec3d{step, 0, 0});
        EXPECT_NE(s.key, t.key) << "extent " << extent << " n " << n;
        const Vec3d local = p - offset;
        for (int a = 0; a < 3; ++a) {
          const double bound = std::ldexp(std::max(std::abs(local[a]), extent), -31);
          EXPECT_LE(std::abs(s.local[a] - local[a]), bound) << "extent " << extent << " axis " << a;
        }
      }
    }
  }
}

TEST(ProbeSite, AProbeJustAboveAFloorFarFromTheOriginStaysAboveIt) {
  // The snap is relative to the scene's local extent, not to the world coordinates' magnitude:
  // 1e-5 above a 1e3 floor at 1e5 units stays 1e-5 above it (to 2^-31 of 1e3).
  const Vec3d centre{1e5, -1e5, 1e5};
  const Scene scene = SceneOfExtent(1e3, centre);
  const ProbeSites sites(scene, LocalOrigin(scene));
  const ProbeSite s = sites.At(centre + Vec3d{0.25, 0.5, 1e-5});
  EXPECT_NEAR(s.local.z, 1e-5, std::ldexp(1e3, -31));
}

}  // namespace
}  // namespace probebake
