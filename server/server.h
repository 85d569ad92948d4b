// probebake-server assembled: data folder (lock, blob store, job store), job manager and the gRPC
// server with health checking and reflection. main.cpp adds flags and signals; tests run it in
// process with their own baker.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "probebake/job/limits.h"
#include "server/bake_backend.h"
#include "server/garbage_collector.h"

namespace grpc {
class Server;
}

namespace probebake::server {

class BlobStore;
class DiskReserve;
class JobStore;
class JobManager;
class TokenAuth;
class CapabilitiesService;
class ContentStorageService;
class BakeJobsService;
class CallCounter;

struct ServerOptions {
  // host:port to listen on; port 0 picks a free one (see ProbebakeServer::port()).
  std::string listen = "127.0.0.1:50051";
  std::filesystem::path dataDir;
  int threadsPerJob = 0;  // 0: every hardware thread
  int maxConcurrentJobs = 1;
  int maxQueuedJobs = 64;
  std::filesystem::path tokenFile;        // empty: no authentication
  std::filesystem::path tlsCert, tlsKey;  // both or neither (PEM)
  JobLimits limits;
  int64_t maxBlobBytes = int64_t(4) << 30;
  double checkpointIntervalSeconds = 10;
  double progressIntervalSeconds = 0.25;
  int64_t chunkBytes = int64_t(1) << 20;
  int maxMessageBytes = 4 << 20;
  GcConfig gc;  // what the data folder keeps, and how often it is collected
  // Disk space held in DATA/reserve for the job store on a full disk (disk_reserve.h); 0: none.
  int64_t diskReserveBytes = int64_t(16) << 20;
};

// Makes the backend once the blob store and the job store are open (ProductionBackend or
// SlurmBackend in the real server). Errors stop the server's start.
using BackendFactory = std::function<absl::StatusOr<BakeBackend>(const BackendContext&)>;

class ProbebakeServer {
 public:
  // Opens DATA (refusing a folder another server holds), recovers jobs and starts serving.
  static absl::StatusOr<std::unique_ptr<ProbebakeServer>> Start(const ServerOptions& options,
                                                                const BackendFactory& backend);
  ~ProbebakeServer();  // Shutdown()

  int port() const { return port_; }
  // The job manager (for tests and diagnostics).
  JobManager& jobs() { return *jobs_; }
  // The data folder's garbage collector (for tests and diagnostics).
  GarbageCollector& gc() { return *gc_; }
  // Graceful stop: health NOT_SERVING, new jobs UNAVAILABLE, running jobs cancelled and requeued
  // with their checkpoints, watchers told UNAVAILABLE, in-flight calls given a moment, the job
  // store closed. Idempotent.
  void Shutdown();

 private:
  ProbebakeServer() = default;

  int lockFd_ = -1;
  int port_ = 0;
  std::unique_ptr<BlobStore> blobs_;
  std::unique_ptr<JobStore> store_;
  std::unique_ptr<JobManager> jobs_;
  std::unique_ptr<GarbageCollector> gc_;
  std::unique_ptr<DiskReserve> reserve_;
  std::shared_ptr<const TokenAuth> auth_;
  std::shared_ptr<CallCounter> calls_;
  std::unique_ptr<CapabilitiesService> capabilities_;
  std::unique_ptr<ContentStorageService> content_;
  std::unique_ptr<BakeJobsService> bakeJobs_;
  std::unique_ptr<grpc::Server> server_;
  bool shutDown_ = false;
};

}  // namespace probebake::server
