// The gRPC face of probebake.v1 (service.proto), on the callback API: unary handlers finish their
// default reactor; streams are reactor classes (WriteBlob reads chunks, ReadBlob and WatchBakeJob
// write them). Every handler checks the bearer token first, then maps absl::Status codes one to
// one onto gRPC codes.
#pragma once

#include <atomic>
#include <memory>

#include "probebake/v1/service.grpc.pb.h"
#include "server/auth.h"
#include "server/path_redactor.h"

namespace probebake::server {

class BlobStore;
class JobManager;

// Calls being served, so a draining server can give them time to finish and then close at once
// (gRPC's own Shutdown deadline would also wait for idle client connections).
class CallCounter {
 public:
  void Enter() { active_.fetch_add(1); }
  void Leave() { active_.fetch_sub(1); }
  int active() const { return active_.load(); }

 private:
  std::atomic<int> active_{0};
};

// Figures GetCapabilities reports besides the job limits.
struct ServiceLimits {
  int64_t chunkBytes = int64_t(1) << 20;
  int64_t maxMessageBytes = int64_t(4) << 20;
};

class CapabilitiesService final : public v1::Capabilities::CallbackService {
 public:
  CapabilitiesService(std::shared_ptr<const TokenAuth> auth, std::shared_ptr<CallCounter> calls,
                      const JobManager* jobs, const BlobStore* blobs, ServiceLimits limits);
  grpc::ServerUnaryReactor* GetCapabilities(grpc::CallbackServerContext* context,
                                            const v1::GetCapabilitiesRequest* request,
                                            v1::ServerCapabilities* response) override;

 private:
  std::shared_ptr<const TokenAuth> auth_;
  std::shared_ptr<CallCounter> calls_;
  v1::ServerCapabilities capabilities_;
};

class ContentStorageService final : public v1::ContentStorage::CallbackService {
 public:
  // Errors sent to clients name the data folder as DATA (`redact`).
  ContentStorageService(std::shared_ptr<const TokenAuth> auth, std::shared_ptr<CallCounter> calls,
                        BlobStore* blobs, ServiceLimits limits, PathRedactor redact);
  grpc::ServerUnaryReactor* FindMissingBlobs(grpc::CallbackServerContext* context,
                                             const v1::FindMissingBlobsRequest* request,
                                             v1::FindMissingBlobsResponse* response) override;
  grpc::ServerReadReactor<v1::WriteBlobRequest>* WriteBlob(
      grpc::CallbackServerContext* context, v1::WriteBlobResponse* response) override;
  grpc::ServerUnaryReactor* QueryWriteStatus(grpc::CallbackServerContext* context,
                                             const v1::QueryWriteStatusRequest* request,
                                             v1::QueryWriteStatusResponse* response) override;
  grpc::ServerWriteReactor<v1::ReadBlobResponse>* ReadBlob(
      grpc::CallbackServerContext* context, const v1::ReadBlobRequest* request) override;

 private:
  std::shared_ptr<const TokenAuth> auth_;
  std::shared_ptr<CallCounter> calls_;
  BlobStore* blobs_;
  ServiceLimits limits_;
  PathRedactor redact_;
};

class BakeJobsService final : public v1::BakeJobs::CallbackService {
 public:
  BakeJobsService(std::shared_ptr<const TokenAuth> auth, std::shared_ptr<CallCounter> calls,
                  JobManager* jobs);
  grpc::ServerUnaryReactor* CreateBakeJob(grpc::CallbackServerContext* context,
                                          const v1::CreateBakeJobRequest* request,
                                          v1::BakeJob* response) override;
  grpc::ServerUnaryReactor* GetBakeJob(grpc::CallbackServerContext* context,
                                       const v1::GetBakeJobRequest* request,
                                       v1::BakeJob* response) override;
  grpc::ServerUnaryReactor* ListBakeJobs(grpc::CallbackServerContext* context,
                                         const v1::ListBakeJobsRequest* request,
                                         v1::ListBakeJobsResponse* response) override;
  grpc::ServerWriteReactor<v1::BakeJob>* WatchBakeJob(
      grpc::CallbackServerContext* context, const v1::WatchBakeJobRequest* request) override;
  grpc::ServerUnaryReactor* CancelBakeJob(grpc::CallbackServerContext* context,
                                          const v1::CancelBakeJobRequest* request,
                                          v1::BakeJob* response) override;
  grpc::ServerUnaryReactor* DeleteBakeJob(grpc::CallbackServerContext* context,
                                          const v1::DeleteBakeJobRequest* request,
                                          google::protobuf::Empty* response) override;

 private:
  std::shared_ptr<const TokenAuth> auth_;
  std::shared_ptr<CallCounter> calls_;
  JobManager* jobs_;
  PathRedactor redact_;  // errors sent to clients name the data folder as DATA
};

// absl::Status -> grpc::Status (same code numbers, same message).
grpc::Status ToGrpc(const absl::Status& status);

}  // namespace probebake::server
