#include "server/disk_reserve.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>

#include "probebake/base/atomic_file.h"
#include "probebake/base/io_error.h"
#include "probebake/base/log.h"

namespace probebake::server {
namespace fs = std::filesystem;

DiskReserve::DiskReserve(fs::path path, int64_t bytes) : path_(std::move(path)), bytes_(bytes) {}

bool DiskReserve::held() const {
  std::lock_guard lock(mutex_);
  return held_;
}

namespace {

int64_t AllocatedBytes(const fs::path& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 ? int64_t(st.st_blocks) * 512 : 0;
}

int64_t AvailableBytes(const fs::path& dir) {
  struct statvfs vfs;
  if (::statvfs(dir.c_str(), &vfs) != 0) return 0;
  return int64_t(vfs.f_bavail) * int64_t(vfs.f_frsize);
}

}  // namespace

bool DiskReserve::AllocateLocked(int64_t bytes) {
  // Whole or not at all: a reserve cut short by a crash would hold less than it claims.
  absl::StatusOr<AtomicFile> file =
      AtomicFile::Create(path_.string(), AtomicFile::Temp::kBesidePath);
  absl::Status status = file.status();
  if (status.ok()) {
    const int err = ::posix_fallocate(file->fd(), 0, off_t(bytes));
    status = err != 0 ? IoError(err, file->tempPath(), "fallocate") : file->Commit();
  }
  if (!status.ok()) {
    Logger("server")->warn("no disk reserve: {}", std::string(status.message()));
    return false;
  }
  Logger("server")->info("holding {} MiB of disk in reserve ({})", bytes >> 20, path_.string());
  held_ = true;
  return true;
}

bool DiskReserve::Restore() {
  std::lock_guard lock(mutex_);
  if (bytes_ <= 0) return false;
  const int64_t held = AllocatedBytes(path_);
  if (held >= bytes_) {
    held_ = true;
    return true;
  }
  // Beside the file's own blocks, which a new file replaces.
  const int64_t available = AvailableBytes(path_.parent_path()) + held;
  if (available < 2 * bytes_) {
    if (!warnedNoRoom_)
      Logger("server")->warn(
          "no full disk reserve: {} MiB free, {} MiB wanted with as much to spare", available >> 20,
          bytes_ >> 20);
    warnedNoRoom_ = true;
    return held_ = held > 0;
  }
  warnedNoRoom_ = false;
  return AllocateLocked(bytes_);
}

bool DiskReserve::Retake() {
  std::lock_guard lock(mutex_);
  if (bytes_ <= 0) return false;
  if (AllocatedBytes(path_) > 0) return held_ = true;
  constexpr int64_t kMiB = int64_t(1) << 20;
  const int64_t bytes = std::min(bytes_, AvailableBytes(path_.parent_path())) / kMiB * kMiB;
  return bytes >= kMiB && AllocateLocked(bytes);
}

bool DiskReserve::Release() {
  std::lock_guard lock(mutex_);
  struct stat st;
  bool had = ::stat(path_.c_str(), &st) == 0 && st.st_blocks > 0;
  if (::unlink(path_.c_str()) != 0 && errno != ENOENT) {
    Logger("server")->error("cannot release the disk reserve {}: {}", path_.string(),
                            std::strerror(errno));
    had = false;
  }
  held_ = false;
  if (had)
    Logger("server")->warn("disk full: released {} MiB of reserve so the job store can be written",
                           int64_t(st.st_blocks) * 512 >> 20);
  return had;
}

}  // namespace probebake::server
