#include "client/client.h"

#include <fcntl.h>
#include <openssl/rand.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <thread>

#include "absl/cleanup/cleanup.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "probebake/base/check.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/digest.h"
#include "probebake/job/file_refs.h"
#include "runtime/files.h"
#include "runtime/job_state.h"

namespace probebake::client {

namespace {}  // namespace

absl::Status FromGrpc(const grpc::Status& status) {
  if (status.ok()) return absl::OkStatus();
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message());
}

std::string NewRequestId() {
  unsigned char bytes[16];
  PB_CHECK(RAND_bytes(bytes, sizeof(bytes)) == 1);
  return absl::BytesToHexString(absl::string_view(reinterpret_cast<const char*>(bytes), 16));
}

int ExitCodeFor(const absl::Status& status) {
  switch (status.code()) {
    case absl::StatusCode::kOk:
      return kExitOk;
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kUnauthenticated:
    case absl::StatusCode::kPermissionDenied:
    case absl::StatusCode::kDeadlineExceeded:
      return kExitUnreachable;
    case absl::StatusCode::kInvalidArgument:
    case absl::StatusCode::kFailedPrecondition:
    case absl::StatusCode::kNotFound:
    case absl::StatusCode::kOutOfRange:
    case absl::StatusCode::kAlreadyExists:
      return kExitUsage;
    default:
      return kExitFailure;
  }
}

Client::Client(std::shared_ptr<grpc::Channel> channel, std::string token)
    : channel_(std::move(channel)),
      token_(std::move(token)),
      capabilities_(v1::Capabilities::NewStub(channel_)),
      content_(v1::ContentStorage::NewStub(channel_)),
      jobs_(v1::BakeJobs::NewStub(channel_)) {}

absl::StatusOr<std::unique_ptr<Client>> Client::Connect(const ConnectOptions& options) {
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
  if (options.tls || !options.tlsCaFile.empty()) {
    grpc::SslCredentialsOptions ssl;
    if (!options.tlsCaFile.empty()) {
      absl::StatusOr<std::string> roots = runtime::ReadWholeFile(options.tlsCaFile);
      if (!roots.ok())
        return absl::InvalidArgumentError(
            absl::StrCat("--tls-ca: ", std::string(roots.status().message())));
      ssl.pem_root_certs = std::move(*roots);
    }
    credentials = grpc::SslCredentials(ssl);
  }
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(64 << 20);
  auto channel = grpc::CreateCustomChannel(options.server, credentials, arguments);
  // Connect now, so an unreachable server is reported at once: the first failed attempt
  // (refused, no route, TLS handshake) ends the wait instead of the timeout.
  auto deadline = std::chrono::system_clock::now() + options.connectTimeout;
  grpc_connectivity_state state = channel->GetState(/*try_to_connect=*/true);
  while (state != GRPC_CHANNEL_READY) {
    if (state == GRPC_CHANNEL_TRANSIENT_FAILURE || state == GRPC_CHANNEL_SHUTDOWN ||
        !channel->WaitForStateChange(state, deadline))
      return absl::UnavailableError(absl::StrCat("cannot reach the server at ", options.server));
    state = channel->GetState(true);
  }
  std::unique_ptr<Client> client(new Client(std::move(channel), options.token));
  return client;
}

std::unique_ptr<grpc::ClientContext> Client::Context(
    std::optional<std::chrono::seconds> deadline) const {
  auto context = std::make_unique<grpc::ClientContext>();
  if (deadline) context->set_deadline(std::chrono::system_clock::now() + *deadline);
  if (!token_.empty()) context->AddMetadata("authorization", "Bearer " + token_);
  return context;
}

absl::StatusOr<v1::ServerCapabilities> Client::GetCapabilities() {
  v1::ServerCapabilities capabilities;
  auto context = Context();
  PB_RETURN_IF_ERROR(FromGrpc(capabilities_->GetCapabilities(context.get(), {}, &capabilities)));
  if (capabilities.chunk_bytes() > 0) chunkBytes_ = capabilities.chunk_bytes();
  return capabilities;
}

absl::Status Client::UploadBlob(const v1::Digest& digest, const std::string& bytes,
                                int64_t* bytesSent, std::chrono::seconds stallLimit) {
  using Clock = std::chrono::steady_clock;
  auto lastProgress = Clock::now();
  int64_t lastCommitted = -1;
  auto pause = std::chrono::milliseconds(100);
  while (true) {
    int64_t committed = 0;
    absl::Status sent = UploadBlobOnce(digest, bytes, bytesSent, &committed);
    if (!absl::IsAborted(sent)) return sent;
    // Another client's upload of this blob (a build farm's shared asset): wait while it moves.
    if (committed != lastCommitted) lastProgress = Clock::now();
    lastCommitted = committed;
    if (Clock::now() - lastProgress > stallLimit)
      return absl::AbortedError(
          absl::StrCat(sent.message(), "; it made no progress for ", stallLimit.count(), " s"));
    std::this_thread::sleep_for(pause);
    pause = std::min(2 * pause, std::chrono::milliseconds(2000));
  }
}

absl::Status Client::UploadBlobOnce(const v1::Digest& digest, const std::string& bytes,
                                    int64_t* bytesSent, int64_t* committed) {
  // Where an earlier, interrupted upload stopped (or another client's upload has got to).
  v1::QueryWriteStatusRequest query;
  *query.mutable_digest() = digest;
  v1::QueryWriteStatusResponse status;
  auto queryContext = Context();
  PB_RETURN_IF_ERROR(FromGrpc(content_->QueryWriteStatus(queryContext.get(), query, &status)));
  if (status.complete()) return absl::OkStatus();
  int64_t offset = status.committed_size();
  *committed = offset;

  auto context = Context(std::nullopt);
  v1::WriteBlobResponse response;
  auto writer = content_->WriteBlob(context.get(), &response);
  bool first = true;
  do {
    v1::WriteBlobRequest request;
    if (first) *request.mutable_digest() = digest;
    first = false;
    int64_t n = std::min<int64_t>(chunkBytes_, int64_t(bytes.size()) - offset);
    request.set_write_offset(offset);
    request.set_data(bytes.substr(size_t(offset), size_t(n)));
    offset += n;
    request.set_finish_write(offset == int64_t(bytes.size()));
    if (!writer->Write(request)) break;  // the server ended the call; Finish says why
    if (bytesSent) *bytesSent += n;
  } while (offset < int64_t(bytes.size()));
  writer->WritesDone();
  return FromGrpc(writer->Finish());
}

absl::StatusOr<UploadReport> Client::UploadJobFiles(const std::filesystem::path& jobDir,
                                                    v1::JobSpec* job) {
  UploadReport report;
  std::vector<FileReference> refs = ListFileReferences(*job);
  report.files = int(refs.size());
  if (refs.empty()) return report;
  // Read and hash every file (the same file named twice is one blob).
  std::map<std::string, std::pair<std::string, v1::Digest>> files;  // relative path -> bytes
  // The local bake's reader, for its checks and messages (a folder named as a file is refused,
  // not uploaded as an empty blob); the server applies its own size limit.
  const LocalAssetSource local(jobDir.string(), "", /*maxBytes=*/0);
  // The files each mesh's model references, by the path the model writes (uploaded as blobs too;
  // keyed in `files` by their path relative to the job file, so a texture shared by many models is
  // one upload). One the model names but that cannot be read is not uploaded: the server refuses
  // the job, naming it, if the import needs it, as a local bake would.
  std::map<int, std::map<std::string, v1::Digest>> meshReferences;
  for (const FileReference& ref : refs) {
    if (files.count(ref.relativePath) && ref.kind != FileReference::Kind::kMesh) continue;
    if (!files.count(ref.relativePath)) {
      absl::StatusOr<std::string> bytes = local.ReadFile(ref.relativePath, ref.fieldPath);
      if (!bytes.ok()) return bytes.status();
      v1::Digest digest = DigestOf(*bytes);
      files.emplace(ref.relativePath, std::make_pair(std::move(*bytes), digest));
    }
    if (ref.kind != FileReference::Kind::kMesh) continue;
    const std::optional<std::string> format = MeshFormatOf(job->scene().meshes(ref.meshIndex));
    if (!format) continue;  // ReplaceFileWithBlob names the problem
    auto readReference = [&](const std::string& modelPath) -> std::optional<std::string> {
      const std::string inJob = (std::filesystem::path(ref.relativePath).parent_path() / modelPath)
                                    .lexically_normal()
                                    .generic_string();
      if (auto it = files.find(inJob); it != files.end()) return it->second.first;
      absl::StatusOr<std::string> bytes =
          local.ReadReferencedFile(ref.relativePath, modelPath, ref.fieldPath);
      if (!bytes.ok()) {
        const std::string meshPath = ref.fieldPath.substr(0, ref.fieldPath.rfind('.'));
        report.unreadable.push_back(
            {meshPath + ".references: ",
             absl::StrCat("references \"", modelPath, "\", which is not listed"),
             std::string(bytes.status().message())});
        return std::nullopt;
      }
      v1::Digest digest = DigestOf(*bytes);
      return files.emplace(inJob, std::make_pair(std::move(*bytes), digest)).first->second.first;
    };
    std::map<std::string, v1::Digest>& references = meshReferences[ref.meshIndex];
    for (const std::string& modelPath :
         ListModelReferences(files.at(ref.relativePath).first, *format, readReference)) {
      if (!readReference(modelPath)) continue;
      const std::string inJob = (std::filesystem::path(ref.relativePath).parent_path() / modelPath)
                                    .lexically_normal()
                                    .generic_string();
      references[modelPath] = files.at(inJob).second;
    }
  }
  report.files = int(files.size());
  v1::FindMissingBlobsRequest find;
  for (const auto& [path, file] : files) *find.add_blob_digests() = file.second;
  v1::FindMissingBlobsResponse missing;
  auto context = Context();
  PB_RETURN_IF_ERROR(FromGrpc(content_->FindMissingBlobs(context.get(), find, &missing)));
  std::set<std::string> missingHashes;
  for (const v1::Digest& d : missing.missing_blob_digests()) missingHashes.insert(d.hash());
  for (const auto& [path, file] : files) {
    if (!missingHashes.count(file.second.hash())) continue;
    const absl::Status sent = UploadBlob(file.second, file.first, &report.bytesSent);
    if (!sent.ok()) {
      const std::string& field = std::find_if(refs.begin(), refs.end(), [&](const auto& ref) {
                                   return ref.relativePath == path;
                                 })->fieldPath;
      return absl::Status(sent.code(),
                          absl::StrCat(field, ": uploading \"", path, "\": ", sent.message()));
    }
    ++report.uploaded;
  }
  // Rewrite in reverse so indices of later references stay valid whatever the rewrite does.
  for (auto it = refs.rbegin(); it != refs.rend(); ++it) {
    const v1::Digest& digest = files.at(it->relativePath).second;
    PB_RETURN_IF_ERROR(ReplaceFileWithBlob(*it, digest, job));
    report.rewrites.push_back({it->fieldPath, it->relativePath, digest.hash()});
    if (it->kind == FileReference::Kind::kMesh) {
      auto* references = job->mutable_scene()->mutable_meshes(it->meshIndex)->mutable_references();
      for (const auto& [modelPath, referenced] : meshReferences[it->meshIndex])
        (*references)[modelPath] = referenced;
    }
  }
  return report;
}

absl::Status CheckServerAddress(const std::string& target) {
  for (const char* scheme : {"dns:", "unix:", "unix-abstract:", "ipv4:", "ipv6:", "vsock:"})
    if (absl::StartsWith(target, scheme)) return absl::OkStatus();
  const size_t colon = target.rfind(':');
  const std::string host = colon == std::string::npos ? "" : target.substr(0, colon);
  const std::string port = colon == std::string::npos ? "" : target.substr(colon + 1);
  int number = 0;
  const bool portOk = !port.empty() && port.size() <= 5 &&
                      port.find_first_not_of("0123456789") == std::string::npos &&
                      absl::SimpleAtoi(port, &number) && number >= 1 && number <= 65535;
  const bool bracketed = host.size() > 2 && host.front() == '[' && host.back() == ']';
  const bool hostOk =
      !host.empty() && (bracketed || host.find_first_of(":[]/ ") == std::string::npos);
  if (portOk && hostOk) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(
      "\"", target, "\" is not HOST:PORT (a port from 1 to 65535, an IPv6 host in brackets) ",
      "nor a gRPC target URI (dns:, unix:, ipv4:, ipv6:)"));
}

absl::Status NameUploadedFiles(const absl::Status& status, const UploadReport& uploads) {
  if (status.ok() || uploads.rewrites.empty()) return status;
  for (const UploadReport::Unreadable& u : uploads.unreadable) {
    const size_t at = status.message().find(u.serverField);
    if (at != std::string::npos && status.message().find(u.serverTail, at) != std::string::npos)
      return absl::Status(status.code(), u.localMessage);
  }
  std::string message(status.message());
  for (const UploadReport::Rewrite& r : uploads.rewrites) {
    // "scene.meshes[0].file" -> "scene.meshes[0].blob" is the field the server names.
    const std::string field = r.fieldPath.substr(0, r.fieldPath.rfind('.'));
    message =
        absl::StrReplaceAll(message, {{field + ".blob:", r.fieldPath + ":"},
                                      {"\"blob " + r.hash + "\"", "\"" + r.relativePath + "\""}});
  }
  return absl::Status(status.code(), message);
}

absl::StatusOr<v1::BakeJob> Client::CreateJob(const v1::JobSpec& job, const std::string& requestId,
                                              bool skipCache, int maxAttempts) {
  v1::CreateBakeJobRequest request;
  *request.mutable_job() = job;
  request.set_request_id(requestId);
  request.set_skip_cache(skipCache);
  for (int attempt = 1;; ++attempt) {
    v1::BakeJob created;
    auto context = Context();
    grpc::Status status = jobs_->CreateBakeJob(context.get(), request, &created);
    if (status.ok()) return created;
    if (status.error_code() != grpc::StatusCode::RESOURCE_EXHAUSTED || attempt >= maxAttempts)
      return FromGrpc(status);
    // A full queue comes with the server's retry delay; without one the transport refused the
    // request itself (larger than the server's message limit), which a retry cannot cure.
    std::optional<int64_t> retryMs;
    for (const auto& [key, value] : context->GetServerTrailingMetadata()) {
      int64_t ms = 0;
      if (key == "retry-after-ms" &&
          absl::SimpleAtoi(absl::string_view(value.data(), value.size()), &ms))
        retryMs = ms;
    }
    if (!retryMs) return FromGrpc(status);
    retryMs = std::clamp<int64_t>(*retryMs, 100, 60000);
    Logger("client")->info("{}; retrying in {} ms", status.error_message(), *retryMs);
    std::this_thread::sleep_for(std::chrono::milliseconds(*retryMs));
  }
}

absl::StatusOr<v1::BakeJob> Client::GetJob(const std::string& name) {
  v1::GetBakeJobRequest request;
  request.set_name(name);
  request.set_view(v1::BASIC);
  v1::BakeJob job;
  auto context = Context();
  PB_RETURN_IF_ERROR(FromGrpc(jobs_->GetBakeJob(context.get(), request, &job)));
  return job;
}

absl::StatusOr<v1::ListBakeJobsResponse> Client::ListJobs(int pageSize,
                                                          const std::string& pageToken) {
  v1::ListBakeJobsRequest request;
  request.set_page_size(pageSize);
  request.set_page_token(pageToken);
  v1::ListBakeJobsResponse response;
  auto context = Context();
  PB_RETURN_IF_ERROR(FromGrpc(jobs_->ListBakeJobs(context.get(), request, &response)));
  return response;
}

absl::StatusOr<v1::BakeJob> Client::CancelJob(const std::string& name) {
  v1::CancelBakeJobRequest request;
  request.set_name(name);
  v1::BakeJob job;
  auto context = Context();
  PB_RETURN_IF_ERROR(FromGrpc(jobs_->CancelBakeJob(context.get(), request, &job)));
  return job;
}

absl::Status Client::DeleteJob(const std::string& name) {
  v1::DeleteBakeJobRequest request;
  request.set_name(name);
  google::protobuf::Empty empty;
  auto context = Context();
  return FromGrpc(jobs_->DeleteBakeJob(context.get(), request, &empty));
}

absl::StatusOr<v1::BakeJob> Client::Watch(const std::string& name,
                                          const std::function<void(const v1::BakeJob&)>& onUpdate,
                                          std::chrono::seconds reconnectFor) {
  // Start of the current run of failed attempts (time_point{} while connected).
  std::chrono::steady_clock::time_point brokenSince{};
  while (true) {
    v1::WatchBakeJobRequest request;
    request.set_name(name);
    auto context = Context(std::nullopt);
    auto reader = jobs_->WatchBakeJob(context.get(), request);
    v1::BakeJob job, last;
    bool any = false;
    while (reader->Read(&job)) {
      any = true;
      brokenSince = {};
      onUpdate(job);
      last = job;
    }
    grpc::Status status = reader->Finish();
    if (status.ok() && any && runtime::IsFinal(last.state())) return last;
    if (status.ok()) status = {grpc::StatusCode::UNAVAILABLE, "the watch ended early"};
    if (status.error_code() != grpc::StatusCode::UNAVAILABLE) return FromGrpc(status);
    // The server restarts (draining or gone): wait for it, within reconnectFor.
    auto now = std::chrono::steady_clock::now();
    if (brokenSince == std::chrono::steady_clock::time_point{}) brokenSince = now;
    if (now - brokenSince >= reconnectFor) return FromGrpc(status);
    Logger("client")->info("{}: {}; reconnecting", name, status.error_message());
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    channel_->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(5));
  }
}

std::filesystem::path Client::PartialPath(const std::filesystem::path& out,
                                          const v1::Digest& digest) {
  std::filesystem::path part = out;
  // (StrCat, not "." + ...: GCC 12 warns falsely there, -Wrestrict.)
  part += absl::StrCat(".", digest.hash().substr(0, 12), ".part");
  return part;
}

absl::Status Client::FetchBlob(const v1::Digest& digest, const std::filesystem::path& out,
                               const std::function<void(int64_t, int64_t)>& onBytes) {
  const std::filesystem::path part = PartialPath(out, digest);
  const int lockFd = ::open(part.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lockFd < 0) {
    return absl::InternalError(
        absl::StrCat(part.string(), ": cannot write: ", std::strerror(errno)));
  }
  absl::Cleanup unlock = [lockFd] { ::close(lockFd); };
  if (::flock(lockFd, LOCK_EX | LOCK_NB) != 0) {
    return absl::AbortedError(absl::StrCat("another fetch is downloading to ", out.string(), " (",
                                           part.string(), " is locked)"));
  }
  std::error_code ec;
  int64_t have =
      std::filesystem::exists(part, ec) ? int64_t(std::filesystem::file_size(part, ec)) : 0;
  if (ec || have > digest.size_bytes()) {
    // Emptied in place, not removed: the lock is on this file.
    if (::ftruncate(lockFd, 0) != 0) {
      return absl::InternalError(
          absl::StrCat(part.string(), ": cannot write: ", std::strerror(errno)));
    }
    have = 0;
  }
  if (have < digest.size_bytes()) {
    std::ofstream file(part, std::ios::binary | std::ios::app);
    if (!file) {
      return absl::InternalError(
          absl::StrCat(part.string(), ": cannot write: ", std::strerror(errno)));
    }
    v1::ReadBlobRequest request;
    *request.mutable_digest() = digest;
    request.set_read_offset(have);
    auto context = Context(std::nullopt);
    auto reader = content_->ReadBlob(context.get(), request);
    v1::ReadBlobResponse chunk;
    // A write that fails (a full disk) ends the download at once, with the system's reason; the
    // bytes written so far stay for the next fetch.
    auto writeFailed = [&](int error) {
      return absl::InternalError(absl::StrCat(
          part.string(), ": write failed: ", error ? std::strerror(error) : "unknown error",
          "; run fetch again to continue"));
    };
    while (reader->Read(&chunk)) {
      errno = 0;
      if (!file.write(chunk.data().data(), std::streamsize(chunk.data().size())).flush()) {
        const int error = errno;
        context->TryCancel();
        reader->Finish();
        return writeFailed(error);
      }
      have += int64_t(chunk.data().size());
      if (onBytes) onBytes(have, digest.size_bytes());
    }
    errno = 0;
    file.close();
    const int closeError = errno;
    if (absl::Status finished = FromGrpc(reader->Finish()); !finished.ok()) {
      // Keep what arrived for a resumed fetch, but no empty file for a download that never began.
      if (have == 0) std::filesystem::remove(part, ec);
      return finished;
    }
    if (!file) return writeFailed(closeError);
  }
  if (have != digest.size_bytes())
    return absl::DataLossError(absl::StrCat("received ", have, " of ", digest.size_bytes(),
                                            " bytes; run fetch again to continue"));
  PB_ASSIGN_OR_RETURN(std::string hash, runtime::Sha256OfFile(part));
  if (hash != digest.hash()) {
    std::filesystem::remove(part, ec);
    return absl::DataLossError(absl::StrCat(
        "the download hashes to ", hash, ", not ", digest.hash(),
        "; removed, run fetch again (if it happens again, the server's copy is damaged)"));
  }
  std::filesystem::rename(part, out, ec);
  if (ec) return absl::InternalError(absl::StrCat(out.string(), ": cannot write: ", ec.message()));
  return absl::OkStatus();
}

}  // namespace probebake::client
