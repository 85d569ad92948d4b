#include "server/asset_check.h"

#include <unistd.h>

#include <random>

#include "absl/strings/str_cat.h"
#include "probebake/base/status.h"
#include "runtime/asset_check.h"
#include "runtime/files.h"
#include "server/bake_backend.h"
#include "server/blob_store.h"

namespace probebake::server {
namespace {

bool HasAssetBlobs(const v1::JobSpec& spec) {
  for (const v1::Mesh& mesh : spec.scene().meshes())
    if (mesh.has_blob()) return true;
  return spec.scene().environment().has_map() && spec.scene().environment().map().has_blob();
}

}  // namespace

AssetCheck::AssetCheck(std::vector<std::string> argv, std::filesystem::path tmpDir,
                       std::chrono::seconds timeout)
    : argv_(std::move(argv)), tmpDir_(std::move(tmpDir)), timeout_(timeout) {}

absl::StatusOr<MeshImports> AssetCheck::Import(const v1::JobSpec& spec) const {
  if (!HasAssetBlobs(spec)) return MeshImports();
  // Names no other check uses at the same time.
  const std::string stem = absl::StrCat("asset-check-", getpid(), "-", std::random_device{}());
  const std::filesystem::path specFile = tmpDir_ / (stem + ".pb");
  const std::filesystem::path importsFile = tmpDir_ / (stem + ".imports");
  PB_RETURN_IF_ERROR(runtime::WriteFileAtomic(specFile, spec.SerializeAsString()));
  struct RemoveFile {
    std::filesystem::path path;
    ~RemoveFile() {
      std::error_code ignored;
      std::filesystem::remove(path, ignored);
    }
  } removeSpec{specFile};
  std::vector<std::string> args = argv_;
  args.push_back("--check-job-assets");
  args.push_back(specFile.string());
  args.push_back("--check-imports-out");
  args.push_back(importsFile.string());
  return runtime::RunAssetCheck(std::move(args), timeout_, importsFile);
}

int RunAssetCheckChild(const std::filesystem::path& specFile,
                       const std::filesystem::path& importsFile,
                       const std::filesystem::path& dataDir, int64_t maxBlobBytes,
                       const JobLimits& limits, const runtime::AssetCheckLimits& resources) {
  runtime::ApplyAssetCheckLimits(resources);
  absl::StatusOr<std::string> bytes = runtime::ReadWholeFile(specFile);
  if (!bytes.ok()) return runtime::ReportAssetCheck(absl::InternalError(bytes.status().message()));
  v1::JobSpec spec;
  if (!spec.ParseFromString(*bytes))
    return runtime::ReportAssetCheck(absl::InternalError("asset check: unreadable spec file"));
  // The parent server's store, in use: read it, never clean it (its DATA/tmp holds other
  // checks' spec files and running jobs' volumes).
  absl::StatusOr<std::unique_ptr<BlobStore>> blobs =
      BlobStore::OpenForReading(dataDir, maxBlobBytes);
  if (!blobs.ok()) return runtime::ReportAssetCheck(blobs.status());
  const BlobAssetSource store(blobs->get(), limits.maxAssetBytes);
  return runtime::ReportJobAssets(spec, store, limits, importsFile);
}

}  // namespace probebake::server
