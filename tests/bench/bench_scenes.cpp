#include "bench_scenes.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <variant>

#include "bench_util.h"
#include "probebake/base/status.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

namespace probebake::bench {
namespace {

constexpr double kPi = std::numbers::pi;

// Appends an OBJ vertex; fixed precision keeps the file (and so the job digest) identical on
// every run.
void AddVertex(std::string* obj, double x, double y, double z) {
  *obj += Format("v %.6f %.6f %.6f\n", x, y, z);
}
void AddFace(std::string* obj, int a, int b, int c) {
  *obj += Format("f %d %d %d\n", a, b, c);
}

// A pillar: an open-bottomed cylinder standing on z = 0, faces counter-clockwise seen from
// outside. `first` is the OBJ index (1-based) of its first vertex; returns the next one.
int AddPillar(std::string* obj, int first, double cx, double cy, double radius, double height,
              int segments, int rings) {
  for (int k = 0; k <= rings; ++k) {
    const double z = height * k / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2 * kPi * j / segments;
      AddVertex(obj, cx + radius * std::cos(phi), cy + radius * std::sin(phi), z);
    }
  }
  auto index = [&](int k, int j) { return first + k * segments + (j % segments); };
  for (int k = 0; k < rings; ++k) {
    for (int j = 0; j < segments; ++j) {
      AddFace(obj, index(k, j), index(k, j + 1), index(k + 1, j + 1));
      AddFace(obj, index(k, j), index(k + 1, j + 1), index(k + 1, j));
    }
  }
  const int top = first + (rings + 1) * segments;
  AddVertex(obj, cx, cy, height);
  for (int j = 0; j < segments; ++j) AddFace(obj, top, index(rings, j), index(rings, j + 1));
  return top + 1;
}

// A lat-long sphere with pole vertices, faces counter-clockwise seen from outside.
int AddSphere(std::string* obj, int first, const Vec3d& c, double radius, int segments, int rings) {
  AddVertex(obj, c.x, c.y, c.z + radius);  // north pole: index first
  for (int i = 1; i < rings; ++i) {
    const double theta = kPi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2 * kPi * j / segments;
      AddVertex(obj, c.x + radius * std::sin(theta) * std::cos(phi),
                c.y + radius * std::sin(theta) * std::sin(phi), c.z + radius * std::cos(theta));
    }
  }
  const int south = first + 1 + (rings - 1) * segments;
  AddVertex(obj, c.x, c.y, c.z - radius);
  auto index = [&](int i, int j) { return first + 1 + (i - 1) * segments + (j % segments); };
  for (int j = 0; j < segments; ++j) AddFace(obj, first, index(1, j), index(1, j + 1));
  for (int i = 1; i < rings - 1; ++i) {
    for (int j = 0; j < segments; ++j) {
      AddFace(obj, index(i, j), index(i + 1, j), index(i + 1, j + 1));
      AddFace(obj, index(i, j), index(i + 1, j + 1), index(i, j + 1));
    }
  }
  for (int j = 0; j < segments; ++j)
    AddFace(obj, south, index(rings - 1, j + 1), index(rings - 1, j));
  return south + 1;
}

// The courtyard's detail mesh: eight finely tessellated pillars along the walls and a sculpture
// sphere, ~140k triangles.
std::string CourtyardDetailObj() {
  std::string obj = "# probebake bench: courtyard pillars and sculpture (generated)\n";
  int next = 1;
  const double pillarX[2] = {-4.9, 4.9};
  const double pillarY[4] = {-4.0, -1.3, 1.3, 4.0};
  for (double x : pillarX)
    for (double y : pillarY) next = AddPillar(&obj, next, x, y, 0.25, 3.6, 96, 48);
  next = AddSphere(&obj, next, {0.5, 0.8, 1.2}, 1.0, 256, 128);
  return obj;
}

absl::Status Materialise(const std::string& dir, const std::string& name,
                         const std::string& bytes) {
  const std::string path = dir + "/" + name;
  absl::StatusOr<std::string> existing = ReadFileBytes(path);
  if (existing.ok() && *existing == bytes) return absl::OkStatus();
  return WriteFileAtomic(path, bytes);
}

}  // namespace

absl::StatusOr<std::vector<BenchScene>> PrepareScenes(const std::string& sourceDir,
                                                      const std::string& workDir, bool quick) {
  std::vector<BenchScene> scenes;

  BenchScene skySphere;
  skySphere.name = "sky_sphere";
  skySphere.description =
      "uniform sky over a black ground and a small bright sphere light (closed form)";
  skySphere.jobPath = sourceDir + "/tests/bench/scenes/sky_sphere.json";
  skySphere.analytic = true;
  skySphere.counts = quick ? std::vector<int>{4, 4, 2} : std::vector<int>{8, 8, 4};
  scenes.push_back(skySphere);

  BenchScene demo;
  demo.name = "demo";
  demo.description = "demo room: window onto an HDR sky, sun, ceiling light, boxes (34 triangles)";
  demo.jobPath = sourceDir + "/tests/data/demo/demo.json";
  demo.counts = quick ? std::vector<int>{4, 3, 2} : std::vector<int>{8, 6, 3};
  scenes.push_back(demo);

  // The courtyard: copy its job file and the sky next to the generated mesh.
  const std::string dir = workDir + "/scenes/courtyard";
  std::filesystem::create_directories(dir);
  PB_ASSIGN_OR_RETURN(const std::string job,
                      ReadFileBytes(sourceDir + "/tests/bench/scenes/courtyard.json"));
  PB_ASSIGN_OR_RETURN(const std::string sky, ReadFileBytes(sourceDir + "/tests/data/demo/sky.exr"));
  PB_RETURN_IF_ERROR(Materialise(dir, "courtyard.json", job));
  PB_RETURN_IF_ERROR(Materialise(dir, "sky.exr", sky));
  PB_RETURN_IF_ERROR(Materialise(dir, "courtyard_detail.obj", CourtyardDetailObj()));
  BenchScene courtyard;
  courtyard.name = "courtyard";
  courtyard.description =
      "open courtyard: small bright rect lantern + dim HDR sky, ~140k triangles of pillars and a "
      "sculpture";
  courtyard.jobPath = dir + "/courtyard.json";
  if (quick) courtyard.counts = {4, 4, 2};
  scenes.push_back(courtyard);
  return scenes;
}

absl::StatusOr<v1::JobSpec> SceneSpec(const BenchScene& scene, const v1::BakeSettings& settings) {
  PB_ASSIGN_OR_RETURN(v1::JobSpec spec, ReadJobFile(scene.jobPath));
  if (!scene.counts.empty()) {
    v1::Grid* grid = spec.mutable_grid();
    grid->clear_spacing();
    grid->clear_counts();
    for (int c : scene.counts) grid->add_counts(c);
  }
  *spec.mutable_settings() = settings;
  return spec;
}

absl::StatusOr<BakeJob> BuildSceneJob(const BenchScene& scene, const v1::BakeSettings& settings) {
  PB_ASSIGN_OR_RETURN(const v1::JobSpec spec, SceneSpec(scene, settings));
  const JobLimits limits;
  const LocalAssetSource assets(JobFileDir(scene.jobPath), "", limits.maxAssetBytes);
  return BuildBakeJob(spec, assets, limits);
}

}  // namespace probebake::bench
