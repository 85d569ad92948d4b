#include "server/services.h"

#include <mutex>
#include <optional>

#include "absl/strings/str_cat.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/base/version.h"
#include "runtime/job_state.h"
#include "server/blob_store.h"
#include "server/job_manager.h"

namespace probebake::server {

namespace {

constexpr int kMaxFindMissingDigests = 10000;

grpc::ServerUnaryReactor* Done(grpc::CallbackServerContext* context, const grpc::Status& status) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(status);
  return reactor;
}

grpc::ServerUnaryReactor* Done(grpc::CallbackServerContext* context, const absl::Status& status) {
  return Done(context, ToGrpc(status));
}

// Counts a unary call for the duration of its (synchronous) handler.
class CallScope {
 public:
  explicit CallScope(CallCounter& calls) : calls_(calls) { calls_.Enter(); }
  ~CallScope() { calls_.Leave(); }
  CallScope(const CallScope&) = delete;
  CallScope& operator=(const CallScope&) = delete;

 private:
  CallCounter& calls_;
};

}  // namespace

grpc::Status ToGrpc(const absl::Status& status) {
  if (status.ok()) return grpc::Status::OK;
  return {static_cast<grpc::StatusCode>(status.code()), std::string(status.message())};
}

// ---- Capabilities ----

CapabilitiesService::CapabilitiesService(std::shared_ptr<const TokenAuth> auth,
                                         std::shared_ptr<CallCounter> calls, const JobManager* jobs,
                                         const BlobStore* blobs, ServiceLimits limits)
    : auth_(std::move(auth)), calls_(std::move(calls)) {
  const JobManagerConfig& config = jobs->config();
  capabilities_.set_server_version(kVersion);
  capabilities_.set_baker_version(kBakerVersion);
  capabilities_.set_digest_function("SHA256");
  capabilities_.set_max_blob_bytes(blobs->maxBlobBytes());
  capabilities_.set_chunk_bytes(limits.chunkBytes);
  capabilities_.set_max_message_bytes(limits.maxMessageBytes);
  v1::JobLimits* l = capabilities_.mutable_job_limits();
  l->set_max_probes(config.limits.maxProbes);
  l->set_max_triangles(config.limits.maxTriangles);
  l->set_max_samples_per_probe(config.limits.maxSamplesPerProbe);
  l->set_max_sh_order(config.limits.maxShOrder);
  l->set_max_depth(config.limits.maxDepth);
  l->set_max_lights(config.limits.maxLights);
  l->set_max_asset_bytes(config.limits.maxAssetBytes);
  l->set_max_environment_pixels(config.limits.maxEnvironmentPixels);
  l->set_max_texture_pixels(config.limits.maxTexturePixels);
  capabilities_.set_max_queued_jobs(config.maxQueuedJobs);
  capabilities_.set_max_concurrent_jobs(config.maxConcurrentJobs);
  capabilities_.set_threads_per_job(config.threadsPerJob);
  capabilities_.set_default_page_size(config.defaultPageSize);
  capabilities_.set_max_page_size(config.maxPageSize);
}

grpc::ServerUnaryReactor* CapabilitiesService::GetCapabilities(
    grpc::CallbackServerContext* context, const v1::GetCapabilitiesRequest* /*request*/,
    v1::ServerCapabilities* response) {
  CallScope scope(*calls_);
  if (grpc::Status auth = auth_->Check(*context); !auth.ok()) return Done(context, auth);
  *response = capabilities_;
  return Done(context, grpc::Status::OK);
}

// ---- ContentStorage ----

ContentStorageService::ContentStorageService(std::shared_ptr<const TokenAuth> auth,
                                             std::shared_ptr<CallCounter> calls, BlobStore* blobs,
                                             ServiceLimits limits, PathRedactor redact)
    : auth_(std::move(auth)),
      calls_(std::move(calls)),
      blobs_(blobs),
      limits_(limits),
      redact_(std::move(redact)) {}

grpc::ServerUnaryReactor* ContentStorageService::FindMissingBlobs(
    grpc::CallbackServerContext* context, const v1::FindMissingBlobsRequest* request,
    v1::FindMissingBlobsResponse* response) {
  CallScope scope(*calls_);
  if (grpc::Status auth = auth_->Check(*context); !auth.ok()) return Done(context, auth);
  if (request->blob_digests_size() > kMaxFindMissingDigests)
    return Done(context, FieldError("blobDigests", absl::StrCat("at most ", kMaxFindMissingDigests,
                                                                " digests per request")));
  std::vector<v1::Digest> digests;
  for (int i = 0; i < request->blob_digests_size(); ++i) {
    absl::Status valid =
        ValidateDigest(request->blob_digests(i), absl::StrCat("blobDigests[", i, "]"));
    if (!valid.ok()) return Done(context, valid);
    digests.push_back(request->blob_digests(i));
  }
  for (v1::Digest& missing : blobs_->FindMissing(digests))
    *response->add_missing_blob_digests() = std::move(missing);
  return Done(context, grpc::Status::OK);
}

grpc::ServerUnaryReactor* ContentStorageService::QueryWriteStatus(
    grpc::CallbackServerContext* context, const v1::QueryWriteStatusRequest* request,
    v1::QueryWriteStatusResponse* response) {
  CallScope scope(*calls_);
  if (grpc::Status auth = auth_->Check(*context); !auth.ok()) return Done(context, auth);
  if (absl::Status valid = ValidateDigest(request->digest(), "digest"); !valid.ok())
    return Done(context, valid);
  bool complete = false;
  absl::StatusOr<int64_t> committed = blobs_->CommittedSize(request->digest(), &complete);
  if (!committed.ok()) {
    Logger("blobs")->warn("QueryWriteStatus {}: {}", DigestString(request->digest()),
                          std::string(committed.status().message()));
    return Done(context, redact_(committed.status()));
  }
  response->set_committed_size(*committed);
  response->set_complete(complete);
  return Done(context, grpc::Status::OK);
}

namespace {

// WriteBlob: one upload per stream; chunks are appended as they arrive.
class WriteBlobReactor final : public grpc::ServerReadReactor<v1::WriteBlobRequest> {
 public:
  WriteBlobReactor(const TokenAuth& auth, std::shared_ptr<CallCounter> calls,
                   grpc::CallbackServerContext* context, BlobStore* blobs,
                   const PathRedactor& redact, v1::WriteBlobResponse* response)
      : calls_(std::move(calls)), blobs_(blobs), redact_(redact), response_(response) {
    calls_->Enter();
    if (grpc::Status status = auth.Check(*context); !status.ok()) {
      Finish(status);
      return;
    }
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {
      // The client closed the stream (or the call broke) before finishWrite.
      if (!upload_) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT, "digest: no WriteBlobRequest received"});
        return;
      }
      int64_t committed = upload_->committedSize();
      upload_.reset();  // keeps the bytes for resumption
      Finish({grpc::StatusCode::INVALID_ARGUMENT,
              absl::StrCat("finishWrite: the stream ended without finishWrite; ", committed,
                           " bytes are kept (resume at writeOffset ", committed, ")")});
      return;
    }
    absl::Status status = Handle();
    if (!status.ok()) {
      if (!absl::IsInvalidArgument(status) && !absl::IsAborted(status))
        Logger("blobs")->warn("WriteBlob {}: {}", DigestString(digest_),
                              std::string(status.message()));
      // A refused upload is discarded (service.proto), but for bytes an earlier stream left for
      // resuming: a client that resumes at the wrong offset asks QueryWriteStatus and retries.
      if (upload_ && absl::IsInvalidArgument(status) && !keepForResume_) upload_->Discard();
      upload_.reset();
      Finish(ToGrpc(redact_(status)));
      return;
    }
    if (finished_) {
      Finish(grpc::Status::OK);
      return;
    }
    StartRead(&request_);
  }

  void OnDone() override {
    calls_->Leave();
    delete this;
  }

 private:
  absl::Status Handle() {
    if (!upload_) {
      if (!request_.has_digest())
        return FieldError("digest", "required in the first WriteBlobRequest");
      digest_ = request_.digest();
      PB_RETURN_IF_ERROR(ValidateDigest(digest_, "digest"));
      if (blobs_->Touch(digest_)) {
        response_->set_committed_size(digest_.size_bytes());
        response_->set_already_present(true);
        finished_ = true;
        return absl::OkStatus();
      }
      PB_ASSIGN_OR_RETURN(upload_, blobs_->BeginWrite(digest_));
      heldAtStart_ = upload_->committedSize();
    } else if (request_.has_digest() && (request_.digest().hash() != digest_.hash() ||
                                         request_.digest().size_bytes() != digest_.size_bytes())) {
      return FieldError("digest", "differs from the first message's digest");
    }
    keepForResume_ = request_.write_offset() != upload_->committedSize() && heldAtStart_ > 0;
    PB_RETURN_IF_ERROR(upload_->Append(request_.write_offset(), request_.data()));
    if (request_.finish_write()) {
      PB_RETURN_IF_ERROR(upload_->Commit());
      Logger("blobs")->info("stored blob {}", DigestString(digest_));
      response_->set_committed_size(digest_.size_bytes());
      upload_.reset();
      finished_ = true;
    }
    return absl::OkStatus();
  }

  std::shared_ptr<CallCounter> calls_;
  BlobStore* blobs_;
  const PathRedactor& redact_;
  v1::WriteBlobResponse* response_;
  v1::WriteBlobRequest request_;
  v1::Digest digest_;
  std::unique_ptr<BlobUpload> upload_;
  bool finished_ = false;
  int64_t heldAtStart_ = 0;     // bytes earlier streams left, which this one resumes
  bool keepForResume_ = false;  // the refusal is a wrong offset on such bytes
};

// ReadBlob: streams [offset, end) in chunks, one write at a time.
class ReadBlobReactor final : public grpc::ServerWriteReactor<v1::ReadBlobResponse> {
 public:
  ReadBlobReactor(const TokenAuth& auth, std::shared_ptr<CallCounter> calls,
                  grpc::CallbackServerContext* context, const BlobStore* blobs,
                  const PathRedactor& redact, const v1::ReadBlobRequest& request,
                  int64_t chunkBytes)
      : calls_(std::move(calls)), redact_(redact), chunkBytes_(chunkBytes) {
    calls_->Enter();
    grpc::Status status = auth.Check(*context);
    if (status.ok()) status = ToGrpc(redact_(Open(blobs, request)));
    if (!status.ok()) {
      Finish(status);
      return;
    }
    NextWrite();
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      Finish({grpc::StatusCode::CANCELLED, "the client went away"});
      return;
    }
    NextWrite();
  }

  void OnDone() override {
    calls_->Leave();
    delete this;
  }

 private:
  absl::Status Open(const BlobStore* blobs, const v1::ReadBlobRequest& request) {
    PB_RETURN_IF_ERROR(ValidateDigest(request.digest(), "digest"));
    if (request.read_offset() < 0) return FieldError("readOffset", "must be >= 0");
    if (request.read_limit() < 0) return FieldError("readLimit", "must be >= 0");
    PB_ASSIGN_OR_RETURN(reader_, blobs->OpenRead(request.digest()));
    if (request.read_offset() > reader_->size())
      return absl::OutOfRangeError(absl::StrCat("readOffset: ", request.read_offset(),
                                                " is past the end of the blob (", reader_->size(),
                                                " bytes)"));
    position_ = request.read_offset();
    end_ = reader_->size();
    if (request.read_limit() > 0) end_ = std::min(end_, position_ + request.read_limit());
    return absl::OkStatus();
  }

  void NextWrite() {
    if (position_ >= end_) {
      Finish(grpc::Status::OK);
      return;
    }
    absl::Status read = reader_->ReadAt(position_, std::min(chunkBytes_, end_ - position_),
                                        response_.mutable_data());
    if (!read.ok()) {
      Logger("blobs")->error("ReadBlob: {}", std::string(read.message()));
      Finish(ToGrpc(redact_(read)));
      return;
    }
    position_ += int64_t(response_.data().size());
    StartWrite(&response_);
  }

  std::shared_ptr<CallCounter> calls_;
  const PathRedactor& redact_;
  int64_t chunkBytes_;
  std::unique_ptr<BlobReader> reader_;
  int64_t position_ = 0, end_ = 0;
  v1::ReadBlobResponse response_;
};

}  // namespace

grpc::ServerReadReactor<v1::WriteBlobRequest>* ContentStorageService::WriteBlob(
    grpc::CallbackServerContext* context, v1::WriteBlobResponse* response) {
  return new WriteBlobReactor(*auth_, calls_, context, blobs_, redact_, response);
}

grpc::ServerWriteReactor<v1::ReadBlobResponse>* ContentStorageService::ReadBlob(
    grpc::CallbackServerContext* context, const v1::ReadBlobRequest* request) {
  return new ReadBlobReactor(*auth_, calls_, context, blobs_, redact_, *request,
                             limits_.chunkBytes);
}

// ---- BakeJobs ----

namespace {

// The client's mistakes at info; the server's own trouble (a full disk, a broken store) at warn
// or error, for the operator to see.
spdlog::level::level_enum RefusalLevel(absl::StatusCode code) {
  switch (code) {
    case absl::StatusCode::kResourceExhausted:
    case absl::StatusCode::kUnavailable:
      return spdlog::level::warn;
    case absl::StatusCode::kInternal:
    case absl::StatusCode::kDataLoss:
    case absl::StatusCode::kUnknown:
      return spdlog::level::err;
    default:
      return spdlog::level::info;
  }
}

}  // namespace

BakeJobsService::BakeJobsService(std::shared_ptr<const TokenAuth> auth,
                                 std::shared_ptr<CallCounter> calls, JobManager* jobs)
    : auth_(std::move(auth)),
      calls_(std::move(calls)),
      jobs_(jobs),
      redact_(jobs->config().dataDir) {}

grpc::ServerUnaryReactor* BakeJobsService::CreateBakeJob(grpc::CallbackServerContext* context,
                                                         const v1::CreateBakeJobRequest* request,
                                                         v1::BakeJob* response) {
  CallScope scope(*calls_);
  if (grpc::Status auth = auth_->Check(*context); !auth.ok()) return Done(context, auth);
  absl::StatusOr<v1::BakeJob> job = jobs_->CreateJob(*request);
  if (!job.ok()) {
    if (auto retry = job.status().GetPayload(kRetryAfterPayload))
      context->AddTrailingMetadata("retry-after-ms", std::string(*retry));
    const absl::StatusCode code = job.status().code();
    Logger("server")->log(RefusalLevel(code), "CreateBakeJob refused ({}): {}",
                          absl::StatusCodeToString(code), std::string(job.status().message()));
    return Done(context, redact_(job.status()));
  }
  *response = std::move(*job);
  return Done(context, grpc::Status::OK);
}

grpc::ServerUnaryReactor* BakeJobsService::GetBakeJob(grpc::CallbackServerContext* context,
                                                      const v1::GetBakeJobRequest* request,
                                                      v1::BakeJob* response) {
  CallScope scope(*calls_);
  if (grpc::Status auth = auth_->Check(*context); !auth.ok()) return Done(context, auth);
  absl::StatusOr<v1::BakeJob> job =
      jobs_->GetJob(request->name(),
                    request->view() == v1::BAKE_JOB_VIEW_UNSPECIFIED ? v1::FULL : request->view());
  if (!job.ok()) return Done(context, redact_(job.status()));
  *response = std::move(*job);
  return Done(context, grpc::Status::OK);
}

grpc::ServerUnaryReactor* BakeJobsService::ListBakeJobs(grpc::CallbackServerContext* context,
                                                        const v1::ListBakeJobsRequest* request,
                                                        v1::ListBakeJobsResponse* response) {
  CallScope scope(*calls_);
  if (grpc::Status auth = auth_->Check(*context); !auth.ok()) return Done(context, auth);
  absl::StatusOr<v1::ListBakeJobsResponse> page = jobs_->ListJobs(*request);
  if (!page.ok()) return Done(context, redact_(page.status()));
  *response = std::move(*page);
  return Done(context, grpc::Status::OK);
}

grpc::ServerUnaryReactor* BakeJobsService::CancelBakeJob(grpc::CallbackServerContext* context,
                                                         const v1::CancelBakeJobRequest* request,
                                                         v1::BakeJob* response) {
  CallScope scope(*calls_);
  if (grpc::Status auth = auth_->Check(*context); !auth.ok()) return Done(context, auth);
  absl::StatusOr<v1::BakeJob> job = jobs_->CancelJob(request->name());
  if (!job.ok()) return Done(context, redact_(job.status()));
  *response = std::move(*job);
  return Done(context, grpc::Status::OK);
}

grpc::ServerUnaryReactor* BakeJobsService::DeleteBakeJob(grpc::CallbackServerContext* context,
                                                         const v1::DeleteBakeJobRequest* request,
                                                         google::protobuf::Empty* /*response*/) {
  CallScope scope(*calls_);
  if (grpc::Status auth = auth_->Check(*context); !auth.ok()) return Done(context, auth);
  return Done(context, redact_(jobs_->DeleteJob(request->name())));
}

namespace {

class WatchReactor;

// The state of one WatchBakeJob stream, shared by the reactor and the JobManager's subscriber
// list. All of it lives here rather than in the reactor because gRPC may run reactions (even
// OnDone, which deletes the reactor) inline inside StartWrite or Finish: the code that called
// them then touches only this object, which the caller keeps alive.
//
// At most one write is in flight; updates arriving meanwhile replace each other (a slow client
// sees the latest state, never a backlog). A final state is written with the status, in one go.
class WatchStream final : public JobSubscriber {
 public:
  WatchStream(grpc::ServerWriteReactor<v1::BakeJob>* reactor, std::optional<v1::JobSpec> spec)
      : reactor_(reactor), spec_(std::move(spec)) {}

  void OnJobUpdate(const v1::BakeJob& job) override {
    std::lock_guard lock(mutex_);
    if (finishing_ || cancelled_ || !reactor_) return;
    pending_ = job;
    if (spec_) *pending_->mutable_job() = *spec_;
    if (!writing_) WriteNextLocked();
  }

  void OnJobGone(const absl::Status& status) override { End(ToGrpc(status)); }

  bool Detached() const override {
    std::lock_guard lock(mutex_);
    return finishing_ || cancelled_ || !reactor_;
  }

  void End(const grpc::Status& status) {
    std::lock_guard lock(mutex_);
    if (finishing_ || !reactor_) return;
    if (writing_) {
      endStatus_ = status;
      return;
    }
    finishing_ = true;
    reactor_->Finish(status);
  }

  void WriteDone(bool ok) {
    std::lock_guard lock(mutex_);
    writing_ = false;
    if (finishing_ || !reactor_) return;
    if (!ok || cancelled_) {
      finishing_ = true;
      reactor_->Finish({grpc::StatusCode::CANCELLED, "the client went away"});
      return;
    }
    if (endStatus_) {
      finishing_ = true;
      reactor_->Finish(*endStatus_);
      return;
    }
    if (pending_) WriteNextLocked();
  }

  // From OnCancel. gRPC runs OnCancel and OnWriteDone on its executor in no set order, and a
  // write that reached the client before it cancelled completes with ok = true: a write in flight
  // need not report the cancel, so WriteDone finishes the call when it sees `cancelled_`.
  void Cancelled() {
    std::lock_guard lock(mutex_);
    if (finishing_ || !reactor_) return;
    if (writing_) {
      cancelled_ = true;
      return;
    }
    finishing_ = true;
    reactor_->Finish({grpc::StatusCode::CANCELLED, "the client went away"});
  }

  void Detach() {
    std::lock_guard lock(mutex_);
    reactor_ = nullptr;
  }

 private:
  void WriteNextLocked() {
    current_ = std::move(*pending_);
    pending_.reset();
    writing_ = true;
    if (runtime::IsFinal(current_.state())) {
      finishing_ = true;
      reactor_->StartWriteAndFinish(&current_, grpc::WriteOptions(), grpc::Status::OK);
    } else {
      reactor_->StartWrite(&current_);
    }
  }

  // Recursive: a reaction run inline (WriteDone inside StartWrite) re-enters on this thread.
  mutable std::recursive_mutex mutex_;
  grpc::ServerWriteReactor<v1::BakeJob>* reactor_;  // null once the call is done
  std::optional<v1::JobSpec> spec_;                 // FULL view: attached to every message
  v1::BakeJob current_;                             // the message being written
  std::optional<v1::BakeJob> pending_;              // the next one
  std::optional<grpc::Status> endStatus_;           // finish once the current write is done
  bool writing_ = false;
  bool finishing_ = false;
  bool cancelled_ = false;  // the client went away while a write was in flight
};

class WatchReactor final : public grpc::ServerWriteReactor<v1::BakeJob> {
 public:
  WatchReactor(const TokenAuth& auth, grpc::CallbackServerContext* context, JobManager* jobs,
               const v1::WatchBakeJobRequest& request) {
    if (grpc::Status status = auth.Check(*context); !status.ok()) {
      Finish(status);
      return;
    }
    std::optional<v1::JobSpec> spec;
    if (request.view() == v1::FULL) {
      absl::StatusOr<v1::BakeJob> full = jobs->GetJob(request.name(), v1::FULL);
      if (!full.ok()) {
        Finish(ToGrpc(full.status()));
        return;
      }
      spec = full->job();
    }
    stream_ = std::make_shared<WatchStream>(this, std::move(spec));
    if (absl::Status subscribed = jobs->Subscribe(request.name(), stream_); !subscribed.ok()) {
      stream_->Detach();
      Finish(ToGrpc(subscribed));
    }
  }

  void OnWriteDone(bool ok) override {
    std::shared_ptr<WatchStream> stream = stream_;
    stream->WriteDone(ok);
  }
  void OnCancel() override {
    if (std::shared_ptr<WatchStream> stream = stream_) stream->Cancelled();
  }
  void OnDone() override {
    if (stream_) stream_->Detach();
    delete this;
  }

 private:
  std::shared_ptr<WatchStream> stream_;
};

}  // namespace

grpc::ServerWriteReactor<v1::BakeJob>* BakeJobsService::WatchBakeJob(
    grpc::CallbackServerContext* context, const v1::WatchBakeJobRequest* request) {
  return new WatchReactor(*auth_, context, jobs_, *request);
}

}  // namespace probebake::server
