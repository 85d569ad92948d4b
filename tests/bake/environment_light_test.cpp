// The environment map (core/src/bake/environment_light.h): its pixel mapping against OpenEXR's own
// Imf::LatLongMap, its pdf's normalisation and agreement with sampling, and the early rejection of
// samples below a surface.
#include "core/src/bake/environment_light.h"

#include <gtest/gtest.h>

#include <OpenEXR/ImfEnvmap.h>

#include <cmath>
#include <memory>
#include <vector>

#include "bake_test_util.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

using namespace probebake::testing;

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
