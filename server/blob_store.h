// The content-addressed blob store under DATA/blobs (docs/service.md): meshes, environment maps and
// baked volumes, each stored once under its SHA-256.
//
// Layout: DATA/blobs/<hash[0..2]>/<hash> holds the verified bytes; DATA/uploads/<hash>_<size>
// holds the bytes received so far of an unfinished upload, so a broken upload resumes from its
// committed size. A blob reaches its final name only after its size and hash were verified and
// its bytes fsynced (temporary name, fsync, rename, fsync of the folder), so a reader never sees
// a partial or corrupt blob under a digest.
//
// Durability of partial uploads: Append does not sync (a sync per chunk would tie upload speed to
// the disk's flush latency); instead the bytes are synced before the server tells a client how
// many it holds. CommittedSize (QueryWriteStatus) syncs the partial file before it answers, and
// an upload closed without Commit (stream broken or ended, or a bad chunk: the client is then
// told the committed size) syncs on close. So a committed size the client was given survives a
// crash of the server or the machine; bytes never acknowledged may be lost, and QueryWriteStatus
// after a restart reports what is on disk.
//
// Thread safety: every method may be called from any thread. At most one upload per digest is
// open at a time (a second one gets ABORTED).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/job/digest.h"
#include "probebake/v1/job.pb.h"

namespace probebake::server {

// Checks `digest` is well formed (64 lowercase hex characters, size >= 0); errors name
// `fieldPath` ("scene.meshes[0].blob.hash: ...").
absl::Status ValidateDigest(const v1::Digest& digest, std::string_view fieldPath);

// "sha256:<hash>/<size>", for messages and logs.
std::string DigestString(const v1::Digest& digest);

class BlobStore;

// An open upload of one blob (BlobStore::BeginWrite). Append bytes in order, then Commit. Closing
// an upload without Commit keeps (and fsyncs) the bytes received, for resumption.
class BlobUpload {
 public:
  ~BlobUpload();
  BlobUpload(const BlobUpload&) = delete;
  BlobUpload& operator=(const BlobUpload&) = delete;

  const v1::Digest& digest() const { return digest_; }
  // Bytes received so far, including those of earlier interrupted uploads.
  int64_t committedSize() const { return size_; }

  // Appends `data` at `offset`, which must equal committedSize() (INVALID_ARGUMENT otherwise, or
  // when the blob would exceed its digest's size).
  absl::Status Append(int64_t offset, std::string_view data);
  // Verifies size and SHA-256 against the digest and stores the blob. INVALID_ARGUMENT on a
  // mismatch (a wrong hash discards the partial upload, so a retry starts from 0).
  absl::Status Commit();
  // Removes the partial upload: a refused upload leaves nothing behind. No-op once committed.
  void Discard();

 private:
  friend class BlobStore;
  BlobUpload(BlobStore* store, v1::Digest digest, std::filesystem::path partialPath);
  absl::Status Open();
  void Release();

  BlobStore* store_;
  v1::Digest digest_;
  std::filesystem::path partialPath_;
  int fd_ = -1;
  int64_t size_ = 0;
  bool done_ = false;
  Sha256 hash_;
};

// A stored blob opened for reading; the file's size equals the digest's.
class BlobReader {
 public:
  ~BlobReader();
  BlobReader(const BlobReader&) = delete;
  BlobReader& operator=(const BlobReader&) = delete;

  int64_t size() const { return size_; }
  // Reads up to `maxBytes` at `offset` into `out` (replacing its contents); fewer only at the end.
  absl::Status ReadAt(int64_t offset, int64_t maxBytes, std::string* out) const;

 private:
  friend class BlobStore;
  BlobReader(int fd, int64_t size) : fd_(fd), size_(size) {}
  int fd_;
  int64_t size_;
};

class BlobStore {
 public:
  // Opens (creating if needed) the store under `dataDir` for the server that owns it, and clears
  // DATA/tmp (scratch files of an earlier run). `maxBlobBytes` (> 0) bounds uploads.
  static absl::StatusOr<std::unique_ptr<BlobStore>> Open(const std::filesystem::path& dataDir,
                                                         int64_t maxBlobBytes);
  // Opens the store of a running server for reading blobs (the asset-check child): creates and
  // clears nothing, since DATA/tmp holds that server's files in use. NOT_FOUND without a store.
  static absl::StatusOr<std::unique_ptr<BlobStore>> OpenForReading(
      const std::filesystem::path& dataDir, int64_t maxBlobBytes);

  int64_t maxBlobBytes() const { return maxBlobBytes_; }

  // True when the blob is stored with the digest's size.
  bool Contains(const v1::Digest& digest) const;
  // Contains, and when stored marks the blob as used now (its file's modification time), so a
  // collection within its grace period keeps it even while no job refers to it yet. For every
  // check a client or a new job relies on: FindMissing's hits, a new job's inputs, a cache hit's
  // volume.
  bool Touch(const v1::Digest& digest);
  // The digests not stored, in order, without duplicates (digests must be valid); the stored
  // ones are touched.
  std::vector<v1::Digest> FindMissing(const std::vector<v1::Digest>& digests);

  // Bytes held for an upload of `digest`: its size when stored, the partial size otherwise, synced
  // to disk before this returns (an error when the sync fails).
  absl::StatusOr<int64_t> CommittedSize(const v1::Digest& digest, bool* complete) const;

  // Opens an upload (resuming any partial one). INVALID_ARGUMENT past maxBlobBytes, ABORTED when
  // another upload of the same digest is open.
  absl::StatusOr<std::unique_ptr<BlobUpload>> BeginWrite(const v1::Digest& digest);

  // Opens a stored blob. NOT_FOUND when absent, DATA_LOSS when its file has the wrong size.
  absl::StatusOr<std::unique_ptr<BlobReader>> OpenRead(const v1::Digest& digest) const;

  // Moves the file at `path` (on the same file system, e.g. under DATA/tmp) into the store under
  // its SHA-256 and returns its digest. The file is consumed.
  absl::StatusOr<v1::Digest> ImportFile(const std::filesystem::path& path);

  // Reads a whole stored blob (assets handed to the job loader).
  absl::StatusOr<std::string> ReadAll(const v1::Digest& digest) const;

  // A scratch folder on the store's file system for files later imported.
  const std::filesystem::path& tmpDir() const { return tmpDir_; }

  // What Collect removed.
  struct Collected {
    int64_t blobs = 0, blobBytes = 0;
    int64_t partials = 0, partialBytes = 0;  // partial uploads
  };
  // Removes every stored blob whose hash is not in `live` and that was neither stored nor touched
  // since `unusedSince`, and every partial upload neither open nor written to since then. Each
  // file's check and removal is atomic with Touch and with storing a blob, so a blob touched (or
  // stored again) during a collection stays. Files that cannot be removed are logged and left.
  Collected Collect(const std::set<std::string>& live, std::filesystem::file_time_type unusedSince);

 private:
  friend class BlobUpload;
  BlobStore(std::filesystem::path blobsDir, std::filesystem::path uploadsDir,
            std::filesystem::path tmpDir, int64_t maxBlobBytes);
  std::filesystem::path BlobPath(const std::string& hash) const;
  std::filesystem::path PartialPath(const v1::Digest& digest) const;
  // Renames the fsynced file `from` to the blob's final name.
  absl::Status Publish(const std::filesystem::path& from, const std::string& hash);
  void EndUpload(const std::string& key);

  std::filesystem::path blobsDir_, uploadsDir_, tmpDir_;
  int64_t maxBlobBytes_;
  // Guards openUploads_, and makes Touch, Publish and Collect's removals atomic with each other.
  mutable std::mutex mutex_;
  std::set<std::string> openUploads_;  // PartialPath names of open uploads
};

}  // namespace probebake::server
