// Mesh imports handed from one process to another (probebake/job/mesh_imports.h): a job built
// from recorded imports is the job built by importing, bit for bit, without the parent reading a
// single referenced file; a damaged or mismatched hand-over is refused, never trusted.
#include "probebake/job/mesh_imports.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/src/job/imported_mesh_codec.h"
#include "job/gltf_test_files.h"
#include "job/test_util.h"
#include "probebake/bake/bake.h"
#include "probebake/job/digest.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

namespace probebake {
namespace {

using testing::GltfQuad;
using testing::GltfWithLight;
using testing::Png;
using testing::Quadrants;
using testing::TempDir;

// Files beside the job, but no file a model references: what a parent that never imports needs.
class NoReferencesSource final : public AssetSource {
 public:
  explicit NoReferencesSource(const std::filesystem::path& dir) : files_(dir) {}
  absl::StatusOr<std::string> ReadFile(const std::string& path,
                                       const std::string& field) const override {
    return files_.ReadFile(path, field);
  }
  absl::StatusOr<std::string> ReadBlob(const v1::Digest& digest,
                                       const std::string& field) const override {
    return files_.ReadBlob(digest, field);
  }
  absl::StatusOr<std::string> ReadReferencedFile(const std::string&, const std::string& modelPath,
                                                 const std::string& field) const override {
    return absl::FailedPreconditionError(field + ": read " + modelPath);
  }

 private:
  LocalAssetSource files_;
};

// A scene with every kind of data an import hands over: a textured, vertex-coloured, emissive
// glTF quad whose image is a file beside it; a glTF with a spot light, moved by the job; an OBJ
// under a job material (the file's materials not read).
struct Scene3 {
  TempDir dir;
  v1::JobSpec spec;
  Scene3() {
    dir.Write("quadrants.png", Quadrants());
    dir.Write("textured.gltf",
              GltfQuad({0.25f, 0.25f, 0.75f, 0.25f, 0.75f, 0.75f, 0.25f, 0.75f},
                       {1, 0.5f, 0.25f, 1, 1, 0.5f, 0.25f, 1, 1, 0.5f, 0.25f, 1, 1, 0.5f, 0.25f, 1},
                       R"({"name": "q", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                           "metallicFactor": 0}, "emissiveFactor": [0.5, 0.5, 0.5],
                           "emissiveTexture": {"index": 0}, "alphaMode": "MASK",
                           "doubleSided": true})",
                       R"([{"uri": "quadrants.png"}])"));
    dir.Write(
        "lit.gltf",
        GltfWithLight(R"({"type": "spot", "intensity": 683, "spot": {"outerConeAngle": 0.5}})",
                      R"("translation": [0.5, 0.5, 3])"));
    dir.Write("floor.obj", "v -2 -2 -1\nv 2 -2 -1\nv 2 2 -1\nv -2 2 -1\nf 1 2 3 4\n");
    const absl::StatusOr<v1::JobSpec> parsed = ParseJobJson(R"({"scene": {
        "materials": [{"name": "grey", "albedo": [0.5, 0.5, 0.5]}],
        "meshes": [{"file": "textured.gltf"},
                   {"file": "lit.gltf", "transform": [1,0,0,0.25, 0,1,0,0, 0,0,1,0, 0,0,0,1]},
                   {"file": "floor.obj", "material": "grey"}]},
        "grid": {"min": [0.5, 0.5, 1], "max": [0.5, 0.5, 1], "counts": [1, 1, 1],
                 "placement": "ALL"},
        "settings": {"samplesPerProbe": 64, "shOrder": 2}})");
    EXPECT_TRUE(parsed.ok()) << parsed.status();
    if (parsed.ok()) spec = *parsed;
  }
};

TEST(MeshImports, AJobBuiltFromHandedOverImportsIsTheImportedJob) {
  Scene3 scene;
  MeshImports recorded;
  const absl::StatusOr<BakeJob> imported =
      BuildBakeJob(scene.spec, LocalAssetSource(scene.dir.path()), JobLimits{}, {&recorded});
  ASSERT_TRUE(imported.ok()) << imported.status();
  EXPECT_EQ(recorded.size(), 3u);
  const absl::StatusOr<MeshImports> handed = MeshImports::Parse(recorded.Serialize());
  ASSERT_TRUE(handed.ok()) << handed.status();

  // The parent's side reads no referenced file: importing there would fail.
  const NoReferencesSource parentFiles(scene.dir.path());
  const absl::Status importing = BuildBakeJob(scene.spec, parentFiles, JobLimits{}).status();
  EXPECT_NE(importing.message().find("read quadrants.png"), absl::string_view::npos) << importing;
  const absl::StatusOr<BakeJob> built =
      BuildBakeJob(scene.spec, parentFiles, JobLimits{}, {nullptr, &*handed});
  ASSERT_TRUE(built.ok()) << built.status();

  EXPECT_EQ(built->jobDigest, imported->jobDigest);
  EXPECT_EQ(built->sceneDigest, imported->sceneDigest);
  EXPECT_EQ(built->ignored, imported->ignored);
  ASSERT_EQ(built->scene.meshes.size(), imported->scene.meshes.size());
  for (size_t m = 0; m < built->scene.meshes.size(); ++m) {
    const TriangleMesh &a = built->scene.meshes[m], &b = imported->scene.meshes[m];
    EXPECT_EQ(a.positions, b.positions) << m;
    EXPECT_EQ(a.indices, b.indices) << m;
    EXPECT_EQ(a.material, b.material) << m;
    EXPECT_EQ(a.albedoUv, b.albedoUv) << m;
    EXPECT_EQ(a.emissionUv, b.emissionUv) << m;
    EXPECT_EQ(a.colors, b.colors) << m;
  }
  ASSERT_EQ(built->scene.materials.size(), imported->scene.materials.size());
  for (size_t m = 0; m < built->scene.materials.size(); ++m) {
    const Material &a = built->scene.materials[m], &b = imported->scene.materials[m];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.albedo, b.albedo);
    EXPECT_EQ(a.emission, b.emission);
    EXPECT_EQ(a.alphaCutoff, b.alphaCutoff);
    EXPECT_EQ(a.doubleSided, b.doubleSided);
    EXPECT_EQ(a.vertexColors, b.vertexColors);
    EXPECT_EQ(bool(a.albedoMap.image), bool(b.albedoMap.image));
    if (a.albedoMap.image && b.albedoMap.image) {
      EXPECT_EQ(a.albedoMap.image->rgba, b.albedoMap.image->rgba);
    }
  }
  // The textured material's two maps share one image, handed over once.
  const Material& textured = built->scene.materials.at(1);
  ASSERT_TRUE(textured.albedoMap.image && textured.emissionMap.image);
  EXPECT_EQ(textured.albedoMap.image.get(), textured.emissionMap.image.get());
  ASSERT_EQ(built->scene.lights.size(), 1u);

  // What the tracer makes of the two: the same bits.
  const absl::StatusOr<ProbeVolume> a = Bake(*built, BakeOptions{});
  const absl::StatusOr<ProbeVolume> b = Bake(*imported, BakeOptions{});
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_GT(std::abs(a->radiance[0][0]), 0);
  for (int k = 0; k < a->CoeffCount(); ++k)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(a->radiance[k][c], b->radiance[k][c]) << k << " " << c;
}

TEST(MeshImports, AnEntryForOtherBytesOrAnotherMeshIsRefused) {
  Scene3 scene;
  MeshImports recorded;
  ASSERT_TRUE(
      BuildBakeJob(scene.spec, LocalAssetSource(scene.dir.path()), JobLimits{}, {&recorded}).ok());
  // The file changed after the child read it.
  scene.dir.Write("floor.obj", "v -3 -2 -1\nv 2 -2 -1\nv 2 2 -1\nv -2 2 -1\nf 1 2 3 4\n");
  const absl::Status changed = BuildBakeJob(scene.spec, LocalAssetSource(scene.dir.path()),
                                            JobLimits{}, {nullptr, &recorded})
                                   .status();
  EXPECT_EQ(changed.code(), absl::StatusCode::kInternal) << changed;
  EXPECT_NE(changed.message().find("scene.meshes[2] was imported from other bytes"),
            absl::string_view::npos)
      << changed;
  // Entries of another job.
  MeshImports partial;
  partial.Put(0, *recorded.Find(0));
  const absl::Status missing =
      BuildBakeJob(scene.spec, LocalAssetSource(scene.dir.path()), JobLimits{}, {nullptr, &partial})
          .status();
  EXPECT_EQ(missing.code(), absl::StatusCode::kInternal) << missing;
  EXPECT_NE(missing.message().find("no entry for scene.meshes[1]"), absl::string_view::npos)
      << missing;
}

TEST(MeshImports, EveryCutOfAHandOverIsRefused) {
  Scene3 scene;
  MeshImports recorded;
  ASSERT_TRUE(
      BuildBakeJob(scene.spec, LocalAssetSource(scene.dir.path()), JobLimits{}, {&recorded}).ok());
  const std::string bytes = recorded.Serialize();
  for (size_t n = 0; n < bytes.size(); ++n)
    EXPECT_FALSE(MeshImports::Parse(std::string_view(bytes).substr(0, n)).ok()) << n;
  EXPECT_FALSE(MeshImports::Parse(bytes + "x").ok());
  // Each entry cut anywhere, or with a count raised: a clear refusal, never a read past its end.
  for (int mesh = 0; mesh < 3; ++mesh) {
    const std::string entry = *recorded.Find(mesh);
    const job_internal::ImportBinding binding{
        mesh,
        Sha256Hex(*LocalAssetSource(scene.dir.path())
                       .ReadFile(scene.spec.scene().meshes(mesh).file(), "f")),
        mesh == 2 ? "obj" : "gltf", mesh != 2};
    ASSERT_TRUE(job_internal::DecodeImportedMesh(entry, binding).ok()) << mesh;
    for (size_t n = 0; n < entry.size(); ++n) {
      const absl::Status cut =
          job_internal::DecodeImportedMesh(std::string_view(entry).substr(0, n), binding).status();
      ASSERT_EQ(cut.code(), absl::StatusCode::kInternal) << mesh << " cut at " << n;
    }
    for (size_t at = 0; at + 8 <= entry.size(); at += 8) {
      std::string raised = entry;
      raised[at + 7] = char(0x7f);  // a huge count, or a wrong value, wherever it lands
      (void)job_internal::DecodeImportedMesh(raised, binding);  // must not crash or allocate it
    }
  }
}

}  // namespace
}  // namespace probebake
