#include "server/bake_backend.h"

#include "absl/strings/str_cat.h"
#include "probebake/base/status.h"
#include "probebake/job/digest.h"
#include "server/blob_store.h"

namespace probebake::server {

std::string ClientPathRefusal(const std::string& fieldPath) {
  return absl::StrCat(fieldPath,
                      ": the server does not read client paths; upload the file and reference it "
                      "by blob");
}

absl::StatusOr<std::string> BlobAssetSource::ReadFile(const std::string& /*relativePath*/,
                                                      const std::string& fieldPath) const {
  return absl::InvalidArgumentError(ClientPathRefusal(fieldPath));
}

absl::StatusOr<std::string> BlobAssetSource::ReadReferencedFile(
    const std::string& /*modelFile*/, const std::string& /*modelPath*/,
    const std::string& fieldPath) const {
  return absl::InvalidArgumentError(ClientPathRefusal(fieldPath));
}

absl::StatusOr<std::string> BlobAssetSource::ReadBlob(const v1::Digest& digest,
                                                      const std::string& fieldPath) const {
  PB_RETURN_IF_ERROR(ValidateDigest(digest, fieldPath));
  if (maxBytes_ > 0 && digest.size_bytes() > maxBytes_)
    return FieldError(absl::StrCat(fieldPath, ".sizeBytes"),
                      absl::StrCat(digest.size_bytes(), " bytes exceeds the limit of ", maxBytes_));
  absl::StatusOr<std::string> bytes = blobs_->ReadAll(digest);
  if (absl::IsNotFound(bytes.status()))
    return absl::FailedPreconditionError(
        absl::StrCat(fieldPath, ": blob ", DigestString(digest), " is missing; upload it first"));
  if (!bytes.ok()) return bytes.status();
  // The store verified the hash on upload; checking again catches a file damaged on disk.
  if (Sha256Hex(*bytes) != digest.hash())
    return absl::DataLossError(
        absl::StrCat(fieldPath, ": stored blob ", DigestString(digest), " is corrupt"));
  return bytes;
}

}  // namespace probebake::server
