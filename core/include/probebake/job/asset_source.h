// Where a job's asset bytes come from. A job references a mesh or environment map either by `file`
// (a path relative to the job file: local bakes) or by `blob` (a content digest: what the CLI
// uploads and the server bakes). BuildBakeJob asks an AssetSource for the bytes; the server
// implements one over its blob store (and refuses every `file`: the server never opens a path
// that a request names: docs/service.md); LocalAssetSource serves local bakes.
//
// Errors name the job field: every message starts with the `fieldPath` the caller passes
// ("scene.meshes[0].file: cannot read 'room.obj' (/jobs/room.obj): No such file or directory").
// Implementations must be safe to call from several threads at once.
#pragma once

#include <cstdint>
#include <string>

#include "absl/status/statusor.h"
#include "probebake/job/limits.h"
#include "probebake/v1/job.pb.h"

namespace probebake {

class AssetSource {
 public:
  virtual ~AssetSource() = default;

  // The bytes of the file `relativePath`, as written in the job (relative to the job file).
  // `fieldPath` is the referencing field, for error messages.
  virtual absl::StatusOr<std::string> ReadFile(const std::string& relativePath,
                                               const std::string& fieldPath) const = 0;

  // The bytes of the blob `digest`, verified against it (size and hash). `fieldPath` is the
  // referencing field ("scene.meshes[0].blob"), for error messages.
  virtual absl::StatusOr<std::string> ReadBlob(const v1::Digest& digest,
                                               const std::string& fieldPath) const = 0;

  // The bytes of the file `modelPath` (normalized: NormalizeModelPath) that the model file
  // `modelFile` (relative to the job file) references, relative to the model's folder.
  // Only local bakes read files: a server's source refuses (INVALID_ARGUMENT).
  virtual absl::StatusOr<std::string> ReadReferencedFile(const std::string& modelFile,
                                                         const std::string& modelPath,
                                                         const std::string& fieldPath) const = 0;
};

// Reads files relative to the job file's folder, and optionally blobs from a folder holding each
// blob as a file named by its hash (<blobDir>/<64 hex digits>).
class LocalAssetSource final : public AssetSource {
 public:
  // `jobFileDir`: the folder relative paths start from ("" is the current folder). `blobDir`: the
  // blob folder; empty refuses every blob reference (INVALID_ARGUMENT). Files and blobs larger than
  // `maxBytes` (0: no limit) are refused before they are read (INVALID_ARGUMENT).
  explicit LocalAssetSource(std::string jobFileDir, std::string blobDir = {},
                            int64_t maxBytes = JobLimits().maxAssetBytes);

  // INVALID_ARGUMENT naming the field, the path as written and the path opened when the file is
  // missing, not a regular file, unreadable or too large.
  absl::StatusOr<std::string> ReadFile(const std::string& relativePath,
                                       const std::string& fieldPath) const override;
  // FAILED_PRECONDITION when the blob is not in the blob folder; INVALID_ARGUMENT when there is no
  // blob folder or the content does not match the digest.
  absl::StatusOr<std::string> ReadBlob(const v1::Digest& digest,
                                       const std::string& fieldPath) const override;
  // INVALID_ARGUMENT naming the field, the model and `modelPath` when the path is absolute, has a
  // scheme ("http:", "C:"), leads out of the job file's folder lexically or through a symlink, or
  // the file is missing, not regular, unreadable or too large.
  absl::StatusOr<std::string> ReadReferencedFile(const std::string& modelFile,
                                                 const std::string& modelPath,
                                                 const std::string& fieldPath) const override;

 private:
  std::string jobFileDir_;
  std::string blobDir_;
  int64_t maxBytes_;
};

// The folder of the job file at `jobFilePath` ("" when the path has no folder part), the base of
// its relative asset paths.
std::string JobFileDir(const std::string& jobFilePath);

}  // namespace probebake
