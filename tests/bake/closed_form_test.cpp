// Bakes against closed forms: each test builds a scene whose incoming radiance at the
// probe is known exactly, and compares every baked SH coefficient with its exact projection within
// kSigmas reported standard errors (see bake_test_util.h for the tolerance policy).
#include <gtest/gtest.h>

#include <cmath>

#include "bake_test_util.h"
#include "probebake/math/mat3.h"

namespace probebake {
namespace {

using namespace probebake::testing;

const Vec3d kSky{0.2, 0.5, 1.0};
const Vec3d kUp{0, 0, 1}, kDown{0, 0, -1};

TEST(ClosedForm, UniformSkyProjectsToL00Only) {
  // L00 = 2 sqrt(pi) L, every other coefficient 0.
  BakeJob job = MakeJob(4, 4096);
  job.scene.environment.kind = Environment::Kind::kUniform;
  job.scene.environment.radiance = kSky;
  const ProbeVolume v = BakeOrDie(job);
  const ProbeResult r = Probe(v, 0);
  EXPECT_NEAR(r.radiance[0].z, 2 * std::sqrt(kPi) * kSky.z, 1e-6);
  ExpectProjection(r, CapProjection(4, kUp, -1), kSky, "uniform sky");
  EXPECT_EQ(r.sampleCount, 4096);
  EXPECT_EQ(r.validity, 1);
}

TEST(ClosedForm, ReportedStandardErrorsAreCalibrated) {
  // Every k-sigma test here trusts the bake's own standard errors: an inflated sigma would let
  // them pass without checking anything, a deflated one would make them flaky. 512 probes on the
  // axis of a disk light of radius 1 facing them, at distances 0.3 to 1.322 (each sees a cap: L00
  // exact), each an independent estimate (its own streams). The disk is sampled by area, whose
  // radiance / pdf varies over it, so the estimate has a continuous spread (a scene split by a
  // plane through the probe would be integrated exactly by the Sobol strata, with no error to
  // calibrate). The disk is large as seen from the probes, so direction sampling finds it often:
  // from 5 units away (0.7% of directions) the rare MIS hits make batch means skewed, and the
  // batch estimate understates the error of the unlucky probes (mean z^2 1.1-1.3 there; the
  // benchmark's honesty figures show the same on small lights). z = (L00 - exact) / sigma follows
  // Student's t with 63 degrees of freedom (64 batches): E[z^2] = 63/61 = 1.033, Var[z^2] = 3 *
  // 63^2 / (61 * 59) - 1.033^2 = 2.24, so the mean of 512 values of z^2 has a standard error of
  // sqrt(2.24 / 512) = 0.066. Accepted: within 4 of them of 1.033 ([0.77, 1.30]), i.e. sigma right
  // to about +-12%; a sigma 20% too large gives 0.72, 20% too small 1.49. One channel (the three
  // share their paths).
  const Vec3d L{1, 1, 1};
  const double radius = 1;
  BakeJob job = MakeJob(1, 1024, {0, 0, -1.322});
  job.grid.counts[2] = 512;
  job.grid.spacing = {1, 1, 0.002};
  job.scene.lights.push_back(DiskLight{{0, 0, 0}, kDown, radius, L, false});
  const ProbeVolume v = BakeOrDie(job);
  double sumZ2 = 0;
  for (int64_t p = 0; p < 512; ++p) {
    const double d = 1.322 - 0.002 * double(p);
    const double exact = CapProjection(1, kUp, d / std::sqrt(d * d + radius * radius))[0];
    const ProbeResult r = Probe(v, p);
    ASSERT_GT(r.stdError[0].z, 0) << p;
    const double z = (r.radiance[0].z - exact) / r.stdError[0].z;
    sumZ2 += z * z;
  }
  const double meanZ2 = sumZ2 / 512;
  std::printf(
      "[measured] standard error calibration: mean z^2 %.3f over 512 probes (expected %.3f "
      "+- %.3f), i.e. measured / reported error %.3f\n",
      meanZ2, 63.0 / 61, 0.066, std::sqrt(meanZ2 / (63.0 / 61)));
  EXPECT_GE(meanZ2, 63.0 / 61 - 4 * 0.066);
  EXPECT_LE(meanZ2, 63.0 / 61 + 4 * 0.066);
}

TEST(ClosedForm, BlackGroundUnderUniformSky) {
  // A black plane below the probe: sky over the upper hemisphere, nothing below. The plane is
  // finite (half-size 1e6 at height 1): the sky it fails to hide lies within 1e-6 rad of the
  // horizon, a solid angle < 2 pi 1e-6, bounding the error by 2 pi 1e-6 L max|Y| (extraAbs).
  BakeJob job = MakeJob(3, 4096, {0, 0, 1});
  job.scene.environment = {Environment::Kind::kUniform, kSky, nullptr};
  const uint32_t black = AddMaterial(&job.scene, {0, 0, 0});
  const double s = 1e6;
  AddQuad(&job.scene, {-s, -s, 0}, {s, -s, 0}, {s, s, 0}, {-s, s, 0}, black);
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, CapProjection(3, kUp, 0), kSky, "black ground", 2 * kPi * 1e-6 * 1.5);
}

TEST(ClosedForm, WhiteGroundReflectsTheSkyOnce) {
  // Every point of an unoccluded plane under a uniform sky receives E = pi L; a Lambertian
  // albedo rho sends back rho E / pi = rho L. So the probe sees L above and rho L below.
  const Vec3d rho{0.5, 0.25, 0.8};
  BakeJob job = MakeJob(3, 4096, {0, 0, 1});
  job.scene.environment = {Environment::Kind::kUniform, kSky, nullptr};
  const uint32_t white = AddMaterial(&job.scene, rho);
  const double s = 1e6;
  AddQuad(&job.scene, {-s, -s, 0}, {s, -s, 0}, {s, s, 0}, {-s, s, 0}, white);
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  const std::vector<double> up = CapProjection(3, kUp, 0), down = CapProjection(3, kDown, 0);
  std::vector<double> zero(up.size(), 0.0);
  // Compare the sum of the two hemispheres channel by channel.
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
    ExpectProjection(channel, expected, unit, "white ground channel " + std::to_string(ch),
                     2 * kPi * 1e-6 * 1.5);
  }
}

TEST(ClosedForm, DeltaLightsProjectExactly) {
  // c_i = (I / d^2) Y_i(w) for a point light, E Y_i(-direction) for a delta directional light,
  // spot falloff smoothstep(cos outer, cos inner, cos theta); exact up to float storage.
  BakeJob job = MakeJob(4, 64);
  const Vec3d p{0.3, -0.2, 0.1};
  job.grid.origin = p;
  const Vec3d pointPos{1, 2, 3}, intensity{10, 20, 30};
  job.scene.lights.push_back(PointLight{pointPos, intensity});
  const Vec3d dirTravel = Normalize(Vec3d{0.3, 0.2, -1});
  const Vec3d irradiance{3, 2, 1};
  job.scene.lights.push_back(DirectionalLight{dirTravel, irradiance, 1.0});
  const Vec3d spotPos{-1, 0.5, 2};
  // The axis 0.15 rad off the direction to the probe: inside the falloff band (0.02, 0.3).
  const Vec3d toProbe = Normalize(p - spotPos);
  const Vec3d side = Normalize(Cross(toProbe, Vec3d{0, 0, 1}));
  const Vec3d axis = toProbe * std::cos(0.15) + side * std::sin(0.15);
  SpotLight spot{spotPos, axis, {5, 5, 5}, std::cos(0.02), std::cos(0.3)};
  job.scene.lights.push_back(spot);
  const ProbeResult r = Probe(BakeOrDie(job), 0);

  const int n = ShCoeffCount(4);
  std::vector<double> yPoint(n), yDir(n), ySpot(n);
  const Vec3d toPoint = pointPos - p;
  EvalShBasis(4, Normalize(toPoint), yPoint.data());
  EvalShBasis(4, -dirTravel, yDir.data());
  const Vec3d toSpot = spotPos - p;
  EvalShBasis(4, Normalize(toSpot), ySpot.data());
  const double cosSpot = Dot(Normalize(p - spotPos), axis);
  const double t = (cosSpot - spot.cosOuter) / (spot.cosInner - spot.cosOuter);
  ASSERT_GT(t, 0.05);
  ASSERT_LT(t, 0.95);  // the probe sits in the falloff band
  const double falloff = t * t * (3 - 2 * t);
  for (int c = 0; c < n; ++c) {
    for (int ch = 0; ch < 3; ++ch) {
      const double exact = intensity[ch] / LengthSquared(toPoint) * yPoint[c] +
                           irradiance[ch] * yDir[c] +
                           5 * falloff / LengthSquared(toSpot) * ySpot[c];
      // Float storage (2^-23 relative) of a sum of three terms of size up to ~5.
      EXPECT_NEAR(r.radiance[c][ch], exact, 1e-6 * (1 + std::abs(exact))) << c << " " << ch;
    }
  }
}

TEST(ClosedForm, OccludedDeltaLightContributesNothing) {
  BakeJob job = MakeJob(2, 64);
  job.scene.lights.push_back(PointLight{{0, 0, 2}, {10, 10, 10}});
  const uint32_t grey = AddMaterial(&job.scene, {0, 0, 0});
  AddQuad(&job.scene, {-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}, grey);
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  for (const Vec3d& c : r.radiance) EXPECT_EQ(MaxComponent(Abs(c)), 0.0);
}

TEST(ClosedForm, RectLightMatchesQuadrature) {
  // A one-sided rectangle above the probe, facing it, near enough to be sampled by solid angle
  // (area 1.5 over a squared distance of 0.70 to its centre, above area_emitters.cpp's threshold of
  // 1), against a 64 x 64 Gauss-Legendre integration of Y(w) cos / r^2 over its area.
  const Vec3d L{4, 3, 2};
  const Vec3d corner{-0.3, -0.6, 0.8}, e1{0, 1.5, 0}, e2{1, 0, 0};  // e1 x e2 = -z: faces down
  BakeJob job = MakeJob(3, 8192);
  job.scene.lights.push_back(RectLight{corner, e1, e2, L, false});
  ProbeResult r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, ParallelogramProjection(3, {}, corner, e1, e2), L, "rect light");

  // Seen from behind, a one-sided light is dark.
  job.scene.lights[0] = RectLight{corner, e2, e1, L, false};
  r = Probe(BakeOrDie(job), 0);
  for (const Vec3d& c : r.radiance) EXPECT_EQ(MaxComponent(Abs(c)), 0.0);
  // Unless it is two-sided.
  job.scene.lights[0] = RectLight{corner, e2, e1, L, true};
  r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, ParallelogramProjection(3, {}, corner, e1, e2), L, "two-sided rect");
}

TEST(ClosedForm, ParallelogramLightMatchesQuadrature) {
  // Non-orthogonal edges: area sampling.
  const Vec3d L{1, 2, 3};
  const Vec3d corner{-0.5, -0.5, 1}, e1{1, 0, 0.2}, e2{0.4, 1, 0};
  BakeJob job = MakeJob(2, 8192);
  job.scene.lights.push_back(RectLight{corner, e1, e2, L, true});
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, ParallelogramProjection(2, {}, corner, e1, e2), L, "parallelogram light");
}

TEST(ClosedForm, DiskAndSphereLightsSubtendCaps) {
  // On its axis a disk of radius a at distance h covers the cap cos <= h / sqrt(h^2 + a^2); a
  // sphere of radius R at distance d covers cos <= sqrt(1 - R^2 / d^2).
  const Vec3d L{2, 2, 2};
  const Vec3d axis = Normalize(Vec3d{0.3, -0.4, 1});
  BakeJob job = MakeJob(4, 8192);
  const double h = 1.5, a = 0.7;
  job.scene.lights.push_back(DiskLight{axis * h, -axis, a, L, false});
  ProbeResult r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, CapProjection(4, axis, h / std::sqrt(h * h + a * a)), L, "disk light");

  job.scene.lights[0] = SphereLight{axis * 2.0, 0.5, L};
  r = Probe(BakeOrDie(job), 0);
  ExpectProjection(r, CapProjection(4, axis, std::sqrt(1 - 0.25 / 4)), L, "sphere light");
}

TEST(ClosedForm, TinyAndFarSphereLightsStayExact) {
  // A sphere of radius r at distance d covers the solid angle 2 pi (1 - cos) = pi r^2 / d^2 (to
  // r^2 / 4 d^2 relative). With cos computed as sqrt(1 - r^2 / d^2) the cap rounded to nothing
  // from r / d ~ 1e-8 (pdf infinite, the bake NaN) and was 2% off at 1e-7. Light sampling is all
  // that finds such a light, and every sample then gives L Y00 times the cap's solid angle: L0 is
  // exact to rounding (the stored float's 6e-8 relative).
  const Vec3d axis = Normalize(Vec3d{0.3, -0.4, 1});
  for (const double r : {1e-9, 1e-7, 1e-4}) {
    const Vec3d L = Vec3d{1, 1, 1} * (1 / (r * r));
    BakeJob job = MakeJob(2, 256);
    job.scene.lights.push_back(SphereLight{axis, r, L});
    const ProbeResult probe = Probe(BakeOrDie(job), 0);
    const double expected = L.x * M_PI * r * r * (1 + r * r / 4) * (0.5 / std::sqrt(M_PI));
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(probe.radiance[0][c], expected, 2e-7 * expected) << "r / d = " << r;
    for (const Vec3d& coefficient : probe.radiance)
      EXPECT_TRUE(std::isfinite(coefficient.x)) << "r / d = " << r;
  }
}

TEST(ClosedForm, SunDisksOfSeveralSizes) {
  // A sun of angular diameter 2 theta gives radiance E / (pi sin^2 theta) over the cap.
  for (double diameterDeg : {0.53, 30.0}) {
    const Vec3d E{3, 3, 3};
    const Vec3d travel = Normalize(Vec3d{0.3, 0.2, -1});
    const double cosMax = std::cos(diameterDeg / 2 * kPi / 180);
    BakeJob job = MakeJob(4, 4096);
    job.scene.lights.push_back(DirectionalLight{travel, E, cosMax});
    const ProbeResult r = Probe(BakeOrDie(job), 0);
    const double sin2 = (1 - cosMax) * (1 + cosMax);
    const Vec3d radiance = E / (kPi * sin2);
    const std::vector<double> exact = CapProjection(4, -travel, cosMax);
    // MIS leaves direction sampling a share p_dir / (p_dir + p_light) ~ Omega / 4pi = (1 - cos)/2
    // of the cap (5e-6 for the real sun), found only by rays that hit it: at 4096 samples almost
    // never, so the batch error cannot see it. Allow that share of the largest coefficient for the
    // small sun (three times over); the 30-degree sun is hit often enough to need nothing extra.
    double largest = 0;
    for (double c : exact) largest = std::max(largest, std::abs(c) * MaxComponent(radiance));
    const double bound = diameterDeg < 1 ? 3 * (1 - cosMax) / 2 * largest : 0.0;
    ExpectProjection(r, exact, radiance, "sun " + std::to_string(diameterDeg), bound);
  }
}

TEST(ClosedForm, FurnaceRoomCountsEveryBounceOnce) {
  // A closed box whose walls emit Le and reflect rho: radiance reflected k times is Le rho^k, so
  // with at most D bounces the probe sees Le (1 - rho^(D+1)) / (1 - rho) from every direction
  // (checks the depth limit), and with D large and Russian roulette Le / (1 - rho) (checks that
  // roulette is unbiased; rho <= 0.8 makes rho^101 < 2e-10).
  const Vec3d rho{0.8, 0.5, 0.2}, Le{1, 2, 3};
  for (int depth : {1, 3, 100}) {
    BakeJob job = MakeJob(2, 4096, {0.1, 0.2, 0.3});
    const uint32_t wall = AddMaterial(&job.scene, rho, Le);
    AddBox(&job.scene, {-1, -1, -1}, {1, 2, 1.5}, wall, /*inward=*/true);
    job.settings.maxDepth = depth;
    job.settings.russianRoulette = true;
    job.settings.rrMinDepth = 2;
    const ProbeResult r = Probe(BakeOrDie(job), 0);
    Vec3d radiance;
    for (int ch = 0; ch < 3; ++ch)
      radiance[ch] = Le[ch] * (1 - std::pow(rho[ch], depth + 1)) / (1 - rho[ch]);
    ExpectProjection(r, CapProjection(2, kUp, -1), radiance,
                     "furnace depth " + std::to_string(depth));
    EXPECT_EQ(r.validity, 1);
  }
}

EnvironmentMap GradientMap(int w, int h) {
  EnvironmentMap map;
  map.width = w;
  map.height = h;
  map.rgb.resize(size_t(3) * w * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* p = &map.rgb[3 * (size_t(y) * w + x)];
      p[0] = 0.1f + float(x) / w;
      p[1] = 0.2f + float(y) / h;
      p[2] = (x == w / 3 && y == h / 4) ? 50.0f : 0.05f;  // a small bright "sun" pixel
    }
  return map;
}

// Exact projection of a piecewise-constant lat-long map (cells as environment_light.h defines:
// pixel (x, y) covers longitude 2 pi (1/2 - x'/(w-1)) and latitude pi (1/2 - y'/(h-1)) for
// x' in [x - 1/2, x + 1/2], y' likewise, clipped to the image), by 12 x 12 Gauss-Legendre nodes in
// (longitude, sin latitude) per cell: Y is smooth, so this is accurate to ~1e-12.
std::vector<Vec3d> MapProjection(int order, const EnvironmentMap& map) {
  const QuadratureRule1D rule = GaussLegendreRule(12);
  std::vector<Vec3d> out(ShCoeffCount(order));
  std::vector<double> y(ShCoeffCount(order));
  const int w = map.width, h = map.height;
  for (int iy = 0; iy < h; ++iy) {
    const double ya = std::max(0.0, iy - 0.5), yb = std::min(double(h - 1), iy + 0.5);
    const double z0 = std::sin(kPi * (0.5 - yb / (h - 1))),
                 z1 = std::sin(kPi * (0.5 - ya / (h - 1)));
    for (int ix = 0; ix < w; ++ix) {
      const double xa = std::max(0.0, ix - 0.5), xb = std::min(double(w - 1), ix + 0.5);
      const double lon0 = 2 * kPi * (0.5 - xb / (w - 1)), lon1 = 2 * kPi * (0.5 - xa / (w - 1));
      const float* rgb = &map.rgb[3 * (size_t(iy) * w + ix)];
      const Vec3d value = Vec3d(rgb[0], rgb[1], rgb[2]) * map.scale;
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) {
          const double lon = lon0 + (lon1 - lon0) * 0.5 * (rule.nodes[i] + 1);
          const double z = z0 + (z1 - z0) * 0.5 * (rule.nodes[j] + 1);
          const double wgt = 0.25 * rule.weights[i] * rule.weights[j] * (lon1 - lon0) * (z1 - z0);
          const double r = std::sqrt(std::max(0.0, 1 - z * z));
          const Vec3d mapDir{r * std::sin(lon), z, r * std::cos(lon)};
          EvalShBasis(order, map.worldFromMap * mapDir, y.data());
          for (size_t k = 0; k < y.size(); ++k) out[k] += value * (wgt * y[k]);
        }
    }
  }
  return out;
}

TEST(ClosedForm, ConstantEnvironmentMapEqualsUniformSky) {
  auto map = std::make_shared<EnvironmentMap>();
  map->width = 16;
  map->height = 8;
  map->rgb.resize(3 * 16 * 8);
  for (size_t k = 0; k < map->rgb.size(); k += 3)
    map->rgb[k] = float(kSky.x), map->rgb[k + 1] = float(kSky.y), map->rgb[k + 2] = float(kSky.z);
  BakeJob job = MakeJob(4, 4096);
  job.scene.environment = {Environment::Kind::kMap, {}, map};
  const ProbeResult r = Probe(BakeOrDie(job), 0);
  // Float pixels: the radiance is kSky rounded to float.
  ExpectProjection(r, CapProjection(4, kUp, -1), Vec3d(Vec3f(kSky)), "constant map");
}

TEST(ClosedForm, EnvironmentMapMatchesCellProjection) {
  // A gradient with a bright pixel, upright (up Y) and turned (up Z, rotated 30 degrees).
  for (int variant = 0; variant < 2; ++variant) {
    auto map = std::make_shared<EnvironmentMap>(GradientMap(32, 16));
    map->scale = 2;
    if (variant == 1) {
      const Mat3d upZ =
          Mat3d::FromRows({1, 0, 0}, {0, 0, -1}, {0, 1, 0});  // map (x,y,z) -> (x,-z,y)
      map->worldFromMap = Mat3d::Rotation({0, 0, 1}, 30 * kPi / 180) * upZ;
    }
    BakeJob job = MakeJob(4, 16384);
    job.scene.environment = {Environment::Kind::kMap, {}, map};
    const ProbeResult r = Probe(BakeOrDie(job), 0);
    const std::vector<Vec3d> expected = MapProjection(4, *map);
    for (int ch = 0; ch < 3; ++ch) {
      std::vector<double> proj(expected.size());
      for (size_t c = 0; c < expected.size(); ++c) proj[c] = expected[c][ch];
      Vec3d unit;
      unit[ch] = 1;
      ProbeResult channel = r;
      for (size_t c = 0; c < expected.size(); ++c)
        for (int k = 0; k < 3; ++k)
          if (k != ch) channel.radiance[c][k] = 0, channel.stdError[c][k] = 0;
      ExpectProjection(channel, proj, unit,
                       "map variant " + std::to_string(variant) + " channel " + std::to_string(ch));
    }
  }
}

}  // namespace
}  // namespace probebake
