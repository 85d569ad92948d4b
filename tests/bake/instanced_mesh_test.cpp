// Instanced meshes (TriangleMesh::placements, one Embree scene placed by Embree instances) against
// the same triangles copied into world space: the same hits, point queries, validity and bakes.
// Placements include a rotation with a non-uniform scale and a mirror (negative determinant), whose
// front faces turn inside out with the placed winding.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <utility>
#include <vector>

#include "bake_test_util.h"
#include "core/src/bake/tracer_scene.h"

namespace probebake {
namespace {

using namespace probebake::testing;

std::vector<MeshPlacement> Placements() {
  const Mat3d rotation = Mat3d::Rotation(Normalize(Vec3d{1, 2, 3}), 0.7);
  Mat3d stretched = rotation;
  for (int r = 0; r < 3; ++r) stretched(r, 0) *= 1.7, stretched(r, 2) *= 0.6;  // scale x, z first
  Mat3d mirrored;
  mirrored(0, 0) = -1.2;
  return {{Mat3d::Identity(), {-2.5, 0.3, 0.2}},
          {stretched, {0.4, -0.2, 0.5}},
          {mirrored, {2.8, 0.1, 0.3}}};
}

// A closed box [0, 1]^3 with outward faces as one mesh of `scene`, placed by Placements() when
// `instanced`, else as one world-space copy per placement; a floor and walls around it.
Scene Boxes(bool instanced) {
  Scene scene;
  const uint32_t grey = AddMaterial(&scene, {0.6, 0.6, 0.6});
  const uint32_t red = AddMaterial(&scene, {0.7, 0.2, 0.1});
  AddBox(&scene, {-5, -4, -1}, {5, 4, 4}, grey, /*inward=*/true);
  AddBox(&scene, {0, 0, 0}, {1, 1, 1}, red, /*inward=*/false);
  TriangleMesh box = scene.meshes.back();
  scene.meshes.pop_back();
  if (instanced) {
    box.placements = Placements();
    scene.meshes.push_back(box);
  } else {
    for (const MeshPlacement& placement : Placements()) {
      TriangleMesh copy = box;
      for (Vec3d& p : copy.positions) p = placement.Apply(p);
      // A mirroring placement keeps the front faces: the copy's winding is reversed.
      if (Determinant(placement.linear) < 0)
        for (size_t k = 0; k < copy.indices.size(); k += 3)
          std::swap(copy.indices[k + 1], copy.indices[k + 2]);
      scene.meshes.push_back(copy);
    }
  }
  scene.lights.push_back(PointLight{{0.2, 2.5, 3}, {30, 30, 30}});
  return scene;
}

// The copy (mesh index in the flattened scene) a hit of either scene lies on.
uint32_t Copy(const SurfaceHit& hit, bool instanced) {
  return instanced ? 1 + hit.instance : hit.index;
}

TEST(InstancedMesh, TracesTheHitsOfItsWorldSpaceCopies) {
  const Scene instanced = Boxes(true), flat = Boxes(false);
  const Vec3d offset = LocalOrigin(flat);
  // The same local origin: the bounds of the placed boxes enclose the copies and both lie in the
  // room, whose box decides the bounds.
  ASSERT_EQ(LocalOrigin(instanced), offset);
  auto a = TracerScene::Build(instanced, offset);
  auto b = TracerScene::Build(flat, offset);
  ASSERT_TRUE(a.ok() && b.ok());
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  int compared = 0, onBoxes = 0, packetsCompared = 0;
  double worstNormal = 0;
  for (int i = 0; i < 20000; ++i) {
    // From a random point of the room toward a random point near the boxes.
    const Vec3d from{-4.5 + 9 * u(rng), -3.5 + 7 * u(rng), -0.5 + 4 * u(rng)};
    const Vec3d to{-3 + 7 * u(rng), -1.5 + 3 * u(rng), -0.5 + 2.5 * u(rng)};
    const Vec3d dir = Normalize(to - from);
    const Vec3f origin(from - offset);
    SurfaceHit ha, hb;
    const bool fa = (*a)->Intersect(origin, dir, 1e30, &ha);
    const bool fb = (*b)->Intersect(origin, dir, 1e30, &hb);
    ASSERT_TRUE(fa && fb);  // the room is closed
    // Where the copy's hit lies within float error of a triangle's edge, either neighbour may
    // answer; elsewhere the placed triangle must be the copy's.
    const double edge = std::min({double(hb.u), double(hb.v), 1.0 - hb.u - hb.v});
    if (edge < 1e-4) continue;
    ++compared;
    const bool boxA = ha.index == 1 || hb.index >= 1;
    onBoxes += boxA;
    EXPECT_EQ(ha.index == 0, hb.index == 0) << "ray " << i;
    if (hb.index >= 1) {
      EXPECT_EQ(Copy(ha, true), Copy(hb, false)) << "ray " << i;
    }
    EXPECT_EQ(ha.prim, hb.prim) << "ray " << i;
    // Float vertices placed by a float transform against float copies, both rounded to ~1e-7 of
    // coordinates up to ~5 (the transform's conditioning, under 3, on top): the surfaces agree to
    // ~1e-6 along their normal, which a ray at angle theta to the normal turns into 1e-6 / cos.
    const double cosine = std::abs(Dot(dir, hb.ng));
    worstNormal = std::max(worstNormal, std::abs(ha.t - hb.t) * cosine);
    EXPECT_LE(std::abs(ha.t - hb.t) * cosine, 4e-6) << "ray " << i;
    const Vec3d dp = ha.p - hb.p;
    EXPECT_LE(std::abs(Dot(dp, hb.ng)), 4e-6) << "ray " << i;
    EXPECT_LE(Length(dp), 4e-6 / std::max(cosine, 1e-3)) << "ray " << i;
    EXPECT_GT(Dot(ha.ng, hb.ng), 1 - 1e-9) << "ray " << i;
    // The mirrored copy's winding is reversed: its barycentrics swap.
    const bool swapped = hb.index == 3;
    EXPECT_NEAR(ha.u, swapped ? hb.v : hb.u, 1e-4) << "ray " << i;
    EXPECT_NEAR(ha.v, swapped ? hb.u : hb.v, 1e-4) << "ray " << i;
    EXPECT_GT(ha.vertexScale, 0);
    // Occlusion up to a little before the hit, and packets, agree too.
    EXPECT_EQ((*a)->Occluded(origin, dir, 0.999 * hb.t), (*b)->Occluded(origin, dir, 0.999 * hb.t));
    SurfaceHit pa[1], pb[1];
    bool ga[1], gb[1];
    const Vec3f origins[1] = {origin};
    const Vec3d dirs[1] = {dir};
    (*a)->IntersectPacket(origins, dirs, pa, ga);
    (*b)->IntersectPacket(origins, dirs, pb, gb);
    if (ga[0] && gb[0] && pa[0].index >= 1) {
      EXPECT_EQ(Copy(pa[0], true), Copy(pb[0], false)) << "ray " << i;
      ++packetsCompared;
    }
  }
  std::printf(
      "%d rays compared, %d on the boxes, %d packet hits on the boxes; largest difference of the "
      "hits along the normal %.3g\n",
      compared, onBoxes, packetsCompared, worstNormal);
  EXPECT_GT(onBoxes, 3000);
}

TEST(InstancedMesh, PointQueriesFindThePlacedTriangles) {
  const Scene instanced = Boxes(true), flat = Boxes(false);
  const Vec3d offset = LocalOrigin(flat);
  auto a = TracerScene::Build(instanced, offset);
  auto b = TracerScene::Build(flat, offset);
  ASSERT_TRUE(a.ok() && b.ok());
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  int near = 0;
  for (int i = 0; i < 4000; ++i) {
    const Vec3d p = Vec3d{-3.5 + 7.5 * u(rng), -1.5 + 3 * u(rng), -0.5 + 2.5 * u(rng)} - offset;
    const double radius = 0.05 + 0.3 * u(rng);
    const bool wa = (*a)->MeshWithin(p, radius), wb = (*b)->MeshWithin(p, radius);
    // Equal unless the nearest triangle lies within float error of the radius.
    if (wa != wb) {
      EXPECT_TRUE((*b)->MeshWithin(p, radius * (1 + 1e-5)) &&
                  !(*b)->MeshWithin(p, radius * 0.99999))
          << "point " << i;
    }
    near += wb;
  }
  EXPECT_GT(near, 500);
  // Points on the placed faces: the surface and its front normal, as on the copies.
  const std::vector<MeshPlacement> placements = Placements();
  for (uint32_t k = 0; k < 3; ++k) {
    const MeshPlacement& placement = placements[k];
    for (int i = 0; i < 200; ++i) {
      const Vec3d own{0.1 + 0.8 * u(rng), 0.1 + 0.8 * u(rng), i % 2 ? 1.0 : 0.0};  // top, bottom
      const Vec3d p = placement.Apply(own) - offset;
      SurfaceHit sa, sb;
      ASSERT_TRUE((*b)->MeshSurfaceAt(p, &sb)) << "copy " << k << " point " << i;
      ASSERT_TRUE((*a)->MeshSurfaceAt(p, &sa)) << "placement " << k << " point " << i;
      EXPECT_EQ(sa.index, 1u);
      EXPECT_EQ(sa.instance, k);
      EXPECT_EQ(sb.index, 1 + k);
      EXPECT_EQ(sa.prim, sb.prim);
      EXPECT_GT(Dot(sa.ng, sb.ng), 1 - 1e-9);
      EXPECT_LT(Length(sa.p - sb.p), 1e-5);
    }
  }
}

// Bakes of the two scenes: the same random numbers, so the coefficients differ only where a path
// meets an edge within float error; they must agree within kSigmas of their reported errors.
// A probe inside each box (the mirrored one included) is invalid in both.
TEST(InstancedMesh, BakesAsItsWorldSpaceCopies) {
  BakeJob job = MakeJob(2, 512, {-3.5, -2, 0.5});
  job.grid.counts[0] = 4;
  job.grid.counts[1] = 3;
  job.grid.counts[2] = 2;
  job.grid.spacing = {2.2, 1.9, 1.3};
  job.settings.batches = 16;
  std::vector<Vec3d> inside;
  for (const MeshPlacement& placement : Placements())
    inside.push_back(placement.Apply({0.5, 0.5, 0.5}));
  BakeJob a = job, b = job;
  a.scene = Boxes(true);
  b.scene = Boxes(false);
  BakeOptions options;
  options.coefficientErrors = true;
  auto va = Bake(a, options), vb = Bake(b, options);
  ASSERT_TRUE(va.ok() && vb.ok());
  int compared = 0;
  for (int64_t p = 0; p < job.grid.ProbeCount(); ++p) {
    EXPECT_EQ(va->validity[size_t(p)], vb->validity[size_t(p)]) << "probe " << p;
    for (int c = 0; c < va->CoeffCount(); ++c) {
      for (int ch = 0; ch < 3; ++ch) {
        const size_t i = 3 * size_t(p) + size_t(ch);
        const double sa = va->radianceStdError[size_t(c)][i],
                     sb = vb->radianceStdError[size_t(c)][i];
        const double d = va->radiance[size_t(c)][i] - vb->radiance[size_t(c)][i];
        EXPECT_LE(std::abs(d), kSigmas * std::sqrt(sa * sa + sb * sb) +
                                   1e-6 * std::abs(vb->radiance[size_t(c)][i]))
            << "probe " << p << " coefficient " << c;
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 0);
  // Probes placed inside the boxes: invalid, front faces read through the placement.
  BakeJob probe = job;
  probe.grid.counts[0] = probe.grid.counts[1] = probe.grid.counts[2] = 1;
  for (const Vec3d& x : inside) {
    probe.grid.origin = x;
    probe.scene = Boxes(true);
    auto in = Bake(probe, {});
    ASSERT_TRUE(in.ok());
    EXPECT_EQ(in->validity[0], 0.0f) << "inside the box placed at " << x;
  }
}

}  // namespace
}  // namespace probebake
