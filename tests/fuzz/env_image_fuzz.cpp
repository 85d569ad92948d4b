// Environment images (OpenEXR, Radiance .hdr) as a lat-long map and as a cube map, through the
// job build: decoding, the pixel checks and the cube resampling.
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
  probebake::v1::JobSpec spec;
  probebake::v1::EnvironmentMap* map = spec.mutable_scene()->mutable_environment()->mutable_map();
  map->set_file("sky");
  if (data[0] & 1) map->set_projection(probebake::v1::EnvironmentMap::CUBE);
  for (int a = 0; a < 3; ++a) {
    spec.mutable_grid()->add_min(0);
    spec.mutable_grid()->add_max(0);
    spec.mutable_grid()->add_counts(1);
  }
  const probebake::fuzz::MemoryAssetSource assets(
      std::string(reinterpret_cast<const char*>(data) + 1, size - 1));
  probebake::JobLimits limits;
  limits.maxEnvironmentPixels = 1 << 16;  // small images: many executions per second
  (void)probebake::BuildBakeJob(spec, assets, limits);
  return 0;
}
