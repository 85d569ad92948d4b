#include "probebake/job/asset_source.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <system_error>

#include "probebake/base/status.h"
#include "probebake/job/digest.h"
#include "text.h"

namespace probebake {
namespace {

namespace fs = std::filesystem;
using job_internal::Escaped;
using job_internal::Num;
using job_internal::Quoted;

// Reads the regular file `path` whole. `what` starts every error reason ("cannot read ...").
absl::StatusOr<std::string> ReadWholeFile(const fs::path& path, int64_t maxBytes,
                                          const std::string& fieldPath, const std::string& what) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec) return FieldError(fieldPath, what + ": " + ec.message());
  if (!fs::is_regular_file(status)) return FieldError(fieldPath, what + ": not a regular file");
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) return FieldError(fieldPath, what + ": " + ec.message());
  if (maxBytes > 0 && size > uintmax_t(maxBytes)) {
    return FieldError(fieldPath, what + ": " + Num(uint64_t(size)) + " bytes, above the limit of " +
                                     Num(maxBytes));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return FieldError(fieldPath, what + ": " + std::strerror(errno));
  std::string bytes;
  bytes.resize(size_t(size));
  in.read(bytes.data(), std::streamsize(size));
  // A file that shrank while being read is as unreadable as a missing one.
  if (in.gcount() != std::streamsize(size) || in.bad()) {
    return FieldError(fieldPath, what + ": read error");
  }
  return bytes;
}

}  // namespace

LocalAssetSource::LocalAssetSource(std::string jobFileDir, std::string blobDir, int64_t maxBytes)
    : jobFileDir_(std::move(jobFileDir)), blobDir_(std::move(blobDir)), maxBytes_(maxBytes) {}

absl::StatusOr<std::string> LocalAssetSource::ReadFile(const std::string& relativePath,
                                                       const std::string& fieldPath) const {
  const fs::path path =
      jobFileDir_.empty() ? fs::path(relativePath) : fs::path(jobFileDir_) / fs::path(relativePath);
  return ReadWholeFile(path, maxBytes_, fieldPath,
                       "cannot read " + Quoted(relativePath) + " (" + Escaped(path.string()) + ")");
}

absl::StatusOr<std::string> LocalAssetSource::ReadBlob(const v1::Digest& digest,
                                                       const std::string& fieldPath) const {
  if (blobDir_.empty()) {
    return FieldError(fieldPath,
                      "blob references need a blob store; a local bake reads files (use `file`)");
  }
  if (!IsSha256Hex(digest.hash())) {
    return FieldError(fieldPath + ".hash", "expected 64 lowercase hex digits");
  }
  const fs::path path = fs::path(blobDir_) / digest.hash();
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    return absl::FailedPreconditionError(fieldPath + ": missing blob " + digest.hash() + "/" +
                                         Num(digest.size_bytes()) + " (" + path.string() + ")");
  }
  absl::StatusOr<std::string> bytes =
      ReadWholeFile(path, maxBytes_, fieldPath, "cannot read blob " + digest.hash());
  if (!bytes.ok()) return bytes.status();
  if (int64_t(bytes->size()) != digest.size_bytes() || Sha256Hex(*bytes) != digest.hash()) {
    return FieldError(fieldPath,
                      "the content of blob " + digest.hash() + " does not match its digest");
  }
  return bytes;
}

absl::StatusOr<std::string> LocalAssetSource::ReadReferencedFile(
    const std::string& modelFile, const std::string& modelPath,
    const std::string& fieldPath) const {
  const std::string what = Quoted(modelFile) + " references " + Quoted(modelPath);
  const size_t colon = modelPath.find(':');
  if (colon != std::string::npos && modelPath.find('/') > colon)
    return FieldError(fieldPath, what + ": a URI scheme or drive; only relative paths are read");
  if (modelPath.empty() || modelPath[0] == '/' || fs::path(modelPath).is_absolute())
    return FieldError(fieldPath, what + ": an absolute path; only relative paths are read");
  const fs::path inJob =
      (fs::path(modelFile).parent_path() / fs::path(modelPath)).lexically_normal();
  if (inJob.empty() || *inJob.begin() == ".." || inJob.is_absolute())
    return FieldError(fieldPath, what + ": it leads out of the job file's folder");
  const fs::path root = jobFileDir_.empty() ? fs::path(".") : fs::path(jobFileDir_);
  const fs::path path = root / inJob;
  std::error_code ec;
  const fs::path realRoot = fs::weakly_canonical(root, ec);
  const fs::path realPath = ec ? fs::path() : fs::weakly_canonical(path, ec);
  if (!ec) {
    const fs::path relative = realPath.lexically_relative(realRoot);
    if (relative.empty() || *relative.begin() == "..")
      return FieldError(fieldPath, what + ": a symlink leads out of the job file's folder");
  }
  return ReadWholeFile(path, maxBytes_, fieldPath,
                       what + ": cannot read it (" + Escaped(path.string()) + ")");
}

std::string JobFileDir(const std::string& jobFilePath) {
  return fs::path(jobFilePath).parent_path().string();
}

}  // namespace probebake
