#include "server/disk_reserve.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cstring>

#include "probebake/base/log.h"

namespace probebake::server {
namespace fs = std::filesystem;

DiskReserve::DiskReserve(fs::path path, int64_t bytes) : path_(std::move(path)), bytes_(bytes) {}

bool DiskReserve::held() const {
  std::lock_guard lock(mutex_);
  return held_;
}

bool DiskReserve::Restore() {
  std::lock_guard lock(mutex_);
  if (bytes_ <= 0) return false;
  struct stat st;
  if (::stat(path_.c_str(), &st) == 0 && int64_t(st.st_blocks) * 512 >= bytes_) {
    held_ = true;
    return true;
  }
  struct statvfs vfs;
  if (::statvfs(path_.parent_path().c_str(), &vfs) != 0) return false;
  const int64_t available = int64_t(vfs.f_bavail) * int64_t(vfs.f_frsize);
  if (available < 2 * bytes_) {
    Logger("server")->debug("no disk reserve: {} bytes free", available);
    return false;
  }
  const fs::path tmp = fs::path(path_).concat(".tmp");
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) return false;
  const int err = ::posix_fallocate(fd, 0, off_t(bytes_));
  const bool synced = err == 0 && ::fsync(fd) == 0;
  ::close(fd);
  if (!synced || ::rename(tmp.c_str(), path_.c_str()) != 0) {
    ::unlink(tmp.c_str());
    Logger("server")->warn("no disk reserve: {}: {}", path_.string(),
                           std::strerror(err != 0 ? err : errno));
    return false;
  }
  if (!held_)
    Logger("server")->info("holding {} MiB of disk in reserve ({})", bytes_ >> 20, path_.string());
  held_ = true;
  return true;
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
