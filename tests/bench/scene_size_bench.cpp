// Google Benchmark of scenes of real size: a glTF level of many nodes, each instancing one of a
// few meshes of many primitives (the way a DCC tool exports a level built from a kit of props),
// written to a temporary folder and read as a job reads it.
//
// BM_LevelImport times BuildBakeJob (assimp's import; every mesh moved into world space, or what
// several nodes place kept once with their placements: JobLimits::flattenUpToTriangles decides,
// set here to flatten or to instance); BM_LevelTracerBuild
// times the Embree scene of the imported job (TracerScene::Build: one BVH per instanced mesh, one
// instance per placement, a top-level BVH). Both report the triangles stored and placed against
// the file's own, the stored geometry's bytes and the resident memory the result holds (RSS with
// it alive less RSS before, after malloc_trim has returned freed memory to the system).
//
//   probebake_scene_bench [--benchmark_filter=...]
#include <benchmark/benchmark.h>
#include <malloc.h>
#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/src/bake/tracer_scene.h"
#include "probebake/bake/bake.h"
#include "probebake/base/log.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"
#include "tests/bench/bench_util.h"

namespace probebake {
namespace {

// The level: `nodes` nodes on a square grid 1.5 m apart, node i instancing mesh i % kMeshes;
// each mesh is kPrimitives boxes (12 triangles each) in an 8-wide block, each primitive with one
// of kMaterials materials.
constexpr int kMeshes = 50, kPrimitives = 40, kMaterials = 8, kBoxTriangles = 12;

constexpr int64_t kFileTriangles = int64_t(kMeshes) * kPrimitives * kBoxTriangles;

void Append(std::string* bin, const void* data, size_t bytes) {
  bin->append(static_cast<const char*>(data), bytes);
}

// Writes level.gltf, level.bin and job.json into `dir`; returns the job's path.
std::string WriteLevel(const std::filesystem::path& dir, int nodes) {
  std::string bin, accessors, meshes;
  const uint16_t boxIndices[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                   1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
  int accessor = 0;
  char buffer[512];
  for (int m = 0; m < kMeshes; ++m) {
    std::string primitives;
    for (int j = 0; j < kPrimitives; ++j) {
      // A box 0.1 to 0.16 on a side, its height varying by mesh so that the meshes differ.
      const float x0 = 0.15f * float(j % 8), y0 = 0.15f * float(j / 8), s = 0.1f + 0.001f * m;
      const float corners[8][3] = {{x0, 0, y0},         {x0 + s, 0, y0}, {x0 + s, 0, y0 + s},
                                   {x0, 0, y0 + s},     {x0, s, y0},     {x0 + s, s, y0},
                                   {x0 + s, s, y0 + s}, {x0, s, y0 + s}};
      const size_t positionsAt = bin.size();
      Append(&bin, corners, sizeof corners);
      const size_t indicesAt = bin.size();
      Append(&bin, boxIndices, sizeof boxIndices);
      std::snprintf(buffer, sizeof buffer,
                    "%s{\"bufferView\":0,\"byteOffset\":%zu,\"componentType\":5126,\"count\":8,"
                    "\"type\":\"VEC3\",\"min\":[%g,0,%g],\"max\":[%g,%g,%g]},"
                    "{\"bufferView\":0,\"byteOffset\":%zu,\"componentType\":5123,\"count\":36,"
                    "\"type\":\"SCALAR\"}",
                    accessors.empty() ? "" : ",", positionsAt, double(x0), double(y0),
                    double(x0 + s), double(s), double(y0 + s), indicesAt);
      accessors += buffer;
      std::snprintf(buffer, sizeof buffer,
                    "%s{\"attributes\":{\"POSITION\":%d},\"indices\":%d,\"material\":%d}",
                    primitives.empty() ? "" : ",", accessor, accessor + 1, (m + j) % kMaterials);
      primitives += buffer;
      accessor += 2;
    }
    if (m) meshes += ',';
    meshes.append("{\"primitives\":[").append(primitives).append("]}");
  }
  std::string nodeList, sceneNodes, materials;
  const int side = 1 + int(std::sqrt(double(nodes)));
  for (int i = 0; i < nodes; ++i) {
    std::snprintf(buffer, sizeof buffer, "%s{\"mesh\":%d,\"translation\":[%g,0,%g]}", i ? "," : "",
                  i % kMeshes, 1.5 * (i % side), 1.5 * (i / side));
    nodeList += buffer;
    if (i) sceneNodes += ',';
    sceneNodes += std::to_string(i);
  }
  for (int k = 0; k < kMaterials; ++k) {
    std::snprintf(buffer, sizeof buffer,
                  "%s{\"pbrMetallicRoughness\":{\"baseColorFactor\":[%g,0.5,0.4,1],"
                  "\"metallicFactor\":0}}",
                  k ? "," : "", 0.2 + 0.08 * k);
    materials += buffer;
  }
  const std::string binBytes = std::to_string(bin.size());
  std::string gltf = "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[";
  gltf.append(sceneNodes).append("]}],\"nodes\":[").append(nodeList);
  gltf.append("],\"meshes\":[").append(meshes).append("],\"materials\":[").append(materials);
  gltf.append("],\"accessors\":[").append(accessors);
  gltf.append("],\"bufferViews\":[{\"buffer\":0,\"byteLength\":").append(binBytes);
  gltf.append("}],\"buffers\":[{\"uri\":\"level.bin\",\"byteLength\":").append(binBytes);
  gltf.append("}]}");
  std::ofstream(dir / "level.gltf", std::ios::binary) << gltf;
  std::ofstream(dir / "level.bin", std::ios::binary) << bin;
  const double extent = 1.5 * side;
  std::snprintf(buffer, sizeof buffer,
                "{\"scene\":{\"meshes\":[{\"name\":\"level\",\"file\":\"level.gltf\"}],"
                "\"environment\":{\"uniform\":{\"radiance\":[1,1,1]}}},"
                "\"grid\":{\"min\":[0,0,1.5],\"max\":[%g,%g,1.5],\"counts\":[2,2,1]},"
                "\"settings\":{\"samplesPerProbe\":16}}",
                extent, extent);
  std::ofstream(dir / "job.json", std::ios::binary) << buffer;
  return (dir / "job.json").string();
}

// A fresh folder under the system's temporary folder, removed with the object.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "probebake-level-XXXXXX");
    if (!mkdtemp(pattern.data())) std::abort();
    path = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path); }
};

// The level's job, its repeated meshes instanced (`instanced`) or every mesh moved into world
// space (JobLimits::flattenUpToTriangles).
absl::StatusOr<BakeJob> ImportLevel(const std::string& jobPath, bool instanced) {
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(jobPath);
  if (!spec.ok()) return spec.status();
  JobLimits limits;
  limits.flattenUpToTriangles = instanced ? 0 : limits.maxTriangles;
  return BuildBakeJob(*spec, LocalAssetSource(JobFileDir(jobPath), "", limits.maxAssetBytes),
                      limits);
}

// The level of state.range(0) nodes, instanced (state.range(1) = 1) or flattened; nothing, the
// benchmark skipped with the error, when it cannot be read.
std::optional<BakeJob> LevelJob(benchmark::State& state) {
  Logger("job")->set_level(spdlog::level::warn);
  const TempDir dir;
  const std::string jobPath = WriteLevel(dir.path, int(state.range(0)));
  absl::StatusOr<BakeJob> job = ImportLevel(jobPath, state.range(1) != 0);
  if (!job.ok()) {
    state.SkipWithError(std::string(job.status().message()).c_str());
    return std::nullopt;
  }
  return *std::move(job);
}

int64_t SceneGeometryBytes(const Scene& scene) {
  int64_t bytes = 0;
  for (const TriangleMesh& mesh : scene.meshes)
    bytes += int64_t(mesh.positions.size() * sizeof(Vec3d) + mesh.indices.size() * 4);
  return bytes;
}

void Report(benchmark::State& state, const Scene& scene, int64_t distinct, int64_t held) {
  int64_t triangles = 0, placed = 0, instanced = 0;
  for (const TriangleMesh& mesh : scene.meshes) {
    triangles += int64_t(mesh.TriangleCount());
    placed += int64_t(mesh.PlacedTriangleCount());
    instanced += !mesh.placements.empty();
  }
  state.counters["stored_triangles"] = double(triangles);
  state.counters["placed_triangles"] = double(placed);
  state.counters["file_triangles"] = double(distinct);
  state.counters["geometry_MiB"] = double(SceneGeometryBytes(scene)) / (1 << 20);
  state.counters["held_MiB"] = double(held) / (1 << 20);
  state.SetLabel(std::to_string(scene.meshes.size()) + " meshes, " + std::to_string(instanced) +
                 " instanced");
}

void BM_LevelImport(benchmark::State& state) {
  Logger("job")->set_level(spdlog::level::warn);
  const TempDir dir;
  const std::string jobPath = WriteLevel(dir.path, int(state.range(0)));
  int64_t held = 0;
  absl::StatusOr<BakeJob> job;
  for (auto _ : state) {
    state.PauseTiming();
    job = absl::StatusOr<BakeJob>();
    malloc_trim(0);
    const int64_t before = bench::CurrentRssBytes();
    state.ResumeTiming();
    job = ImportLevel(jobPath, state.range(1) != 0);
    if (!job.ok()) {
      state.SkipWithError(std::string(job.status().message()).c_str());
      return;
    }
    state.PauseTiming();
    malloc_trim(0);
    held = std::max(held, bench::CurrentRssBytes() - before);
    state.ResumeTiming();
  }
  Report(state, job->scene, kFileTriangles, held);
}

// Args: nodes; instanced (1) or flattened (0).
void BM_LevelTracerBuild(benchmark::State& state) {
  std::optional<BakeJob> job = LevelJob(state);
  if (!job) return;
  int64_t held = 0;
  for (auto _ : state) {
    state.PauseTiming();
    malloc_trim(0);
    const int64_t before = bench::CurrentRssBytes();
    state.ResumeTiming();
    absl::StatusOr<std::unique_ptr<TracerScene>> tracer =
        TracerScene::Build(job->scene, LocalOrigin(job->scene));
    if (!tracer.ok()) {
      state.SkipWithError(std::string(tracer.status().message()).c_str());
      return;
    }
    state.PauseTiming();
    held = std::max(held, bench::CurrentRssBytes() - before);
    tracer->reset();
    state.ResumeTiming();
  }
  Report(state, job->scene, kFileTriangles, held);
}

// Args: nodes; instanced (1) or flattened (0). Whole bakes of the level's 4 probes at 65536 samples
// each under a uniform sky, 1 thread: what the second level of traversal costs per ray.
void BM_LevelBake(benchmark::State& state) {
  Logger("bake")->set_level(spdlog::level::warn);
  std::optional<BakeJob> job = LevelJob(state);
  if (!job) return;
  job->settings.samplesPerProbe = 65536;
  BakeOptions options;
  options.threads = 1;
  int64_t rays = 0;
  for (auto _ : state) {
    absl::StatusOr<ProbeVolume> volume = Bake(*job, options);
    if (!volume.ok()) {
      state.SkipWithError(std::string(volume.status().message()).c_str());
      return;
    }
    rays += volume->stats.rays;
  }
  state.counters["rays/s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsRate);
}

// Args: nodes (each placing one of 50 meshes of 40 primitives); instanced (1) or flattened (0).
BENCHMARK(BM_LevelImport)
    ->ArgsProduct({{100, 400, 1600}, {1, 0}})
    ->ArgNames({"nodes", "instanced"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_LevelBake)
    ->ArgsProduct({{400}, {1, 0}})
    ->ArgNames({"nodes", "instanced"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_LevelTracerBuild)
    ->ArgsProduct({{100, 400, 1600}, {1, 0}})
    ->ArgNames({"nodes", "instanced"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace probebake

BENCHMARK_MAIN();
