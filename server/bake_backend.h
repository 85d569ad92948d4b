// The seam between the job scheduler and the core: how a job spec becomes a BakeJob, how it is
// baked and how the volume is written. Production wires BuildBakeJob over the blob store, Bake and
// WriteProbeVolume (ProductionBackend); tests inject a deterministic baker to drive cancellation
// and restart without the path tracer.
#pragma once

#include <functional>
#include <string>

#include "absl/status/statusor.h"
#include "probebake/bake/bake.h"
#include "probebake/bake/probe_volume.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/limits.h"
#include "probebake/scene/scene.h"
#include "probebake/v1/job.pb.h"

namespace probebake::server {

class BlobStore;

struct BakeBackend {
  // Builds the BakeJob of a validated spec whose blobs are all stored (assets read from the blob
  // store). Errors name the field.
  std::function<absl::StatusOr<BakeJob>(const v1::JobSpec&)> build;
  // Bakes (probebake::Bake's contract: BakeOptions hooks, CANCELLED when cancelled).
  std::function<absl::StatusOr<ProbeVolume>(const BakeJob&, const BakeOptions&)> bake;
  // Writes the volume file at `path` (WriteProbeVolume's contract). The volume is left as it
  // is, so a write that failed for lack of space can be tried again.
  std::function<absl::Status(const std::string& path, const ProbeVolume&, const VolumeMetadata&)>
      writeVolume;
};

// The assets of a server-side job: blobs from the store (size and hash verified), never files.
class BlobAssetSource final : public AssetSource {
 public:
  BlobAssetSource(const BlobStore* blobs, int64_t maxBytes) : blobs_(blobs), maxBytes_(maxBytes) {}
  // Always INVALID_ARGUMENT: "<field>: the server does not read client paths; upload the file and
  // reference it by blob".
  absl::StatusOr<std::string> ReadFile(const std::string& relativePath,
                                       const std::string& fieldPath) const override;
  // FAILED_PRECONDITION when the blob is not stored; INVALID_ARGUMENT past maxBytes (0: none).
  absl::StatusOr<std::string> ReadBlob(const v1::Digest& digest,
                                       const std::string& fieldPath) const override;

 private:
  const BlobStore* blobs_;
  int64_t maxBytes_;
};

// The message for a `file` reference in a server request (docs/service.md).
std::string ClientPathRefusal(const std::string& fieldPath);

// BuildBakeJob over BlobAssetSource, probebake::Bake and WriteProbeVolume.
BakeBackend ProductionBackend(const BlobStore* blobs, const JobLimits& limits);

}  // namespace probebake::server
