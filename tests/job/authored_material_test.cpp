// A mesh file's own materials beyond constant factors, through BuildBakeJob: glTF base colour and
// emissive textures at their TEXCOORD_n with KHR_texture_transform, embedded (data: URI) and
// external images, COLOR_0, PLY vertex colours, OBJ map_Kd; textures refused with the field, the
// material and the path; the pixel limit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <variant>
#include <vector>

#include "absl/strings/escaping.h"
#include "core/src/bake/surface_material.h"
#include "job/gltf_test_files.h"
#include "job/test_util.h"
#include "probebake/bake/bake.h"
#include "probebake/base/status.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

namespace probebake {
namespace {

using testing::Append;
using testing::GltfQuad;
using testing::GltfWithLight;
using testing::HasFieldError;
using testing::Png;
using testing::Quadrants;
using testing::TempDir;

// A job of the mesh file `file` with the file's own materials (no job `material`).
absl::StatusOr<BakeJob> BuildFileJob(const TempDir& dir, const std::string& file,
                                     const JobLimits& limits = {}) {
  const std::string json =
      R"({"scene": {"meshes": [{"file": ")" + file +
      R"("}]}, "grid": {"min": [0, 0, 2], "max": [0, 0, 2], "counts": [1, 1, 1]}})";
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  EXPECT_TRUE(job.ok()) << job.status();
  if (!job.ok()) return job.status();
  return BuildBakeJob(*job, LocalAssetSource(dir.path()), limits);
}

// The albedo at the mesh's vertex `v` (of its first triangle holding it).
Vec3d AlbedoAtVertex(const BakeJob& job, uint32_t v) {
  const TriangleMesh& mesh = job.scene.meshes.at(0);
  for (uint32_t t = 0; t < mesh.TriangleCount(); ++t) {
    for (int k = 0; k < 3; ++k) {
      if (mesh.indices[3 * t + k] != v) continue;
      const double bu = k == 1 ? 1 : 0, bv = k == 2 ? 1 : 0;
      return AlbedoAt(job.scene.materials.at(mesh.material), mesh, t, bu, bv);
    }
  }
  ADD_FAILURE() << "vertex " << v << " is in no triangle";
  return {};
}

// The mesh vertex at position (x, y, 0).
uint32_t VertexAt(const BakeJob& job, double x, double y) {
  const TriangleMesh& mesh = job.scene.meshes.at(0);
  for (uint32_t v = 0; v < mesh.positions.size(); ++v)
    if (mesh.positions[v] == Vec3d(x, y, 0)) return v;
  ADD_FAILURE() << "no vertex at " << x << ", " << y;
  return 0;
}

constexpr double kWhiteBelowOne = 1.0 - 1.0 / (1 << 20);  // the clamped factor of 1

TEST(AuthoredMaterials, GltfBaseColourTextureAtTheTexelCentres) {
  TempDir dir;
  dir.Write("quadrants.png", Quadrants());
  // Each corner at a texel centre: (0,0,0) reads the top-left texel (glTF's v points down).
  dir.Write(
      "m.gltf",
      GltfQuad({0.25f, 0.25f, 0.75f, 0.25f, 0.75f, 0.75f, 0.25f, 0.75f}, {},
               R"({"name": "q", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1],
                         "metallicFactor": 0, "baseColorTexture": {"index": 0}}})",
               R"([{"uri": "quadrants.png"}])"));
  const absl::StatusOr<BakeJob> job = BuildFileJob(dir, "m.gltf");
  ASSERT_TRUE(job.ok()) << job.status();
  const Material& m = job->scene.materials.at(0);
  ASSERT_TRUE(m.albedoMap.image);
  EXPECT_TRUE(m.albedoMap.srgb);
  EXPECT_EQ(AlbedoAtVertex(*job, VertexAt(*job, 0, 0)), Vec3d(0.5, 0, 0));
  EXPECT_EQ(AlbedoAtVertex(*job, VertexAt(*job, 1, 0)), Vec3d(0, 0.5, 0));
  EXPECT_EQ(AlbedoAtVertex(*job, VertexAt(*job, 1, 1)), Vec3d(0.5, 0.5, 0.5));
  EXPECT_EQ(AlbedoAtVertex(*job, VertexAt(*job, 0, 1)), Vec3d(0, 0, 0.5));
}

TEST(AuthoredMaterials, KhrTextureTransformAsTheExtensionWritesIt) {
  // uv' = offset + R(rotation) (scale * uv), R = [cos -sin; sin cos] (the extension's GLSL).
  TempDir dir;
  dir.Write("quadrants.png", Quadrants());
  const std::vector<float> uv = {0.1f, 0.2f, 0.7f, 0.15f, 0.6f, 0.9f, 0.05f, 0.65f};
  const double ox = 0.3, oy = -0.2, rotation = 0.4, sx = 1.5, sy = 0.75;
  dir.Write("m.gltf", GltfQuad(uv, {},
                               R"({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0,
                         "extensions": {"KHR_texture_transform": {"offset": [0.3, -0.2],
                         "rotation": 0.4, "scale": [1.5, 0.75]}}}}})",
                               R"([{"uri": "quadrants.png"}])"));
  const absl::StatusOr<BakeJob> job = BuildFileJob(dir, "m.gltf");
  ASSERT_TRUE(job.ok()) << job.status();
  const TriangleMesh& mesh = job->scene.meshes.at(0);
  ASSERT_EQ(mesh.albedoUv.size(), mesh.positions.size());
  const double positions[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  for (int k = 0; k < 4; ++k) {
    const double u = sx * uv[2 * k], v = sy * uv[2 * k + 1];
    const double x = ox + std::cos(rotation) * u - std::sin(rotation) * v;
    const double y = oy + std::sin(rotation) * u + std::cos(rotation) * v;
    const std::array<float, 2>& got =
        mesh.albedoUv[VertexAt(*job, positions[k][0], positions[k][1])];
    EXPECT_NEAR(got[0], x, 1e-6) << k;
    EXPECT_NEAR(got[1], y, 1e-6) << k;
  }
}

TEST(AuthoredMaterials, EmbeddedImagesColoursAndEmissiveTextures) {
  TempDir dir;
  const std::string png = Png(1, 1, {255, 255, 255, 255});
  const std::string uri = "data:image/png;base64," + absl::Base64Escape(png);
  dir.Write("m.gltf",
            GltfQuad({0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f},
                     {1, 0.5f, 0.25f, 1, 1, 0.5f, 0.25f, 1, 1, 0.5f, 0.25f, 1, 1, 0.5f, 0.25f, 1},
                     R"({"name": "glow", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                         "metallicFactor": 0},
                         "emissiveFactor": [1, 1, 0.5], "emissiveTexture": {"index": 0}})",
                     "[{\"uri\": \"" + uri + "\"}]"));
  const absl::StatusOr<BakeJob> job = BuildFileJob(dir, "m.gltf");
  ASSERT_TRUE(job.ok()) << job.status();
  const Material& m = job->scene.materials.at(0);
  ASSERT_TRUE(m.emissionMap.image);
  EXPECT_TRUE(m.vertexColors);
  const TriangleMesh& mesh = job->scene.meshes.at(0);
  // COLOR_0 is linear: read as written.
  EXPECT_EQ(AlbedoAtVertex(*job, 0),
            Vec3d(kWhiteBelowOne, kWhiteBelowOne * 0.5, kWhiteBelowOne * 0.25));
  EXPECT_EQ(EmissionAt(m, mesh, 0, 0.2, 0.3), Vec3d(1, 1, 0.5));
}

TEST(AuthoredMaterials, PlyColoursAreDisplayValues) {
  TempDir dir;
  dir.Write("c.ply", R"(ply
format ascii 1.0
element vertex 3
property float x
property float y
property float z
property uchar red
property uchar green
property uchar blue
element face 1
property list uchar int vertex_indices
end_header
0 0 0 255 128 0
1 0 0 255 128 0
0 1 0 255 128 0
3 0 1 2
)");
  const absl::StatusOr<BakeJob> job = BuildFileJob(dir, "c.ply");
  ASSERT_TRUE(job.ok()) << job.status();
  const Material& m = job->scene.materials.at(0);
  ASSERT_TRUE(m.vertexColors);
  const Vec3d albedo = AlbedoAtVertex(*job, 0);
  const double grey = std::pow((128 / 255.0 + 0.055) / 1.055, 2.4);  // sRGB 128
  EXPECT_NEAR(albedo.x, m.albedo.x, 1e-7);
  EXPECT_NEAR(albedo.y, m.albedo.y * grey, 1e-7);
  EXPECT_EQ(albedo.z, 0);
}

TEST(AuthoredMaterials, ObjMapKdWithVUp) {
  // An OBJ's vt (0, 0) is the image's bottom-left corner.
  TempDir dir;
  dir.Write("quadrants.png", Quadrants());
  dir.Write("m.mtl", "newmtl q\nKd 0.5 0.5 0.5\nmap_Kd quadrants.png\n");
  dir.Write("m.obj", R"(mtllib m.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0.25 0.25
vt 0.75 0.25
vt 0.75 0.75
vt 0.25 0.75
usemtl q
f 1/1 2/2 3/3 4/4
)");
  const absl::StatusOr<BakeJob> job = BuildFileJob(dir, "m.obj");
  ASSERT_TRUE(job.ok()) << job.status();
  EXPECT_EQ(AlbedoAtVertex(*job, VertexAt(*job, 0, 0)), Vec3d(0, 0, 0.5));  // bottom-left: blue
  EXPECT_EQ(AlbedoAtVertex(*job, VertexAt(*job, 1, 1)), Vec3d(0, 0.5, 0));  // top-right: green
}

TEST(AuthoredMaterials, CutoutsAndDoubleSidedMaterials) {
  TempDir dir;
  dir.Write("quadrants.png", Quadrants());
  const std::vector<float> uv(8, 0.5f);
  const auto material = [&](const std::string& json) -> Material {
    dir.Write("m.gltf", GltfQuad(uv, {}, json, R"([{"uri": "quadrants.png"}])"));
    const absl::StatusOr<BakeJob> job = BuildFileJob(dir, "m.gltf");
    EXPECT_TRUE(job.ok()) << job.status();
    return job.ok() ? job->scene.materials.at(0) : Material{};
  };
  const Material mask = material(
      R"({"alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": true,
          "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.25]}})");
  EXPECT_FLOAT_EQ(float(mask.alphaCutoff), 0.3f);
  EXPECT_EQ(mask.coverage, 0.25);
  EXPECT_TRUE(mask.doubleSided);
  const Material blend = material(R"({"alphaMode": "BLEND"})");
  EXPECT_EQ(blend.alphaCutoff, 0.5);
  EXPECT_FALSE(blend.doubleSided);
  const Material opaque =
      material(R"({"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0]}})");
  EXPECT_FALSE(opaque.HasCutout());

  // OBJ: d below 1 or a map_d cut out at 0.5; map_d reads alpha, or red without alpha.
  std::string grey;  // 2 x 1, one grey channel: 0 then 255
  const uint8_t texels[2] = {0, 255};
  stbi_write_png_to_func(
      [](void* context, void* data, int size) {
        static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
      },
      &grey, 2, 1, 1, texels, 2);
  dir.Write("grey.png", grey);
  dir.Write("m.mtl", "newmtl a\nKd 0.5 0.5 0.5\nd 0.4\nnewmtl b\nKd 0.5 0.5 0.5\nmap_d grey.png\n");
  dir.Write("m.obj", R"(mtllib m.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0.25 0.5
vt 0.75 0.5
vt 0.75 0.5
usemtl a
f 1/1 2/2 3/3
usemtl b
f 1/1 3/3 4/2
)");
  const absl::StatusOr<BakeJob> job = BuildFileJob(dir, "m.obj");
  ASSERT_TRUE(job.ok()) << job.status();
  ASSERT_EQ(job->scene.materials.size(), 2u);
  const Material& a = job->scene.materials[0];
  const Material& b = job->scene.materials[1];
  EXPECT_EQ(a.alphaCutoff, 0.5);
  EXPECT_FLOAT_EQ(float(a.coverage), 0.4f);
  EXPECT_EQ(b.alphaCutoff, 0.5);
  ASSERT_TRUE(b.coverageMap.image);
  EXPECT_FALSE(b.coverageMap.srgb);
  // Without alpha, the grey value: 0 at the first texel's centre, 1 at the second's.
  const TriangleMesh& mb = job->scene.meshes[1];
  EXPECT_EQ(CoverageAt(b, mb, 0, 0, 0), 0.0);
  EXPECT_EQ(CoverageAt(b, mb, 0, 1, 0), 1.0);
}

// Bakes `file` with the file's materials and `lights` (JSON) as the job's lights; one probe at the
// origin.
absl::StatusOr<ProbeVolume> BakeWithLights(const TempDir& dir, const std::string& file,
                                           const std::string& lights) {
  const std::string json = R"({"scene": {"meshes": [{"file": ")" + file + R"("}], "lights": [)" +
                           lights + R"(]}, "grid": {"min": [0, 0, 0], "max": [0, 0, 0],
                           "counts": [1, 1, 1], "placement": "ALL"},
                           "settings": {"samplesPerProbe": 256, "shOrder": 2}})";
  const absl::StatusOr<v1::JobSpec> spec = ParseJobJson(json);
  if (!spec.ok()) return spec.status();
  PB_ASSIGN_OR_RETURN(const BakeJob job,
                      BuildBakeJob(*spec, LocalAssetSource(dir.path()), JobLimits{}));
  return Bake(job, BakeOptions{});
}

TEST(AuthoredMaterials, KhrLightsEqualTheJobsLightsAt683LumensPerWatt) {
  // Each light of the file, placed by its node, bakes the same bits as the job's light with
  // intensity (or irradiance) = the file's candela (or lux) / 683 on the same quad.
  struct Case {
    std::string what, gltfLight, node, jobLight;
  };
  const std::vector<Case> cases = {
      {"point", R"({"type": "point", "color": [1, 0.5, 0.25], "intensity": 1366})",
       R"("translation": [0.5, 0.25, 2])",
       R"({"point": {"position": [0.5, 0.25, 2], "intensity": [2, 1, 0.5]}})"},
      {"spot",
       R"({"type": "spot", "color": [1, 1, 0.5], "intensity": 683,
           "spot": {"innerConeAngle": 0.25, "outerConeAngle": 0.75}})",
       R"("translation": [0.25, 0, 1.5])",
       R"({"spot": {"position": [0.25, 0, 1.5], "direction": [0, 0, -1], "intensity": [1, 1, 0.5],
           "innerAngleDeg": 14.32394487827058, "outerAngleDeg": 42.97183463481174}})"},
      {"directional", R"({"type": "directional", "color": [0.5, 1, 1], "intensity": 2049})",
       R"("translation": [3, 3, 3])",
       R"({"directional": {"direction": [0, 0, -1], "irradiance": [1.5, 3, 3]}})"},
  };
  for (const Case& c : cases) {
    TempDir dir;
    dir.Write("lit.gltf", GltfWithLight(c.gltfLight, c.node));
    dir.Write("dark.gltf", GltfWithLight("", R"("translation": [0, 0, 0])"));
    const absl::StatusOr<ProbeVolume> file = BakeWithLights(dir, "lit.gltf", "");
    const absl::StatusOr<ProbeVolume> job = BakeWithLights(dir, "dark.gltf", c.jobLight);
    ASSERT_TRUE(file.ok()) << c.what << ": " << file.status();
    ASSERT_TRUE(job.ok()) << c.what << ": " << job.status();
    EXPECT_GT(std::abs(file->radiance[0][0]), 0) << c.what;
    for (int k = 0; k < file->CoeffCount(); ++k) {
      for (int ch = 0; ch < 3; ++ch) {
        // The spot's cone angles pass through degrees: a few ulps.
        EXPECT_NEAR(file->radiance[k][ch], job->radiance[k][ch],
                    c.what == "spot" ? 1e-5 * std::abs(job->radiance[0][ch]) : 0.0)
            << c.what << " coefficient " << k << " channel " << ch;
      }
    }
  }
}

TEST(AuthoredMaterials, KhrLightsFollowTheirNodesAndTheMeshTransform) {
  TempDir dir;
  // A spot under a node rotated a quarter turn about x (-z to +y), translated; the mesh moved
  // by +10 along x.
  dir.Write("lit.gltf",
            GltfWithLight(R"({"type": "spot", "intensity": 683, "spot": {"outerConeAngle": 0.5}})",
                          R"("translation": [1, 2, 3], "rotation": [0.7071067811865476, 0, 0,
                              0.7071067811865476])"));
  const absl::StatusOr<v1::JobSpec> spec = ParseJobJson(
      R"({"scene": {"meshes": [{"file": "lit.gltf", "transform": [1,0,0,10, 0,1,0,0, 0,0,1,0,
      0,0,0,1]}]}, "grid": {"min": [0, 0, 0], "max": [0, 0, 0], "counts": [1, 1, 1]}})");
  ASSERT_TRUE(spec.ok()) << spec.status();
  const absl::StatusOr<BakeJob> job =
      BuildBakeJob(*spec, LocalAssetSource(dir.path()), JobLimits{});
  ASSERT_TRUE(job.ok()) << job.status();
  ASSERT_EQ(job->scene.lights.size(), 1u);
  const auto* spot = std::get_if<SpotLight>(&job->scene.lights[0]);
  ASSERT_NE(spot, nullptr);
  EXPECT_NEAR(spot->position.x, 11, 1e-12);
  EXPECT_NEAR(spot->position.y, 2, 1e-12);
  EXPECT_NEAR(spot->position.z, 3, 1e-12);
  EXPECT_NEAR(spot->direction.y, 1, 1e-6);
  EXPECT_NEAR(spot->cosOuter, std::cos(0.5), 1e-7);
  EXPECT_EQ(spot->cosInner, 1.0);  // innerConeAngle defaults to 0
  EXPECT_EQ(spot->intensity, Vec3d(1, 1, 1));
}

TEST(AuthoredMaterials, ExtensionsThatDoNotChangeDiffuseTransportAreListed) {
  TempDir dir;
  std::string gltf = GltfQuad(std::vector<float>(8, 0.5f), {}, R"({"name": "m"})", "[]", "[]");
  // No textures: drop the texture table the helper writes.
  gltf.replace(gltf.find(R"("textures": [{"source": 0, "sampler": 0}],)"),
               std::string(R"("textures": [{"source": 0, "sampler": 0}],)").size(), "");
  gltf.replace(gltf.find(R"("extensionsUsed": ["KHR_texture_transform"])"),
               std::string(R"("extensionsUsed": ["KHR_texture_transform"])").size(),
               R"("extensionsUsed": ["KHR_texture_transform", "KHR_materials_sheen",
                   "KHR_materials_clearcoat", "KHR_materials_ior"])");
  dir.Write("m.gltf", gltf);
  const absl::StatusOr<BakeJob> job = BuildFileJob(dir, "m.gltf");
  ASSERT_TRUE(job.ok()) << job.status();
  const std::vector<std::string> expected = {"scene.meshes[0]: KHR_materials_clearcoat",
                                             "scene.meshes[0]: KHR_materials_ior",
                                             "scene.meshes[0]: KHR_materials_sheen"};
  EXPECT_EQ(job->ignored, expected);
  // Nothing to list in a file without extensions.
  dir.Write("q.gltf",
            GltfQuad(std::vector<float>(8, 0.5f), {}, R"({"name": "m"})", R"([{"uri": "q.png"}])"));
  dir.Write("q.png", Quadrants());
  const absl::StatusOr<BakeJob> plain = BuildFileJob(dir, "q.gltf");
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_TRUE(plain->ignored.empty());
}

TEST(AuthoredMaterials, BadTexturesAreRefusedNamingTheFieldTheMaterialAndThePath) {
  TempDir dir;
  const std::string material =
      R"({"name": "wall", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})";
  const std::vector<float> uv(8, 0.5f);
  dir.Write("bad.png", "png bytes");
  dir.Write("m.gltf", GltfQuad(uv, {}, material, R"([{"uri": "bad.png"}])"));
  EXPECT_TRUE(HasFieldError(BuildFileJob(dir, "m.gltf").status(), "scene.meshes[0].file",
                            "texture \"bad.png\" of material \"wall\": not a PNG, JPEG"));
  dir.Write("big.png", Png(2, 2, std::vector<uint8_t>(16, 255)));
  dir.Write("m.gltf", GltfQuad(uv, {}, material, R"([{"uri": "big.png"}])"));
  JobLimits limits;
  limits.maxTexturePixels = 3;
  EXPECT_TRUE(HasFieldError(BuildFileJob(dir, "m.gltf", limits).status(), "scene.meshes[0].file",
                            "texture \"big.png\" of material \"wall\": 2 x 2 pixels, above the "
                            "limit of 3"));
  limits.maxTexturePixels = 4;
  EXPECT_TRUE(BuildFileJob(dir, "m.gltf", limits).ok());
  dir.Write("m.gltf", GltfQuad(uv, {}, material, R"([{"uri": "missing.png"}])"));
  EXPECT_TRUE(
      HasFieldError(BuildFileJob(dir, "m.gltf").status(), "scene.meshes[0].file", "missing.png"));
}

}  // namespace
}  // namespace probebake
