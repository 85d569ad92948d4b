// The tracer's hits do not depend on the CPU it runs on: with kEmbreeDeviceConfig every x86-64
// machine runs Embree kernels without fused multiply-adds, so a job bakes the same bits on a
// laptop, a build farm's AVX-512 node and an old SSE-only one, and shards baked on a mixed cluster
// merge into a local bake's bits.
#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include "bake_test_util.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// A closed room with a box inside, lit by a rect, a disk and a sphere light (Embree's triangle,
// oriented-disc and sphere kernels).
Scene Room() {
  Scene scene;
  const uint32_t grey = AddMaterial(&scene, {0.5, 0.5, 0.5});
  AddBox(&scene, {-3, -2, 0}, {3, 2, 2.5}, grey, /*inward=*/true);
  AddBox(&scene, {-0.7, -0.4, 0}, {0.3, 0.9, 0.8}, grey, /*inward=*/false);
  scene.lights.push_back(RectLight{{-1, -1, 2.49}, {0, 1, 0}, {1, 0, 0}, {4, 4, 4}, false});
  scene.lights.push_back(
      DiskLight{{2, -1, 1.2}, Normalize(Vec3d{-1, 0.2, -0.3}), 0.3, {2, 2, 2}, true});
  scene.lights.push_back(SphereLight{{-2, 1, 1.5}, 0.25, {5, 5, 5}});
  return scene;
}

struct Traced {
  std::vector<bool> found, occluded;
  std::vector<SurfaceHit> hits;
};

// Rays from points spread through the room in directions spread over the sphere: each traced
// alone, as packets of kPacketWidth from one origin, and as shadow rays to half their hit
// distance and past it.
Traced Trace(const Scene& scene, const char* deviceConfig) {
  Traced out;
  auto tracer = TracerScene::Build(scene, LocalOrigin(scene), deviceConfig);
  EXPECT_TRUE(tracer.ok()) << deviceConfig << ": " << tracer.status();
  if (!tracer.ok()) return out;
  const TracerScene& t = **tracer;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  constexpr int kW = TracerScene::kPacketWidth;
  SobolSampler sampler(/*seed=*/11, /*stream=*/0);
  for (int i = 0; i < 512; ++i) {
    sampler.StartSample(i);
    const Vec2d a = sampler.Get2D();
    const Vec3d p =
        Vec3d{-2.9 + 5.8 * a.x, -1.9 + 3.8 * a.y, 0.05 + 2.4 * sampler.Get1D()} - t.offset();
    const Vec3f origin(p);
    Vec3d dirs[kW];
    for (Vec3d& d : dirs) d = SampleUniformSphere(sampler.Get2D());
    SurfaceHit packetHits[kW];
    bool packetFound[kW];
    t.IntersectPacket(std::span(&origin, 1), dirs, packetHits, packetFound);
    for (int k = 0; k < kW; ++k) {
      SurfaceHit hit;
      const bool found = t.Intersect(origin, dirs[k], kInf, &hit);
      out.found.push_back(found);
      out.hits.push_back(found ? hit : SurfaceHit{});
      out.found.push_back(packetFound[k]);
      out.hits.push_back(packetFound[k] ? packetHits[k] : SurfaceHit{});
      const double tMax = found ? hit.t : 10.0;
      out.occluded.push_back(t.Occluded(origin, dirs[k], 0.5 * tMax));
      out.occluded.push_back(t.Occluded(origin, dirs[k], 1.01 * tMax));
    }
  }
  return out;
}

// The number of rays whose hits differ in any bit between a and b.
int Differences(const Traced& a, const Traced& b) {
  EXPECT_EQ(a.hits.size(), b.hits.size());
  int differ = 0;
  for (size_t k = 0; k < std::min(a.hits.size(), b.hits.size()); ++k) {
    const SurfaceHit& x = a.hits[k];
    const SurfaceHit& y = b.hits[k];
    const bool same = a.found[k] == b.found[k] && x.t == y.t && x.p.x == y.p.x && x.p.y == y.p.y &&
                      x.p.z == y.p.z && x.ng.x == y.ng.x && x.ng.y == y.ng.y && x.ng.z == y.ng.z &&
                      x.kind == y.kind && x.index == y.index && x.prim == y.prim &&
                      x.vertexScale == y.vertexScale;
    differ += !same;
  }
  for (size_t k = 0; k < std::min(a.occluded.size(), b.occluded.size()); ++k)
    differ += a.occluded[k] != b.occluded[k];
  return differ;
}

TEST(TracerKernels, ThePinnedKernelsTraceTheHitsOfTheBaselineOnes) {
  const Scene scene = Room();
  const Traced pinned = Trace(scene, kEmbreeDeviceConfig);
  ASSERT_EQ(pinned.hits.size(), 512u * 2 * TracerScene::kPacketWidth);
  // SSE2 is the kernel set every x86-64 CPU has.
  for (const char* config : {"isa=sse2", "isa=sse4.2"}) {
    EXPECT_EQ(Differences(pinned, Trace(scene, config)), 0)
        << kEmbreeDeviceConfig << " against " << config;
  }
}

// What the pin guards against, shown on this machine when it can run them: Embree's FMA kernels
// trace other bits. If they ever traced the same ones, the pin's cost would be for nothing.
TEST(TracerKernels, TheFusedMultiplyAddKernelsWouldTraceOtherBits) {
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma"))
    GTEST_SKIP() << "this CPU has no AVX2 and FMA: Embree's FMA kernels cannot run here";
  const Scene scene = Room();
  EXPECT_GT(Differences(Trace(scene, kEmbreeDeviceConfig), Trace(scene, "isa=avx2")), 0);
}

}  // namespace
}  // namespace probebake
