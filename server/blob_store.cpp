#include "server/blob_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <optional>
#include <system_error>

#include "absl/strings/str_cat.h"
#include "probebake/base/atomic_file.h"
#include "probebake/base/check.h"
#include "probebake/base/io_error.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "runtime/files.h"

namespace probebake::server {
namespace fs = std::filesystem;

namespace {

constexpr int64_t kHashBufferBytes = 1 << 20;

absl::Status WriteAll(int fd, std::string_view data, const fs::path& path) {
  while (!data.empty()) {
    ssize_t n = ::write(fd, data.data(), data.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return IoError(errno, path.string(), "write");
    }
    data.remove_prefix(size_t(n));
  }
  return absl::OkStatus();
}

// pread loop: fills `out` with up to `count` bytes at `offset` (fewer only at end of file).
absl::Status ReadFully(int fd, int64_t offset, int64_t count, std::string* out) {
  out->resize(size_t(count));
  int64_t got = 0;
  while (got < count) {
    ssize_t n = ::pread(fd, out->data() + got, size_t(count - got), offset + got);
    if (n < 0) {
      if (errno == EINTR) continue;
      return absl::InternalError(absl::StrCat("read: ", std::strerror(errno)));
    }
    if (n == 0) break;
    got += n;
  }
  out->resize(size_t(got));
  return absl::OkStatus();
}

// A blob's time of last use is its file's modification time (Collect). A store that cannot be
// written keeps its blobs anyway: nothing is collected there.
void StampUsed(const fs::path& path) {
  if (::utimensat(AT_FDCWD, path.c_str(), nullptr, 0) != 0)
    Logger("blobs")->debug("touch {}: {}", path.string(), std::strerror(errno));
}

}  // namespace

absl::Status ValidateDigest(const v1::Digest& digest, std::string_view fieldPath) {
  const std::string& hash = digest.hash();
  if (!IsSha256Hex(hash))
    return FieldError(absl::StrCat(std::string(fieldPath), ".hash"),
                      hash.size() != 64
                          ? absl::StrCat("expected 64 lowercase hex characters (SHA-256), got ",
                                         hash.size(), " characters")
                          : std::string("expected lowercase hex characters (SHA-256)"));
  if (digest.size_bytes() < 0)
    return FieldError(absl::StrCat(std::string(fieldPath), ".sizeBytes"), "must be >= 0");
  return absl::OkStatus();
}

std::string DigestString(const v1::Digest& digest) {
  return absl::StrCat("sha256:", digest.hash(), "/", digest.size_bytes());
}

// ---- BlobUpload ----

BlobUpload::BlobUpload(BlobStore* store, v1::Digest digest, fs::path partialPath)
    : store_(store), digest_(std::move(digest)), partialPath_(std::move(partialPath)) {}

BlobUpload::~BlobUpload() {
  if (fd_ >= 0) {
    // Keep what arrived, durably, so QueryWriteStatus reports it and the client resumes.
    if (::fdatasync(fd_) != 0)
      Logger("blobs")->warn("fdatasync {}: {}", partialPath_.string(), std::strerror(errno));
    ::close(fd_);
  }
  Release();
}

void BlobUpload::Release() {
  if (store_) store_->EndUpload(partialPath_.filename().string());
  store_ = nullptr;
}

absl::Status BlobUpload::Open() {
  fd_ = ::open(partialPath_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd_ >= 0) {
    // A new partial upload: its name must survive a crash as its bytes will.
    PB_RETURN_IF_ERROR(FsyncDirectory(partialPath_.parent_path().string()));
  } else if (errno == EEXIST) {
    fd_ = ::open(partialPath_.c_str(), O_RDWR | O_CLOEXEC);
  }
  if (fd_ < 0) return IoError(errno, partialPath_.string(), "open");
  struct stat st;
  if (::fstat(fd_, &st) != 0) return IoError(errno, partialPath_.string(), "stat");
  size_ = st.st_size;
  if (size_ > digest_.size_bytes()) {
    // Cannot be the prefix of this blob: start over.
    if (::ftruncate(fd_, 0) != 0) return IoError(errno, partialPath_.string(), "truncate");
    size_ = 0;
  }
  // Resuming: the hash covers the bytes received by earlier uploads.
  std::string buffer;
  for (int64_t offset = 0; offset < size_; offset += kHashBufferBytes) {
    PB_RETURN_IF_ERROR(ReadFully(fd_, offset, std::min(kHashBufferBytes, size_ - offset), &buffer));
    if (int64_t(buffer.size()) != std::min(kHashBufferBytes, size_ - offset))
      return absl::InternalError("partial upload shrank while being read");
    hash_.Update(buffer);
  }
  if (::lseek(fd_, size_, SEEK_SET) < 0) return IoError(errno, partialPath_.string(), "seek");
  return absl::OkStatus();
}

absl::Status BlobUpload::Append(int64_t offset, std::string_view data) {
  if (done_) return absl::FailedPreconditionError("the upload is already committed");
  if (offset != size_)
    return FieldError("writeOffset", absl::StrCat("expected ", size_,
                                                  " (the bytes committed so far), got ", offset));
  if (int64_t(data.size()) > digest_.size_bytes() - size_)
    return FieldError("data", absl::StrCat("the blob would exceed its digest's size ",
                                           digest_.size_bytes(), " bytes"));
  PB_RETURN_IF_ERROR(WriteAll(fd_, data, partialPath_));
  hash_.Update(data);
  size_ += int64_t(data.size());
  return absl::OkStatus();
}

void BlobUpload::Discard() {
  if (done_) return;
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  std::error_code ec;
  fs::remove(partialPath_, ec);
  if (ec) Logger("blobs")->warn("discard {}: {}", partialPath_.string(), ec.message());
  done_ = true;
}

absl::Status BlobUpload::Commit() {
  if (done_) return absl::OkStatus();
  if (size_ != digest_.size_bytes()) {
    // Short: keep the bytes so the client can resume.
    return FieldError("finishWrite",
                      absl::StrCat("received ", size_, " bytes of ", digest_.size_bytes(),
                                   "; the blob is incomplete"));
  }
  std::string hash = hash_.FinalHex();
  if (hash != digest_.hash()) {
    Discard();
    return FieldError("digest.hash",
                      absl::StrCat("the uploaded bytes hash to ", hash, ", not ", digest_.hash()));
  }
  if (::fsync(fd_) != 0) return IoError(errno, partialPath_.string(), "fsync");
  ::close(fd_);
  fd_ = -1;
  done_ = true;
  return store_->Publish(partialPath_, digest_.hash());
}

// ---- BlobReader ----

BlobReader::~BlobReader() {
  ::close(fd_);
}

absl::Status BlobReader::ReadAt(int64_t offset, int64_t maxBytes, std::string* out) const {
  int64_t count = std::max<int64_t>(0, std::min(maxBytes, size_ - offset));
  PB_RETURN_IF_ERROR(ReadFully(fd_, offset, count, out));
  if (int64_t(out->size()) != count)
    return absl::DataLossError("the stored blob is shorter than its digest's size");
  return absl::OkStatus();
}

// ---- BlobStore ----

BlobStore::BlobStore(fs::path blobsDir, fs::path uploadsDir, fs::path tmpDir, int64_t maxBlobBytes)
    : blobsDir_(std::move(blobsDir)),
      uploadsDir_(std::move(uploadsDir)),
      tmpDir_(std::move(tmpDir)),
      maxBlobBytes_(maxBlobBytes) {}

absl::StatusOr<std::unique_ptr<BlobStore>> BlobStore::Open(const fs::path& dataDir,
                                                           int64_t maxBlobBytes) {
  if (maxBlobBytes <= 0) return absl::InvalidArgumentError("maxBlobBytes must be > 0");
  fs::path blobs = dataDir / "blobs", uploads = dataDir / "uploads", tmp = dataDir / "tmp";
  for (const fs::path& dir : {blobs, uploads, tmp}) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) return IoError(ec.value(), dir.string(), "create");
  }
  // Scratch files of an earlier run are garbage (results are imported before a job completes).
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(tmp, ec)) fs::remove_all(entry.path(), ec);
  return std::unique_ptr<BlobStore>(new BlobStore(blobs, uploads, tmp, maxBlobBytes));
}

absl::StatusOr<std::unique_ptr<BlobStore>> BlobStore::OpenForReading(const fs::path& dataDir,
                                                                     int64_t maxBlobBytes) {
  if (maxBlobBytes <= 0) return absl::InvalidArgumentError("maxBlobBytes must be > 0");
  const fs::path blobs = dataDir / "blobs";
  std::error_code ec;
  if (!fs::is_directory(blobs, ec))
    return absl::NotFoundError(absl::StrCat(blobs.string(), ": no blob store there"));
  return std::unique_ptr<BlobStore>(
      new BlobStore(blobs, dataDir / "uploads", dataDir / "tmp", maxBlobBytes));
}

fs::path BlobStore::BlobPath(const std::string& hash) const {
  return blobsDir_ / hash.substr(0, 2) / hash;
}

fs::path BlobStore::PartialPath(const v1::Digest& digest) const {
  return uploadsDir_ / absl::StrCat(digest.hash(), "_", digest.size_bytes());
}

bool BlobStore::Contains(const v1::Digest& digest) const {
  struct stat st;
  if (::stat(BlobPath(digest.hash()).c_str(), &st) != 0) return false;
  return S_ISREG(st.st_mode) && st.st_size == digest.size_bytes();
}

bool BlobStore::Touch(const v1::Digest& digest) {
  std::lock_guard lock(mutex_);
  if (!Contains(digest)) return false;
  StampUsed(BlobPath(digest.hash()));
  return true;
}

std::vector<v1::Digest> BlobStore::FindMissing(const std::vector<v1::Digest>& digests) {
  std::vector<v1::Digest> missing;
  std::set<std::pair<std::string, int64_t>> seen;
  for (const v1::Digest& d : digests) {
    if (!seen.insert({d.hash(), d.size_bytes()}).second) continue;
    if (!Touch(d)) missing.push_back(d);
  }
  return missing;
}

absl::StatusOr<int64_t> BlobStore::CommittedSize(const v1::Digest& digest, bool* complete) const {
  *complete = Contains(digest);
  if (*complete) return digest.size_bytes();
  const fs::path partial = PartialPath(digest);
  const int fd = ::open(partial.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return 0;
    return IoError(errno, partial.string(), "open");
  }
  // The size first, then the sync: uploads only append, so every byte counted was written before
  // the fdatasync began and is on disk when it returns. (An open upload goes on appending.)
  struct stat st;
  absl::Status status;
  if (::fstat(fd, &st) != 0) {
    status = IoError(errno, partial.string(), "stat");
  } else if (::fdatasync(fd) != 0) {
    status = IoError(errno, partial.string(), "fdatasync");
  }
  ::close(fd);
  PB_RETURN_IF_ERROR(status);
  return st.st_size <= digest.size_bytes() ? int64_t(st.st_size) : 0;
}

absl::StatusOr<std::unique_ptr<BlobUpload>> BlobStore::BeginWrite(const v1::Digest& digest) {
  PB_RETURN_IF_ERROR(ValidateDigest(digest, "digest"));
  if (digest.size_bytes() > maxBlobBytes_)
    return FieldError("digest.sizeBytes",
                      absl::StrCat(digest.size_bytes(), " bytes exceeds the server's limit of ",
                                   maxBlobBytes_, " bytes per blob"));
  fs::path partial = PartialPath(digest);
  {
    std::lock_guard lock(mutex_);
    if (!openUploads_.insert(partial.filename().string()).second)
      return absl::AbortedError(
          absl::StrCat("another upload of ", DigestString(digest), " is in progress"));
  }
  auto upload = std::unique_ptr<BlobUpload>(new BlobUpload(this, digest, partial));
  PB_RETURN_IF_ERROR(upload->Open());
  return upload;
}

void BlobStore::EndUpload(const std::string& key) {
  std::lock_guard lock(mutex_);
  openUploads_.erase(key);
}

absl::Status BlobStore::Publish(const fs::path& from, const std::string& hash) {
  fs::path target = BlobPath(hash);
  std::error_code ec;
  fs::create_directories(target.parent_path(), ec);
  if (ec) return IoError(ec.value(), target.parent_path().string(), "create");  // ENOSPC: no inode
  {
    std::lock_guard lock(mutex_);  // not between a collection's check of the name and its removal
    if (::rename(from.c_str(), target.c_str()) != 0) return IoError(errno, from.string(), "rename");
    // Stored now, whenever its bytes were written: what a collection under way compares with.
    StampUsed(target);
  }
  PB_RETURN_IF_ERROR(FsyncDirectory(target.parent_path().string()));
  Logger("blobs")->debug("stored blob {}", hash);
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<BlobReader>> BlobStore::OpenRead(const v1::Digest& digest) const {
  PB_RETURN_IF_ERROR(ValidateDigest(digest, "digest"));
  fs::path path = BlobPath(digest.hash());
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT)
      return absl::NotFoundError(absl::StrCat("blob ", DigestString(digest), " is not stored"));
    return IoError(errno, path.string(), "open");
  }
  struct stat st;
  if (::fstat(fd, &st) != 0 || st.st_size != digest.size_bytes()) {
    ::close(fd);
    return absl::DataLossError(absl::StrCat("blob ", digest.hash(), " is stored with ",
                                            int64_t(st.st_size), " bytes, not ",
                                            digest.size_bytes()));
  }
  return std::unique_ptr<BlobReader>(new BlobReader(fd, st.st_size));
}

absl::StatusOr<std::string> BlobStore::ReadAll(const v1::Digest& digest) const {
  PB_ASSIGN_OR_RETURN(std::unique_ptr<BlobReader> reader, OpenRead(digest));
  std::string bytes;
  PB_RETURN_IF_ERROR(reader->ReadAt(0, reader->size(), &bytes));
  return bytes;
}

absl::StatusOr<v1::Digest> BlobStore::ImportFile(const fs::path& path) {
  int64_t size = 0;
  PB_ASSIGN_OR_RETURN(std::string hash, runtime::Sha256OfFile(path, &size));
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return IoError(errno, path.string(), "open");
  absl::Status status;
  if (::fsync(fd) != 0) status = IoError(errno, path.string(), "fsync");
  ::close(fd);
  PB_RETURN_IF_ERROR(status);
  v1::Digest digest;
  digest.set_hash(hash);
  digest.set_size_bytes(size);
  if (Touch(digest)) {
    std::error_code ec;
    fs::remove(path, ec);
  } else {
    PB_RETURN_IF_ERROR(Publish(path, digest.hash()));
  }
  return digest;
}

BlobStore::Collected BlobStore::Collect(const std::set<std::string>& live,
                                        fs::file_time_type unusedSince) {
  Collected collected;
  const fs::file_time_type cutoff = unusedSince;
  // Removes `path` when `keep` (called under the lock) says no and it is older than the cutoff;
  // its size when removed.
  auto removeIfStale = [&](const fs::path& path, const auto& keep) -> std::optional<int64_t> {
    std::lock_guard lock(mutex_);
    if (keep()) return std::nullopt;
    std::error_code ec;
    const fs::file_time_type modified = fs::last_write_time(path, ec);
    if (ec || modified > cutoff) return std::nullopt;
    const int64_t size = int64_t(fs::file_size(path, ec));
    if (ec || !fs::remove(path, ec)) {
      if (ec) Logger("blobs")->warn("collect: remove {}: {}", path.string(), ec.message());
      return std::nullopt;
    }
    return size;
  };
  std::error_code ec;
  for (const auto& dir : fs::directory_iterator(blobsDir_, ec)) {
    std::error_code dirError;
    for (const auto& entry : fs::directory_iterator(dir.path(), dirError)) {
      const std::string hash = entry.path().filename().string();
      if (std::optional<int64_t> size =
              removeIfStale(entry.path(), [&] { return live.count(hash) > 0; })) {
        ++collected.blobs;
        collected.blobBytes += *size;
      }
    }
  }
  for (const auto& entry : fs::directory_iterator(uploadsDir_, ec)) {
    const std::string name = entry.path().filename().string();
    if (std::optional<int64_t> size =
            removeIfStale(entry.path(), [&] { return openUploads_.count(name) > 0; })) {
      ++collected.partials;
      collected.partialBytes += *size;
    }
  }
  return collected;
}

}  // namespace probebake::server
