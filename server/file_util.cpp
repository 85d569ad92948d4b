#include "server/file_util.h"

#include <fcntl.h>
#include <openssl/evp.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "probebake/base/check.h"
#include "probebake/base/status.h"

namespace probebake::server {

absl::Status ErrnoError(std::string_view what, const std::filesystem::path& path, int err) {
  std::string message =
      absl::StrCat(std::string(what), " ", path.string(), ": ", std::strerror(err));
  if (err == ENOSPC || err == EDQUOT) return absl::ResourceExhaustedError(message);
  if (err == ENOENT) return absl::NotFoundError(message);
  return absl::InternalError(message);
}

absl::Status FsyncDir(const std::filesystem::path& dir) {
  int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return ErrnoError("open", dir, errno);
  int rc = ::fsync(fd);
  int err = errno;
  ::close(fd);
  if (rc != 0) return ErrnoError("fsync", dir, err);
  return absl::OkStatus();
}

absl::Status WriteFileAtomic(const std::filesystem::path& path, std::string_view bytes) {
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return ErrnoError("open", tmp, errno);
  absl::Status status;
  while (!bytes.empty()) {
    ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      status = ErrnoError("write", tmp, errno);
      break;
    }
    bytes.remove_prefix(size_t(n));
  }
  if (status.ok() && ::fsync(fd) != 0) status = ErrnoError("fsync", tmp, errno);
  ::close(fd);
  if (status.ok() && ::rename(tmp.c_str(), path.c_str()) != 0)
    status = ErrnoError("rename", tmp, errno);
  if (!status.ok()) {
    ::unlink(tmp.c_str());
    return status;
  }
  return FsyncDir(path.parent_path().empty() ? "." : path.parent_path());
}

absl::StatusOr<std::string> ReadWholeFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return ErrnoError("open", path, errno);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (in.bad()) return absl::InternalError(absl::StrCat("read ", path.string(), " failed"));
  return bytes.str();
}

struct Sha256Stream::Context {
  EVP_MD_CTX* ctx;
};

Sha256Stream::Sha256Stream() : context_(new Context{EVP_MD_CTX_new()}) {
  PB_CHECK(context_->ctx && EVP_DigestInit_ex(context_->ctx, EVP_sha256(), nullptr) == 1);
}

Sha256Stream::~Sha256Stream() {
  EVP_MD_CTX_free(context_->ctx);
  delete context_;
}

void Sha256Stream::Update(std::string_view bytes) {
  PB_CHECK(EVP_DigestUpdate(context_->ctx, bytes.data(), bytes.size()) == 1);
}

std::string Sha256Stream::FinalHex() {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned length = 0;
  PB_CHECK(EVP_DigestFinal_ex(context_->ctx, md, &length) == 1);
  return absl::BytesToHexString(absl::string_view(reinterpret_cast<const char*>(md), length));
}

absl::StatusOr<std::string> Sha256OfFile(const std::filesystem::path& path, int64_t* size) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return ErrnoError("open", path, errno);
  Sha256Stream hash;
  std::string buffer(1 << 20, '\0');
  int64_t total = 0;
  while (true) {
    ssize_t n = ::read(fd, buffer.data(), buffer.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      absl::Status error = ErrnoError("read", path, errno);
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

}  // namespace probebake::server
