// The service's request handling behind gRPC: job names, page tokens, page sizes, request ids and
// job specs as clients send them, into a job manager over a real job store and blob store (the
// fake baker stands in for the tracer). The first byte picks the call; the rest is the request
// (binary protobuf) or the job name.
#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "fake_backend.h"
#include "probebake/base/log.h"
#include "server/blob_store.h"
#include "server/job_manager.h"
#include "server/job_store.h"

namespace {

using namespace probebake;

struct Service {
  std::unique_ptr<server::BlobStore> blobs;
  std::unique_ptr<server::JobStore> store;
  std::unique_ptr<server::JobManager> jobs;
  testing::FakeBakeStats stats;

  Service() {
    SetLogLevel(spdlog::level::off);
    const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                      ("probebake-fuzz-service-" + std::to_string(getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    blobs = std::move(*server::BlobStore::Open(dir, int64_t(1) << 20));
    store = std::move(*server::JobStore::Open(dir / "jobs.sqlite"));
    server::JobManagerConfig config;
    config.dataDir = dir;
    config.maxQueuedJobs = 1 << 20;
    jobs = std::make_unique<server::JobManager>(
        config, blobs.get(), store.get(),
        testing::FakeBackend(blobs.get(), config.limits, std::chrono::microseconds(0), &stats));
    (void)jobs->Start();
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Service service;
  if (size < 1) return 0;
  const std::string rest(reinterpret_cast<const char*>(data) + 1, size - 1);
  server::JobManager& jobs = *service.jobs;
  switch (data[0] % 6) {
    case 0: {
      v1::CreateBakeJobRequest request;
      if (request.ParseFromString(rest)) (void)jobs.CreateJob(request);
      break;
    }
    case 1:
      (void)jobs.GetJob(rest, v1::FULL);
      break;
    case 2: {
      v1::ListBakeJobsRequest request;
      if (request.ParseFromString(rest)) (void)jobs.ListJobs(request);
      break;
    }
    case 3:
      (void)jobs.CancelJob(rest);
      break;
    case 4:
      (void)jobs.DeleteJob(rest);
      break;
    case 5:
      (void)jobs.GetJob(rest, v1::BASIC);
      break;
  }
  return 0;
}
