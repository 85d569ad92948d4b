// The seam between the job scheduler and the core: how a job spec becomes a BakeJob, how it is
// baked and how the volume is written. Production wires BuildBakeJob over the blob store, Bake and
// WriteProbeVolume (ProductionBackend), or bakes on a Slurm cluster (SlurmBackend,
// slurm_backend.h); tests inject a deterministic baker to drive cancellation and restart without
// the path tracer.
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
class JobStore;

// What a bake is told of the job it runs besides the BakeJob: a cluster backend keys its own state
// by the job's name, ships the spec to the cluster, and tells a client's cancel (which ends the
// cluster's work) from the server's shutdown (after which the job runs again and re-attaches).
struct BakeRun {
  std::string jobName;                // "bakeJobs/<id>"
  const v1::JobSpec* spec = nullptr;  // as stored: assets by blob
  int attempt = 1;                    // the job's attempts so far, this one included
  // True once a client cancelled the job; BakeOptions::cancel is raised for a shutdown as well.
  std::function<bool()> cancelledByClient;
  // Why the running job is not advancing (progress.waiting; empty: it is). Must not block.
  std::function<void(const std::string&)> setWaiting;
};

struct BakeBackend {
  // Builds the BakeJob of a validated spec whose blobs are all stored (assets read from the blob
  // store). Errors name the field.
  std::function<absl::StatusOr<BakeJob>(const v1::JobSpec&)> build;
  // Bakes (probebake::Bake's contract: BakeOptions hooks, CANCELLED when cancelled).
  std::function<absl::StatusOr<ProbeVolume>(const BakeRun&, const BakeJob&, const BakeOptions&)>
      bake;
  // Writes the volume file at `path` (WriteProbeVolume's contract). The volume is left as it
  // is, so a write that failed for lack of space can be tried again.
  std::function<absl::Status(const std::string& path, const ProbeVolume&, const VolumeMetadata&)>
      writeVolume;
  // Optional: called once the end of job `jobName` is stored (SUCCEEDED, FAILED or CANCELLED) or
  // the job deleted, so that what the backend keeps for the job can go.
  std::function<void(const std::string& jobName)> release;
};

// What a backend is made from, once the server's stores are open.
struct BackendContext {
  const BlobStore* blobs = nullptr;
  JobStore* store = nullptr;  // for backends that keep state of their own per job
  JobLimits limits;
};

// The assets of a server-side job: blobs from the store (size and hash verified), never files.
class BlobAssetSource final : public AssetSource {
 public:
  BlobAssetSource(const BlobStore* blobs, int64_t maxBytes) : blobs_(blobs), maxBytes_(maxBytes) {}
  // Always INVALID_ARGUMENT: "<field>: the server does not read client paths; upload the file and
  // reference it by blob".
  absl::StatusOr<std::string> ReadFile(const std::string& relativePath,
                                       const std::string& fieldPath) const override;
  // Always INVALID_ARGUMENT, as ReadFile.
  absl::StatusOr<std::string> ReadReferencedFile(const std::string& modelFile,
                                                 const std::string& modelPath,
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

// BuildBakeJob over BlobAssetSource, probebake::Bake in process and WriteProbeVolume.
BakeBackend ProductionBackend(const BlobStore* blobs, const JobLimits& limits);

}  // namespace probebake::server
