// Writing a file so that readers see either the old file or the complete new one, never a part,
// and a crash leaves one of the two: write a temporary file in the same directory, fsync it,
// rename it over the final name, fsync the directory. The one implementation for the volume and
// PNG writers, the server's files (checkpoints, port file, disk reserve) and the runtime's
// WriteFileAtomic.
#pragma once

#include <string>

#include "probebake/base/status.h"

namespace probebake {

class AtomicFile {
 public:
  // How the temporary file is named.
  enum class Temp {
    // "<dir>/.<name>.<pid>.<n>.tmp", created anew: any number of writers of one path at once
    // (paths users name, such as volumes). A crash leaves the temporary file behind.
    kUnique,
    // "<path>.tmp", emptied if it exists: one writer of the path at a time. What a crash left
    // behind is reused by the next write instead of piling up (the server's own files).
    kBesidePath,
  };

  // Creates an empty temporary file beside `path`, named as `temp` says, with mode 0666 less the
  // umask (as a plain open would). Refuses a `path` that is a directory. Errors name `path`.
  static absl::StatusOr<AtomicFile> Create(const std::string& path, Temp temp = Temp::kUnique);

  AtomicFile(AtomicFile&& other) noexcept;
  AtomicFile& operator=(AtomicFile&&) = delete;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  // Removes the temporary file unless Commit() succeeded.
  ~AtomicFile();

  const std::string& path() const { return path_; }
  // Where to write the content: by name (the file exists and is empty), or through fd().
  const std::string& tempPath() const { return tempPath_; }
  // The temporary file, open for writing, until Commit or Abort; owned by this object.
  int fd() const { return fd_; }

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

// fsync of the directory `dir`, making a rename or a creation inside it durable. Errors name
// `dir` (IoError).
absl::Status FsyncDirectory(const std::string& dir);

}  // namespace probebake
