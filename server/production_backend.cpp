// Kept apart from bake_backend.cpp so that binaries injecting their own baker (tests) do not need
// the tracer and the volume writer linked in.
#include "probebake/job/job.h"
#include "probebake/volume/vdb_io.h"
#include "server/bake_backend.h"

namespace probebake::server {

BakeBackend ProductionBackend(const BlobStore* blobs, const JobLimits& limits) {
  BakeBackend backend;
  backend.build = [blobs, limits](const v1::JobSpec& spec) {
    BlobAssetSource assets(blobs, limits.maxAssetBytes);
    return BuildBakeJob(spec, assets, limits);
  };
  backend.bake = [](const BakeRun&, const BakeJob& job, const BakeOptions& options) {
    return Bake(job, options);
  };
  backend.writeVolume = [](const std::string& path, const ProbeVolume& volume,
                           const VolumeMetadata& meta) {
    return WriteProbeVolume(path, volume, meta);
  };
  return backend;
}

}  // namespace probebake::server
