// Meshes a model places under several nodes are kept once and placed (TriangleMesh::placements):
// what the import stores, that mirrors keep front faces, that emissive meshes are placed as
// copies, that a hand-over carries the placements, and that a bake of the placed level equals a
// bake of the same boxes given as separate world-space meshes.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "job/gltf_test_files.h"
#include "job/test_util.h"
#include "probebake/bake/bake.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"
#include "probebake/job/mesh_imports.h"

namespace probebake {
namespace {

using testing::Append;
using testing::TempDir;

using Matrix = std::array<double, 16>;  // row-major 4 x 4, the job file's `transform`

// The nodes of the level: a box (mesh 0) placed by the first four (the fourth scaled to zero), a
// quad (mesh 1) placed once by a node mirroring z, an emissive box (mesh 2, a lamp) placed twice.
struct Node {
  int mesh;
  Matrix m;
};
const std::vector<Node>& Nodes() {
  static const std::vector<Node> nodes = {
      {0, {1, 0, 0, -1.5, 0, 1, 0, 0.2, 0, 0, 1, 0.1, 0, 0, 0, 1}},
      // A rotation by 0.6 about z with x stretched by 1.5 and z by 0.7.
      {0,
       {1.5 * std::cos(0.6), -std::sin(0.6), 0, 0.3, 1.5 * std::sin(0.6), std::cos(0.6), 0, -0.4, 0,
        0, 0.7, 0.2, 0, 0, 0, 1}},
      {0, {-1, 0, 0, 2.2, 0, 1, 0, 0.3, 0, 0, 1, 0.15, 0, 0, 0, 1}},  // mirrors x
      {0, {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1}},          // scaled to zero: hidden
      {1, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, 2.5, 0, 0, 0, 1}},       // mirrors z
      {2, {1, 0, 0, -0.5, 0, 1, 0, -1, 0, 0, 1, 2.9, 0, 0, 0, 1}},
      {2, {1, 0, 0, 0.5, 0, 1, 0, -1, 0, 0, 1, 2.9, 0, 0, 0, 1}},
  };
  return nodes;
}

Matrix Multiply(const Matrix& a, const Matrix& b) {
  Matrix r{};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) r[4 * i + j] += a[4 * i + k] * b[4 * k + j];
  return r;
}

std::string MatrixJson(const Matrix& m, bool columnMajor) {
  std::string out = "[";
  for (int k = 0; k < 16; ++k) {
    const int at = columnMajor ? 4 * (k % 4) + k / 4 : k;  // glTF's matrices are column-major
    absl::StrAppend(&out, k ? "," : "", absl::StrFormat("%.17g", m[size_t(at)]));
  }
  out += "]";
  return out;
}

// The unit box's corners and outward counter-clockwise triangles.
constexpr float kBoxCorners[8][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0},
                                     {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};
constexpr uint16_t kBoxTriangles[36] = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                        2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};

// The glTF members both levels read their meshes from: the unit box (accessors 0 and 1) and a
// quad facing +z (2 and 3), in one buffer as a data URI.
std::string BoxAndQuadBuffers() {
  std::string bin;
  for (const auto& c : kBoxCorners) Append<float>(&bin, {c[0], c[1], c[2]});
  for (uint16_t i : kBoxTriangles) Append<uint16_t>(&bin, {i});
  Append<float>(&bin, {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0});
  Append<uint16_t>(&bin, {0, 1, 2, 0, 2, 3});
  return R"("accessors": [
      {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
       "min": [0, 0, 0], "max": [1, 1, 1]},
      {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"},
      {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3",
       "min": [0, 0, 0], "max": [1, 1, 0]},
      {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 96},
                    {"buffer": 0, "byteOffset": 96, "byteLength": 72},
                    {"buffer": 0, "byteOffset": 168, "byteLength": 48},
                    {"buffer": 0, "byteOffset": 216, "byteLength": 12}],
    "buffers": [{"byteLength": 228, "uri": "data:application/octet-stream;base64,)" +
         absl::Base64Escape(bin) + R"("}])";
}

std::string LevelGltf() {
  std::string nodes, roots;
  for (size_t n = 0; n < Nodes().size(); ++n) {
    absl::StrAppend(&nodes, n ? "," : "", "{\"mesh\": ", Nodes()[n].mesh,
                    ", \"matrix\": ", MatrixJson(Nodes()[n].m, true), "}");
    absl::StrAppend(&roots, n ? "," : "", n);
  }
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [)" + roots +
         R"(]}], "nodes": [)" + nodes + R"(],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
               {"primitives": [{"attributes": {"POSITION": 2}, "indices": 3, "material": 0}]},
               {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 1}]}],
    "materials": [{"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1],
                                                            "metallicFactor": 0}},
                  {"name": "lamp", "emissiveFactor": [1, 0.9, 0.8],
                   "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1],
                                            "metallicFactor": 0}}],
    )" + BoxAndQuadBuffers() +
         "}";
}

// The job's own transform of the level: +Y up to +Z up, and a shift.
constexpr Matrix kJob = {1, 0, 0, 0.1, 0, 0, -1, 0.2, 0, 1, 0, -0.3, 0, 0, 0, 1};

// Probes 0.9 apart, two of them at the centres of the first and the mirrored box.
std::string Grid() {
  return R"("grid": {"min": [-2.7, -2.45, 0.45], "max": [1.8, 1.55, 2.45],
                     "counts": [6, 3, 3], "placement": "ALL"},
            "settings": {"samplesPerProbe": 256, "shOrder": 2, "batches": 16})";
}

// Built with every repeated mesh instanced (JobLimits::flattenUpToTriangles 0) unless `flatten`
// says otherwise.
absl::StatusOr<BakeJob> Build(const TempDir& dir, const std::string& json,
                              MeshImports* record = nullptr, const MeshImports* use = nullptr,
                              int64_t flatten = 0) {
  const absl::StatusOr<v1::JobSpec> spec = ParseJobJson(json);
  if (!spec.ok()) return spec.status();
  JobLimits limits;
  limits.flattenUpToTriangles = flatten;
  return BuildBakeJob(*spec, LocalAssetSource(dir.path()), limits, {record, use});
}

// The level as authored: one glTF placed by the job's transform, in a closed room.
std::string LevelJob() {
  return R"({"scene": {"materials": [{"name": "wall", "albedo": [0.5, 0.5, 0.5]}],
      "meshes": [{"file": "level.gltf", "transform": )" +
         MatrixJson(kJob, false) + R"(},
                 {"file": "room.obj", "material": "wall"}]}, )" +
         Grid() + "}";
}

// A room around everything: a box with inward faces, x, y in [-4, 4], z in [-1, 4].
constexpr const char* kRoomObj =
    "v -4 -4 -1\nv 4 -4 -1\nv -4 4 -1\nv 4 4 -1\nv -4 -4 4\nv 4 -4 4\nv -4 4 4\nv 4 4 4\n"
    "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n";

struct Level {
  TempDir dir;
  Level() {
    dir.Write("level.gltf", LevelGltf());
    dir.Write("room.obj", kRoomObj);
  }
};

TEST(Instancing, AMeshPlacedByManyNodesIsStoredOnce) {
  Level level;
  const absl::StatusOr<BakeJob> job = Build(level.dir, LevelJob());
  ASSERT_TRUE(job.ok()) << job.status();
  int instanced = 0, emissive = 0, quads = 0;
  for (const TriangleMesh& mesh : job->scene.meshes) {
    const Material& material = job->scene.materials[mesh.material];
    if (!mesh.placements.empty()) {
      ++instanced;
      // The box, in its own frame, placed by its three nodes of non-zero volume, each after the
      // job's transform.
      EXPECT_EQ(mesh.TriangleCount(), 12u);
      ASSERT_EQ(mesh.placements.size(), 3u);
      for (size_t k = 0; k < 3; ++k) {
        const Matrix world = Multiply(kJob, Nodes()[k].m);
        int matches = 0;
        for (const MeshPlacement& placement : mesh.placements) {
          bool same = true;
          for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c)
              same = same && std::abs(placement.linear(r, c) - world[size_t(4 * r + c)]) < 1e-6;
            same = same && std::abs(placement.translation[r] - world[size_t(4 * r + 3)]) < 1e-6;
          }
          matches += same;
        }
        EXPECT_EQ(matches, 1) << "node " << k;
      }
      for (const Vec3d& p : mesh.positions) {
        for (int a = 0; a < 3; ++a) EXPECT_TRUE(p[a] == 0 || p[a] == 1) << p;
      }
    } else if (MaxComponent(material.emission) > 0) {
      // The lamp placed twice: world-space copies, a light per triangle.
      ++emissive;
      EXPECT_EQ(mesh.TriangleCount(), 24u);
    } else if (mesh.TriangleCount() == 2) {
      // The quad under the node mirroring z: the same plane, its front turned with the mirror,
      // +z in the file's frame to -z, which the job's transform turns to +y.
      ++quads;
      const Vec3d& a = mesh.positions[mesh.indices[0]];
      const Vec3d n = Normalize(
          Cross(mesh.positions[mesh.indices[1]] - a, mesh.positions[mesh.indices[2]] - a));
      EXPECT_GT(Dot(n, Vec3d{0, 1, 0}), 1 - 1e-12) << n;
    }
  }
  EXPECT_EQ(instanced, 1);
  EXPECT_EQ(emissive, 1);
  EXPECT_EQ(quads, 1);
}

// The level's nodes place 74 triangles (4 x 12 of the box, the hidden node's included, 2 of the
// quad, 2 x 12 of the lamp): up to that many the file is flattened, above it instanced.
TEST(Instancing, FilesPlacingFewTrianglesAreFlattened) {
  Level level;
  for (const int64_t flatten : {int64_t(74), int64_t(73)}) {
    const absl::StatusOr<BakeJob> job = Build(level.dir, LevelJob(), nullptr, nullptr, flatten);
    ASSERT_TRUE(job.ok()) << job.status();
    size_t instanced = 0, held = 0;
    for (const TriangleMesh& mesh : job->scene.meshes) {
      instanced += !mesh.placements.empty();
      if (mesh.material != 0) held += mesh.TriangleCount();  // the file's meshes, not the room
    }
    EXPECT_EQ(instanced, flatten == 74 ? 0u : 1u) << flatten;
    // Flattened: the three boxes of non-zero volume, the quad and the lamp's two copies.
    EXPECT_EQ(held, flatten == 74 ? 3 * 12 + 2 + 24u : 12 + 2 + 24u) << flatten;
  }
  // The default: a level this small is flattened.
  const absl::StatusOr<v1::JobSpec> spec = ParseJobJson(LevelJob());
  ASSERT_TRUE(spec.ok());
  const absl::StatusOr<BakeJob> job =
      BuildBakeJob(*spec, LocalAssetSource(level.dir.path()), JobLimits{});
  ASSERT_TRUE(job.ok()) << job.status();
  for (const TriangleMesh& mesh : job->scene.meshes) EXPECT_TRUE(mesh.placements.empty());
}

// A glTF placing the unit box (12 triangles) under `boxes` nodes and a quad (2) under `quads`,
// in a job of its own.
std::string RepeatedJob(const TempDir& dir, int boxes, int quads) {
  std::string nodes, roots;
  for (int n = 0; n < boxes + quads; ++n) {
    absl::StrAppend(&nodes, n ? "," : "", "{\"mesh\": ", n < boxes ? 0 : 1, ", \"translation\": [",
                    2 * n, ", 0, 0]}");
    absl::StrAppend(&roots, n ? "," : "", n);
  }
  dir.Write("repeated.gltf", R"({"asset": {"version": "2.0"}, "scene": 0,
    "scenes": [{"nodes": [)" + roots +
                                 R"(]}], "nodes": [)" + nodes + R"(],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
               {"primitives": [{"attributes": {"POSITION": 2}, "indices": 3}]}],
    )" + BoxAndQuadBuffers() + "}");
  return R"({"scene": {"materials": [{"name": "grey", "albedo": [0.5, 0.5, 0.5]}],
      "meshes": [{"file": "repeated.gltf", "material": "grey"}]},
    "grid": {"min": [0, 3, 1], "max": [0, 3, 1], "counts": [1, 1, 1], "placement": "ALL"},
    "settings": {"samplesPerProbe": 16}})";
}

// Ten boxes and two quads: the quad (under 8 triangles) is copied, not instanced; instanced, the
// file counts 12 + 10 x 8 (each placement as 8 triangles) + 2 x 2 = 96 triangles against the
// limit, flattened the 10 x 12 + 2 x 2 = 124 it places.
TEST(Instancing, SmallMeshesAreCopiedAndPlacementsCountAgainstTheLimit) {
  TempDir dir;
  const std::string json = RepeatedJob(dir, 10, 2);
  const absl::StatusOr<v1::JobSpec> spec = ParseJobJson(json);
  ASSERT_TRUE(spec.ok()) << spec.status();
  const auto build = [&](int64_t maxTriangles, int64_t flatten) {
    JobLimits limits;
    limits.maxTriangles = maxTriangles;
    limits.flattenUpToTriangles = flatten;
    return BuildBakeJob(*spec, LocalAssetSource(dir.path()), limits);
  };
  const absl::StatusOr<BakeJob> job = build(96, 0);
  ASSERT_TRUE(job.ok()) << job.status();
  size_t instanced = 0, copied = 0;
  for (const TriangleMesh& mesh : job->scene.meshes) {
    if (!mesh.placements.empty()) {
      ++instanced;
      EXPECT_EQ(mesh.TriangleCount(), 12u);
      EXPECT_EQ(mesh.placements.size(), 10u);
    } else {
      copied += mesh.TriangleCount();
    }
  }
  EXPECT_EQ(instanced, 1u);
  EXPECT_EQ(copied, 4u);  // the quad's two copies
  const absl::Status over = build(95, 0).status();
  EXPECT_NE(over.message().find("exceed the limit of 95"), absl::string_view::npos) << over;
  // Flattened, the same limit refuses the 124 triangles the file places.
  const absl::Status flat = build(96, int64_t(1) << 22).status();
  EXPECT_NE(flat.message().find("exceed the limit of 96"), absl::string_view::npos) << flat;
  EXPECT_TRUE(build(124, int64_t(1) << 22).ok());
}

TEST(Instancing, PlacementsSurviveTheHandOver) {
  Level level;
  MeshImports recorded;
  const absl::StatusOr<BakeJob> imported = Build(level.dir, LevelJob(), &recorded);
  ASSERT_TRUE(imported.ok()) << imported.status();
  const absl::StatusOr<MeshImports> handed = MeshImports::Parse(recorded.Serialize());
  ASSERT_TRUE(handed.ok()) << handed.status();
  const absl::StatusOr<BakeJob> built = Build(level.dir, LevelJob(), nullptr, &*handed);
  ASSERT_TRUE(built.ok()) << built.status();
  ASSERT_EQ(built->scene.meshes.size(), imported->scene.meshes.size());
  for (size_t m = 0; m < built->scene.meshes.size(); ++m) {
    const TriangleMesh &a = built->scene.meshes[m], &b = imported->scene.meshes[m];
    EXPECT_EQ(a.positions, b.positions) << m;
    EXPECT_EQ(a.indices, b.indices) << m;
    ASSERT_EQ(a.placements.size(), b.placements.size()) << m;
    for (size_t k = 0; k < a.placements.size(); ++k) {
      EXPECT_EQ(a.placements[k].linear, b.placements[k].linear) << m;
      EXPECT_EQ(a.placements[k].translation, b.placements[k].translation) << m;
    }
  }
}

double Determinant3(const Matrix& m) {
  return m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
         m[2] * (m[4] * m[9] - m[5] * m[8]);
}

// The same boxes and the quad as separate meshes of the job, each placed by its own `transform`
// (the job's times the node's), the lamp's two copies included. A job's transform keeps the
// winding where a glTF node keeps the front faces: a mirroring node's copy is the file with its
// winding reversed ("-flipped").
std::string CopiesJob() {
  std::string meshes;
  for (const Node& node : Nodes()) {
    if (node.mesh == 0 && node.m[0] == 0) continue;  // the hidden node
    const bool flipped = Determinant3(node.m) < 0;
    const char* file = node.mesh != 1 ? (flipped ? "box-flipped.obj" : "box.obj")
                                      : (flipped ? "quad-flipped.obj" : "quad.obj");
    const char* material = node.mesh == 2 ? "lamp" : "grey";
    absl::StrAppend(&meshes, R"({"file": ")", file, R"(", "material": ")", material,
                    R"(", "transform": )", MatrixJson(Multiply(kJob, node.m), false), "},");
  }
  return R"({"scene": {"materials": [{"name": "wall", "albedo": [0.5, 0.5, 0.5]},
                                     {"name": "grey", "albedo": [0.6, 0.6, 0.6]},
                                     {"name": "lamp", "albedo": [0, 0, 0],
                                      "emission": [1, 0.9, 0.8]}],
      "meshes": [)" +
         meshes + R"({"file": "room.obj", "material": "wall"}]}, )" + Grid() + "}";
}

// Bakes of the placed level and of the copies agree within kSigmas of their reported errors
// (the same random numbers: they differ where a path meets an edge within float error), probe
// by probe, with the same validity.
TEST(Instancing, ALevelBakesAsItsCopiesDo) {
  Level level;
  std::string box, flipped;
  for (const auto& c : kBoxCorners) absl::StrAppend(&box, "v ", c[0], " ", c[1], " ", c[2], "\n");
  flipped = box;
  for (int t = 0; t < 12; ++t) {
    const int a = kBoxTriangles[3 * t] + 1, b = kBoxTriangles[3 * t + 1] + 1,
              c = kBoxTriangles[3 * t + 2] + 1;
    absl::StrAppend(&box, "f ", a, " ", b, " ", c, "\n");
    absl::StrAppend(&flipped, "f ", a, " ", c, " ", b, "\n");
  }
  level.dir.Write("box.obj", box);
  level.dir.Write("box-flipped.obj", flipped);
  level.dir.Write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  level.dir.Write("quad-flipped.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 4 3 2\n");
  const absl::StatusOr<BakeJob> placed = Build(level.dir, LevelJob());
  const absl::StatusOr<BakeJob> copies = Build(level.dir, CopiesJob());
  ASSERT_TRUE(placed.ok()) << placed.status();
  ASSERT_TRUE(copies.ok()) << copies.status();
  BakeOptions options;
  options.coefficientErrors = true;
  const absl::StatusOr<ProbeVolume> a = Bake(*placed, options), b = Bake(*copies, options);
  ASSERT_TRUE(a.ok() && b.ok());
  double worst = 0;
  for (int64_t p = 0; p < placed->grid.ProbeCount(); ++p) {
    EXPECT_EQ(a->validity[size_t(p)], b->validity[size_t(p)]) << "probe " << p;
    for (int c = 0; c < a->CoeffCount(); ++c) {
      for (int ch = 0; ch < 3; ++ch) {
        const size_t i = 3 * size_t(p) + size_t(ch);
        const double sa = a->radianceStdError[size_t(c)][i], sb = b->radianceStdError[size_t(c)][i];
        const double d = std::abs(a->radiance[size_t(c)][i] - b->radiance[size_t(c)][i]);
        const double bound =
            5 * std::sqrt(sa * sa + sb * sb) + 1e-6 * std::abs(b->radiance[size_t(c)][i]);
        worst = std::max(worst, bound > 0 ? d / bound : 0.0);
        EXPECT_LE(d, bound) << "probe " << p << " coefficient " << c;
      }
    }
  }
  std::printf("largest difference over its bound: %.3g\n", worst);
  // The probes at the centres of the first and of the mirrored box lie inside them: invalid.
  const ProbeGrid& grid = placed->grid;
  EXPECT_EQ(a->validity[size_t(grid.LinearIndex(2, 1, 0))], 0.0f) << grid.Position(2, 1, 0);
  EXPECT_EQ(a->validity[size_t(grid.LinearIndex(5, 1, 0))], 0.0f) << grid.Position(5, 1, 0);
  EXPECT_GT(std::abs(a->radiance[0][0]), 0);
}

}  // namespace
}  // namespace probebake
