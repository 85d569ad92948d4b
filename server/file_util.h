// Small POSIX file helpers for the server's stores: durable writes (fsync before rename, fsync of
// the folder after) so a crash leaves either the old file or the new one, never a torn one.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace probebake::server {

// INTERNAL "<what> <path>: <strerror>" (RESOURCE_EXHAUSTED for a full disk).
absl::Status ErrnoError(std::string_view what, const std::filesystem::path& path, int err);

// fsync of a folder, making a rename or creation inside it durable.
absl::Status FsyncDir(const std::filesystem::path& dir);

// Writes `bytes` to a temporary file beside `path`, fsyncs it, renames it over `path` and fsyncs
// the folder.
absl::Status WriteFileAtomic(const std::filesystem::path& path, std::string_view bytes);

// The whole file. NOT_FOUND when it does not exist.
absl::StatusOr<std::string> ReadWholeFile(const std::filesystem::path& path);

// Incremental SHA-256 (OpenSSL), for data that arrives in pieces (uploads, files).
class Sha256Stream {
 public:
  Sha256Stream();
  ~Sha256Stream();
  Sha256Stream(const Sha256Stream&) = delete;
  Sha256Stream& operator=(const Sha256Stream&) = delete;
  void Update(std::string_view bytes);
  // Lowercase hex of the digest of everything given; the stream is spent afterwards.
  std::string FinalHex();

 private:
  struct Context;
  Context* context_;
};

// SHA-256 (lowercase hex) of the file at `path`, read in 1 MiB pieces; its size in `*size`.
absl::StatusOr<std::string> Sha256OfFile(const std::filesystem::path& path,
                                         int64_t* size = nullptr);

}  // namespace probebake::server
