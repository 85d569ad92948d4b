// Mesh files through the whole import (pre-checks, assimp, triangulation, transforms): the first
// byte picks the format, the rest is the file.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz/fuzz_assets.h"
#include "probebake/base/log.h"
#include "probebake/job/job.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = (probebake::SetLogLevel(spdlog::level::off), true);
  (void)quiet;
  if (size < 1) return 0;
  static const char* const kFormats[] = {"obj", "ply", "gltf", "glb"};
  probebake::v1::JobSpec spec;
  probebake::v1::Material* material = spec.mutable_scene()->add_materials();
  material->set_name("m");
  for (int c = 0; c < 3; ++c) material->add_albedo(0.5);
  probebake::v1::Mesh* mesh = spec.mutable_scene()->add_meshes();
  mesh->set_material("m");
  mesh->set_file(std::string("m.") + kFormats[data[0] % 4]);
  spec.mutable_grid()->add_min(0), spec.mutable_grid()->add_min(0), spec.mutable_grid()->add_min(0);
  spec.mutable_grid()->add_max(0), spec.mutable_grid()->add_max(0), spec.mutable_grid()->add_max(0);
  for (int a = 0; a < 3; ++a) spec.mutable_grid()->add_counts(1);
  const probebake::fuzz::MemoryAssetSource assets(
      std::string(reinterpret_cast<const char*>(data) + 1, size - 1));
  probebake::JobLimits limits;
  limits.maxTriangles = 1 << 20;  // a fuzzer's memory, not a farm's
  (void)probebake::BuildBakeJob(spec, assets, limits);
  return 0;
}
