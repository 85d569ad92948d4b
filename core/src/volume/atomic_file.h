// Writing a file so that readers see either the old file or the complete new one, never a part:
// write a hidden temporary file in the same directory, fsync it, rename it over the final name,
// fsync the directory. Private to the volume module.
#pragma once

#include <string>

#include "probebake/base/status.h"

namespace probebake::volume_internal {

class AtomicFile {
 public:
  // Creates an empty temporary file "<dir>/.<name>.<pid>.<n>.tmp" beside `path` (mode 0666 less
  // the umask, as a plain open would). Refuses a `path` that is a directory. Errors name `path`.
  static absl::StatusOr<AtomicFile> Create(const std::string& path);

  AtomicFile(AtomicFile&& other) noexcept;
  AtomicFile& operator=(AtomicFile&&) = delete;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  // Removes the temporary file unless Commit() succeeded.
  ~AtomicFile();

  const std::string& path() const { return path_; }
  // Where to write the content (by name; the file exists and is empty).
  const std::string& tempPath() const { return tempPath_; }

  // Makes the content durable and visible under path(): fsync, rename, fsync of the directory.
  // Call after every writer of tempPath() has flushed and closed. On error the temporary file is
  // removed and path() is untouched.
  absl::Status Commit();

  // Removes the temporary file now (also done by the destructor).
  void Abort();

 private:
  AtomicFile(std::string path, std::string tempPath, int fd)
      : path_(std::move(path)), tempPath_(std::move(tempPath)), fd_(fd) {}

  std::string path_;
  std::string tempPath_;
  int fd_ = -1;  // open on tempPath_ until Commit or Abort
  bool done_ = false;
};

// An absl::Status for errno `error_number`: "<path>: <what>: <strerror>", with the code
// absl::ErrnoToStatus picks (NOT_FOUND, PERMISSION_DENIED, RESOURCE_EXHAUSTED for ENOSPC, ...).
absl::Status IoError(int error_number, const std::string& path, const std::string& what);

}  // namespace probebake::volume_internal
