#include "runtime/files.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "probebake/base/atomic_file.h"
#include "probebake/base/io_error.h"
#include "probebake/base/status.h"
#include "probebake/job/digest.h"

namespace probebake::runtime {

absl::StatusOr<std::string> ReadWholeFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return IoError(errno, path.string(), "open");
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (in.bad()) return absl::InternalError(absl::StrCat(path.string(), ": read failed"));
  return bytes.str();
}

absl::Status WriteFileAtomic(const std::filesystem::path& path, std::string_view bytes) {
  PB_ASSIGN_OR_RETURN(AtomicFile file,
                      AtomicFile::Create(path.string(), AtomicFile::Temp::kBesidePath));
  while (!bytes.empty()) {
    const ssize_t n = ::write(file.fd(), bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return IoError(errno, file.tempPath(), "write");  // ~AtomicFile removes the temporary file
    }
    bytes.remove_prefix(size_t(n));
  }
  return file.Commit();
}

absl::StatusOr<std::string> Sha256OfFile(const std::filesystem::path& path, int64_t* size) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return IoError(errno, path.string(), "open");
  Sha256 hash;
  std::string buffer(1 << 20, '\0');
  int64_t total = 0;
  while (true) {
    const ssize_t n = ::read(fd, buffer.data(), buffer.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const absl::Status error = IoError(errno, path.string(), "read");
      ::close(fd);
      return error;
    }
    if (n == 0) break;
    hash.Update(std::string_view(buffer.data(), size_t(n)));
    total += n;
  }
  ::close(fd);
  if (size) *size = total;
  return hash.FinalHex();
}

}  // namespace probebake::runtime
