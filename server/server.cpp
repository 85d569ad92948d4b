#include "server/server.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>

#include "absl/strings/str_cat.h"
#include "probebake/base/io_error.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "runtime/files.h"
#include "server/auth.h"
#include "server/blob_store.h"
#include "server/disk_reserve.h"
#include "server/garbage_collector.h"
#include "server/job_manager.h"
#include "server/job_store.h"
#include "server/services.h"

namespace probebake::server {

namespace {

// One server per data folder: a second one would run the same queued jobs.
absl::StatusOr<int> LockDataDir(const std::filesystem::path& dataDir) {
  std::filesystem::path lockPath = dataDir / "LOCK";
  int fd = ::open(lockPath.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return IoError(errno, lockPath.string(), "open");
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    return absl::FailedPreconditionError(
        absl::StrCat(dataDir.string(), " is in use by another probebake-server"));
  }
  return fd;
}

}  // namespace

absl::StatusOr<std::unique_ptr<ProbebakeServer>> ProbebakeServer::Start(
    const ServerOptions& options, const BackendFactory& backend) {
  if (options.dataDir.empty()) return absl::InvalidArgumentError("--data-dir is required");
  if (options.tlsCert.empty() != options.tlsKey.empty())
    return absl::InvalidArgumentError("--tls-cert and --tls-key go together");
  if (options.gc.grace < GcConfig::kMinGrace)
    return absl::InvalidArgumentError(absl::StrCat("--blob-grace-hours: at least ",
                                                   GcConfig::kMinGrace.count(), " s (",
                                                   GcConfig::kMinGrace.count() / 3600.0, " h)"));
  std::error_code ec;
  std::filesystem::create_directories(options.dataDir, ec);
  if (ec)
    return absl::InvalidArgumentError(
        absl::StrCat("--data-dir ", options.dataDir.string(), ": ", ec.message()));

  std::unique_ptr<ProbebakeServer> s(new ProbebakeServer);
  PB_ASSIGN_OR_RETURN(s->lockFd_, LockDataDir(options.dataDir));

  std::optional<std::string> token;
  if (!options.tokenFile.empty()) {
    PB_ASSIGN_OR_RETURN(token, TokenAuth::ReadTokenFile(options.tokenFile));
  }
  s->auth_ = std::make_shared<TokenAuth>(std::move(token));

  std::shared_ptr<grpc::ServerCredentials> credentials = grpc::InsecureServerCredentials();
  if (!options.tlsCert.empty()) {
    grpc::SslServerCredentialsOptions ssl;
    grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
    absl::StatusOr<std::string> key = runtime::ReadWholeFile(options.tlsKey);
    absl::StatusOr<std::string> cert = runtime::ReadWholeFile(options.tlsCert);
    if (!key.ok())
      return absl::InvalidArgumentError(
          absl::StrCat("--tls-key: ", std::string(key.status().message())));
    if (!cert.ok())
      return absl::InvalidArgumentError(
          absl::StrCat("--tls-cert: ", std::string(cert.status().message())));
    pair.private_key = std::move(*key);
    pair.cert_chain = std::move(*cert);
    ssl.pem_key_cert_pairs.push_back(std::move(pair));
    credentials = grpc::SslServerCredentials(ssl);
  }

  PB_ASSIGN_OR_RETURN(s->blobs_, BlobStore::Open(options.dataDir, options.maxBlobBytes));
  s->reserve_ =
      std::make_unique<DiskReserve>(options.dataDir / "reserve", options.diskReserveBytes);
  s->reserve_->Restore();
  absl::StatusOr<std::unique_ptr<JobStore>> store = JobStore::Open(options.dataDir / "jobs.sqlite");
  // A full disk fails the open in several ways (SQLITE_FULL, or an I/O error setting up the WAL).
  if (!store.ok() && s->reserve_->Release()) {
    store = JobStore::Open(options.dataDir / "jobs.sqlite");
    s->reserve_->Retake();
  }
  if (!store.ok()) return store.status();
  s->store_ = std::move(*store);
  // Lent to the store for one write at a time, and taken back at once (disk_reserve.h).
  s->store_->SetSpaceReclaimer([reserve = s->reserve_.get()] { return reserve->Release(); },
                               [reserve = s->reserve_.get()] { reserve->Retake(); });

  JobManagerConfig config;
  config.dataDir = options.dataDir;
  config.limits = options.limits;
  config.maxConcurrentJobs = options.maxConcurrentJobs;
  config.maxQueuedJobs = options.maxQueuedJobs;
  config.threadsPerJob = options.threadsPerJob;
  config.progressIntervalSeconds = options.progressIntervalSeconds;
  config.checkpointIntervalSeconds = options.checkpointIntervalSeconds;
  config.maxMessageBytes = options.maxMessageBytes;
  BackendContext context;
  context.blobs = s->blobs_.get();
  context.store = s->store_.get();
  context.limits = options.limits;
  PB_ASSIGN_OR_RETURN(BakeBackend made, backend(context));
  s->jobs_ =
      std::make_unique<JobManager>(config, s->blobs_.get(), s->store_.get(), std::move(made));

  ServiceLimits limits;
  limits.chunkBytes = options.chunkBytes;
  limits.maxMessageBytes = options.maxMessageBytes;
  s->calls_ = std::make_shared<CallCounter>();
  s->capabilities_ = std::make_unique<CapabilitiesService>(s->auth_, s->calls_, s->jobs_.get(),
                                                           s->blobs_.get(), limits);
  s->content_ = std::make_unique<ContentStorageService>(s->auth_, s->calls_, s->blobs_.get(),
                                                        limits, PathRedactor(options.dataDir));
  s->bakeJobs_ = std::make_unique<BakeJobsService>(s->auth_, s->calls_, s->jobs_.get());

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, credentials, &s->port_);
  builder.SetMaxReceiveMessageSize(options.maxMessageBytes);
  builder.SetMaxSendMessageSize(options.maxMessageBytes);
  builder.RegisterService(s->capabilities_.get());
  builder.RegisterService(s->content_.get());
  builder.RegisterService(s->bakeJobs_.get());
  std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> interceptors;
  interceptors.push_back(std::make_unique<AuthInterceptorFactory>(s->auth_));
  builder.experimental().SetInterceptorCreators(std::move(interceptors));

  PB_RETURN_IF_ERROR(s->jobs_->Start());
  s->server_ = builder.BuildAndStart();
  if (!s->server_ || s->port_ == 0) {
    s->jobs_->Shutdown();
    return absl::UnavailableError(absl::StrCat("cannot listen on ", options.listen));
  }
  s->gc_ = std::make_unique<GarbageCollector>(
      s->store_.get(), s->blobs_.get(),
      [jobs = s->jobs_.get()](std::filesystem::file_time_type* since) {
        return jobs->VolumesNotYetReferenced(since);
      },
      options.gc);
  s->gc_->SetAfterCollection([reserve = s->reserve_.get()] { reserve->Restore(); });
  s->gc_->Start();
  Logger("server")->info("probebake-server listening on {} (port {}), data {}, {}{}",
                         options.listen, s->port_, options.dataDir.string(),
                         s->auth_->enabled() ? "token auth" : "no auth",
                         options.tlsCert.empty() ? "" : ", TLS");
  return s;
}

ProbebakeServer::~ProbebakeServer() {
  Shutdown();
}

void ProbebakeServer::Shutdown() {
  if (shutDown_) return;
  shutDown_ = true;
  auto start = std::chrono::steady_clock::now();
  if (server_) {
    if (auto* health = server_->GetHealthCheckService()) health->SetServingStatus(false);
  }
  Logger("server")->info("draining: health NOT_SERVING, new jobs refused");
  if (gc_) gc_->Stop();
  if (jobs_) jobs_->Shutdown();
  if (server_) {
    // Calls in flight (uploads, downloads, a CreateBakeJob loading assets) get up to 2 s to
    // finish; then the rest are cancelled and connections closed at once. (A Shutdown deadline
    // alone would also wait that long for idle client connections.)
    auto grace = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (calls_->active() > 0 && std::chrono::steady_clock::now() < grace)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (calls_->active() > 0)
      Logger("server")->warn("cancelling {} call(s) still in flight", calls_->active());
    server_->Shutdown(std::chrono::system_clock::now());
    server_->Wait();
  }
  server_.reset();
  bakeJobs_.reset();
  content_.reset();
  capabilities_.reset();
  gc_.reset();
  jobs_.reset();
  store_.reset();  // closing checkpoints the WAL into the database file
  blobs_.reset();
  if (lockFd_ >= 0) ::close(lockFd_);
  lockFd_ = -1;
  Logger("server")->info(
      "stopped in {:.3f} s",
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

}  // namespace probebake::server
