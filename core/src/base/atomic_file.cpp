#include "probebake/base/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

#include "probebake/base/io_error.h"

namespace probebake {
namespace {

struct PathParts {
  std::string dir;   // "." when the path has no directory part
  std::string name;  // the file name
};

PathParts SplitPath(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return {std::string("."), path};
  return {slash == 0 ? std::string("/") : path.substr(0, slash), path.substr(slash + 1)};
}

// Distinguishes temporary files of concurrent writers in one process.
std::atomic<uint64_t> g_tempCounter{0};

}  // namespace

absl::StatusOr<AtomicFile> AtomicFile::Create(const std::string& path, Temp temp) {
  if (path.empty() || path.back() == '/') {
    return absl::InvalidArgumentError("'" + path + "': not a file path");
  }
  // Found now rather than when the rename over it fails, after the content was written.
  struct stat info;
  if (::stat(path.c_str(), &info) == 0 && S_ISDIR(info.st_mode))
    return absl::InvalidArgumentError(path + ": is a directory, not a file path");
  const auto [dir, name] = SplitPath(path);
  if (temp == Temp::kBesidePath) {
    std::string beside = path + ".tmp";
    const int fd = ::open(beside.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) return IoError(errno, path, "cannot create " + beside);
    return AtomicFile(path, std::move(beside), fd);
  }
  for (int attempt = 0; attempt < 100; ++attempt) {
    const uint64_t n = g_tempCounter.fetch_add(1, std::memory_order_relaxed);
    std::string unique = (dir == "/" ? std::string() : dir) + "/." + name + "." +
                         std::to_string(::getpid()) + "." + std::to_string(n) + ".tmp";
    const int fd = ::open(unique.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) return AtomicFile(path, std::move(unique), fd);
    if (errno != EEXIST) return IoError(errno, path, "cannot create a temporary file in " + dir);
  }
  return absl::InternalError(path + ": cannot find a free temporary file name in " + dir);
}

AtomicFile::AtomicFile(AtomicFile&& other) noexcept
    : path_(std::move(other.path_)),
      tempPath_(std::move(other.tempPath_)),
      fd_(std::exchange(other.fd_, -1)),
      done_(std::exchange(other.done_, true)) {}

AtomicFile::~AtomicFile() {
  Abort();
}

void AtomicFile::Abort() {
  if (done_) return;
  done_ = true;
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  ::unlink(tempPath_.c_str());
}

absl::Status AtomicFile::Commit() {
  if (done_) return absl::FailedPreconditionError(path_ + ": file already committed or aborted");
  // fsync through our descriptor flushes the inode, whichever descriptor wrote the data.
  if (::fsync(fd_) != 0) {
    const int e = errno;
    Abort();
    return IoError(e, path_, "fsync of " + tempPath_ + " failed");
  }
  const int closed = ::close(fd_);
  fd_ = -1;
  if (closed != 0) {
    const int e = errno;
    Abort();
    return IoError(e, path_, "close of " + tempPath_ + " failed");
  }
  if (::rename(tempPath_.c_str(), path_.c_str()) != 0) {
    const int e = errno;
    Abort();
    return IoError(e, path_, "cannot rename " + tempPath_ + " to it");
  }
  done_ = true;
  // The rename is durable once the directory entry is.
  return FsyncDirectory(SplitPath(path_).dir);
}

absl::Status FsyncDirectory(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return IoError(errno, dir, "cannot open the directory to fsync it");
  const int synced = ::fsync(fd);
  const int e = errno;
  ::close(fd);
  if (synced != 0) return IoError(e, dir, "fsync of the directory failed");
  return absl::OkStatus();
}

}  // namespace probebake
