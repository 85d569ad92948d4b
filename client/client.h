// The probebake.v1 client behind the `probebake` CLI: connection and token, uploads of a job's
// files as blobs (only the missing ones, resumable), job calls, watching, and resumable
// downloads of result volumes. Errors are absl::Status with the gRPC code; the CLI maps codes
// to its exit codes (ExitCodeFor).
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "absl/status/statusor.h"
#include "probebake/v1/service.grpc.pb.h"

namespace probebake::client {

struct ConnectOptions {
  std::string server = "127.0.0.1:50051";  // host:port
  std::string token;                       // empty: no authorization metadata
  std::filesystem::path tlsCaFile;         // PEM roots; empty with `tls`: the system's roots
  bool tls = false;
  std::chrono::milliseconds connectTimeout{5000};
};

// What uploading a job's files did.
struct UploadReport {
  int files = 0;          // distinct files the job and its models reference
  int uploaded = 0;       // blobs sent (the rest the server had)
  int64_t bytesSent = 0;  // bytes of the uploaded blobs
  // Every file reference rewritten to a blob: its field ("scene.meshes[0].file"), its path as
  // written, and the blob's hash.
  struct Rewrite {
    std::string fieldPath, relativePath, hash;
  };
  std::vector<Rewrite> rewrites;
  // A file a model references that could not be read, so was not uploaded: the server's refusal
  // when its import needs it ("<mesh>.references: ... references \"x\", which is not listed") and
  // the local reader's error, which the CLI reports instead (what a local bake says).
  struct Unreadable {
    std::string serverField, serverTail, localMessage;
  };
  std::vector<Unreadable> unreadable;
};

// `status` with the server's names of uploaded files put back as the user wrote them: the
// server reports "scene.meshes[0].blob: cannot import \"blob <hash>\" ...", the user's job says
// "scene.meshes[0].file" and "room.obj". A refusal for a referenced file that could not be read
// becomes the local reader's error.
// OK when `target` can name a server: HOST:PORT (port 1-65535; an IPv6 host in brackets) or a
// gRPC target URI (dns:, unix:, unix-abstract:, ipv4:, ipv6:, vsock:). INVALID_ARGUMENT saying why
// not otherwise (gRPC would only report the server unreachable).
absl::Status CheckServerAddress(const std::string& target);

absl::Status NameUploadedFiles(const absl::Status& status, const UploadReport& uploads);

class Client {
 public:
  // Opens the channel and waits until it connects. UNAVAILABLE when the server cannot be reached
  // within connectTimeout.
  static absl::StatusOr<std::unique_ptr<Client>> Connect(const ConnectOptions& options);

  absl::StatusOr<v1::ServerCapabilities> GetCapabilities();

  // Uploads `bytes` as a blob unless the server has it, resuming a partial upload. While another
  // client uploads the same blob (the server takes one upload of a digest at a time and answers
  // others ABORTED), waits for it and then skips or resumes; ABORTED only if that upload makes no
  // progress for `stallLimit`.
  absl::Status UploadBlob(const v1::Digest& digest, const std::string& bytes,
                          int64_t* bytesSent = nullptr,
                          std::chrono::seconds stallLimit = std::chrono::seconds(120));

  // Replaces every `file` of `job` (paths relative to `jobDir`) by the digest of its bytes and
  // uploads the blobs the server lacks. INVALID_ARGUMENT naming the field for unreadable files.
  absl::StatusOr<UploadReport> UploadJobFiles(const std::filesystem::path& jobDir,
                                              v1::JobSpec* job);

  // CreateBakeJob; RESOURCE_EXHAUSTED is retried after the server's retry-after-ms, up to
  // `maxAttempts` times, with the same request id.
  absl::StatusOr<v1::BakeJob> CreateJob(const v1::JobSpec& job, const std::string& requestId,
                                        bool skipCache, int maxAttempts = 10);
  absl::StatusOr<v1::BakeJob> GetJob(const std::string& name);
  absl::StatusOr<v1::ListBakeJobsResponse> ListJobs(int pageSize, const std::string& pageToken);
  absl::StatusOr<v1::BakeJob> CancelJob(const std::string& name);
  // Forgets a job that is not running (FAILED_PRECONDITION for a running one).
  absl::Status DeleteJob(const std::string& name);

  // Streams the job's states to `onUpdate` until a final state, which it returns. A stream broken
  // by a server restart (UNAVAILABLE) is resumed for up to `reconnectFor`.
  absl::StatusOr<v1::BakeJob> Watch(const std::string& name,
                                    const std::function<void(const v1::BakeJob&)>& onUpdate,
                                    std::chrono::seconds reconnectFor = std::chrono::seconds(120));

  // Downloads the blob to `out`: bytes go to PartialPath(out, digest), which a later call for the
  // same blob continues from its size (a partial file of another blob is never taken up), held
  // under an exclusive lock so that a second fetch to the same path fails at once (ABORTED) rather
  // than writing into it; when complete the file's SHA-256 is checked and it is renamed to `out`.
  // Write errors are INTERNAL, with the system's reason. `onBytes` gets
  // the bytes received so far.
  static std::filesystem::path PartialPath(const std::filesystem::path& out,
                                           const v1::Digest& digest);
  absl::Status FetchBlob(const v1::Digest& digest, const std::filesystem::path& out,
                         const std::function<void(int64_t done, int64_t total)>& onBytes = {});

 private:
  Client(std::shared_ptr<grpc::Channel> channel, std::string token);
  std::unique_ptr<grpc::ClientContext> Context(
      std::optional<std::chrono::seconds> deadline = std::chrono::seconds(60)) const;
  // One attempt of UploadBlob; `committed`: the server's committed size when it began.
  absl::Status UploadBlobOnce(const v1::Digest& digest, const std::string& bytes,
                              int64_t* bytesSent, int64_t* committed);

  std::shared_ptr<grpc::Channel> channel_;
  std::string token_;
  std::unique_ptr<v1::Capabilities::Stub> capabilities_;
  std::unique_ptr<v1::ContentStorage::Stub> content_;
  std::unique_ptr<v1::BakeJobs::Stub> jobs_;
  int64_t chunkBytes_ = 1 << 20;
};

// grpc::Status -> absl::Status.
absl::Status FromGrpc(const grpc::Status& status);

// A fresh request id: 32 random lowercase hex digits.
std::string NewRequestId();

// The exit codes for an error (docs/service.md): 4 could not reach or authenticate to the server
// (UNAVAILABLE, UNAUTHENTICATED, PERMISSION_DENIED, DEADLINE_EXCEEDED), 2 bad usage or input
// (INVALID_ARGUMENT, FAILED_PRECONDITION, NOT_FOUND, OUT_OF_RANGE, ALREADY_EXISTS), 1 otherwise.
int ExitCodeFor(const absl::Status& status);

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitJobFailed = 3;
inline constexpr int kExitUnreachable = 4;

}  // namespace probebake::client
