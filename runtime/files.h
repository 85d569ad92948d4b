// Whole files for the CLI and the server: reading one, writing one atomically and durably, and
// its SHA-256. Built on the core's AtomicFile, IoError and Sha256 (probebake/base/atomic_file.h,
// probebake/base/io_error.h, probebake/job/digest.h), the one implementation of each.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace probebake::runtime {

// The whole file. Errors: IoError (NOT_FOUND when it does not exist).
absl::StatusOr<std::string> ReadWholeFile(const std::filesystem::path& path);

// Replaces the file at `path` with `bytes` so that a crash leaves the old file or the new one:
// AtomicFile with its temporary file at "<path>.tmp" (one writer of a path at a time; what a
// crash left there is reused). Errors: IoError, naming the file.
absl::Status WriteFileAtomic(const std::filesystem::path& path, std::string_view bytes);

// SHA-256 (64 lowercase hex characters) of the file at `path`, read in 1 MiB pieces; its size in
// `*size` when given. Errors: IoError.
absl::StatusOr<std::string> Sha256OfFile(const std::filesystem::path& path,
                                         int64_t* size = nullptr);

}  // namespace probebake::runtime
