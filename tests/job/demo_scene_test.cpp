// The bundled demo level (tests/data/demo/demo-gltf.json: loft.gltf, authored +Y up with its own
// materials, textures, a cutout trellis and a KHR lamp) is read as authored: the room of
// demo.json, turned +Z up by the job's transform, with the file's materials and light.
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <variant>

#include "core/src/bake/surface_material.h"
#include "probebake/job/job.h"

namespace probebake {
namespace {

const std::string kDemo = std::string(PROBEBAKE_TEST_DATA_DIR) + "/demo/";

double Area(const Scene& scene, const std::string& skipMaterial = "") {
  double area = 0;
  for (const TriangleMesh& m : scene.meshes) {
    for (size_t t = 0; t < m.TriangleCount(); ++t) {
      const Vec3d& a = m.positions[m.indices[3 * t]];
      const Vec3d& b = m.positions[m.indices[3 * t + 1]];
      const Vec3d& c = m.positions[m.indices[3 * t + 2]];
      if (!scene.materials[m.material].name.ends_with(skipMaterial) || skipMaterial.empty())
        area += Length(Cross(b - a, c - a)) / 2;
    }
  }
  return area;
}

TEST(DemoScene, TheAuthoredLoftIsReadAsAuthored) {
  const absl::StatusOr<BakeJob> loft = LoadBakeJob(kDemo + "demo-gltf.json", JobLimits{});
  ASSERT_TRUE(loft.ok()) << loft.status();
  const absl::StatusOr<BakeJob> room = LoadBakeJob(kDemo + "demo.json", JobLimits{});
  ASSERT_TRUE(room.ok()) << room.status();

  std::map<std::string, const Material*> materials;
  // A file's materials are named "<mesh field>:<the file's name>".
  for (const Material& m : loft->scene.materials)
    materials[m.name.substr(m.name.find(':') + 1)] = &m;
  ASSERT_EQ(materials.size(), 8u);
  for (const char* textured : {"floor planks", "wallpaper", "crate", "trellis"}) {
    ASSERT_TRUE(materials.count(textured)) << textured;
    EXPECT_TRUE(materials[textured]->albedoMap.image) << textured;
    EXPECT_TRUE(materials[textured]->albedoMap.srgb) << textured;
  }
  const Material& trellis = *materials["trellis"];
  EXPECT_TRUE(trellis.HasCutout());
  EXPECT_TRUE(trellis.doubleSided);
  // Slats 4 texels wide every 16 both ways: 1 - (12/16)^2 of the texels stay (the viewer's
  // opacity for it); materials without a texture show their factors (below).
  EXPECT_DOUBLE_EQ(KeptFraction(trellis), 1 - 0.75 * 0.75);
  for (const char* plain : {"plaster", "red paint", "green paint", "slate"}) {
    ASSERT_TRUE(materials.count(plain)) << plain;
    EXPECT_FALSE(materials[plain]->AlbedoVaries()) << plain;
    EXPECT_FALSE(materials[plain]->HasCutout()) << plain;
    EXPECT_EQ(KeptFraction(*materials[plain]), 1.0) << plain;
    EXPECT_EQ(MeanAlbedo(*materials[plain]), materials[plain]->albedo) << plain;
  }
  // Factors are float in the file: within float's rounding of demo.json's albedos.
  EXPECT_NEAR(materials["red paint"]->albedo.x, 0.65, 1e-7);
  EXPECT_NEAR(materials["slate"]->albedo.z, 0.55, 1e-7);

  // The lamp: 3074 cd of colour (1, 0.917, 0.792) at 683 lm/W, at (0, -0.75, 2.6) once the
  // file's +Y up is turned +Z up; and the job's sun.
  ASSERT_EQ(loft->scene.lights.size(), 2u);
  int points = 0;
  for (const Light& light : loft->scene.lights) {
    if (const auto* p = std::get_if<PointLight>(&light)) {
      ++points;
      EXPECT_NEAR(p->position.x, 0, 1e-6);
      EXPECT_NEAR(p->position.y, -0.75, 1e-6);
      EXPECT_NEAR(p->position.z, 2.6, 1e-6);
      EXPECT_NEAR(p->intensity.x, 3074.0 / 683, 1e-5);
      EXPECT_NEAR(p->intensity.y, 0.917 * 3074 / 683, 1e-5);
      EXPECT_NEAR(p->intensity.z, 0.792 * 3074 / 683, 1e-5);
    }
  }
  EXPECT_EQ(points, 1);

  // The same room as demo.json plus the 3 x 2.4 m trellis: the areas agree to float's rounding
  // of the file's coordinates (relative 6e-8 each, on areas of about 240 m^2).
  const double roomArea = Area(room->scene);
  EXPECT_NEAR(Area(loft->scene, "trellis"), roomArea, 1e-5 * roomArea);
  EXPECT_NEAR(Area(loft->scene) - Area(loft->scene, "trellis"), 3 * 2.4, 1e-5);
  for (int a = 0; a < 3; ++a) {
    double lo = 1e9, hi = -1e9;
    for (const TriangleMesh& m : loft->scene.meshes)
      for (const Vec3d& p : m.positions) {
        lo = std::min(lo, p[a]);
        hi = std::max(hi, p[a]);
      }
    const double want[3][2] = {{-4, 4}, {-3, 3}, {0, 3}};
    EXPECT_NEAR(lo, want[a][0], 1e-6) << "axis " << a;
    EXPECT_NEAR(hi, want[a][1], 1e-6) << "axis " << a;
  }
}

}  // namespace
}  // namespace probebake
