#include "test_server.h"

#include <fstream>
#include <future>
#include <thread>

#include <grpcpp/generic/generic_stub.h>

#include "probebake/job/digest.h"
#include "probebake/job/job_json.h"
#include "server/checkpoint.h"

namespace probebake::testing {

StoreWriteLock::StoreWriteLock(const std::filesystem::path& dataDir) {
  EXPECT_EQ(sqlite3_open((dataDir / "jobs.sqlite").c_str(), &db_), SQLITE_OK);
  sqlite3_busy_timeout(db_, 10000);  // the server may be writing progress at this moment
  locked_ = sqlite3_exec(db_, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr) == SQLITE_OK;
  EXPECT_TRUE(locked_);
}

void StoreWriteLock::Release() {
  if (locked_) {
    EXPECT_EQ(sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr), SQLITE_OK);
  }
  locked_ = false;
  sqlite3_close(db_);
  db_ = nullptr;
}

void LockStoreAtVolumeWrite::Arm(TestServerOptions* options, std::filesystem::path dataDir) {
  options->volumeWriteFault = [this, dataDir = std::move(dataDir)] {
    if (!lock_) {
      lock_ = std::make_unique<StoreWriteLock>(dataDir);
      taken_.set_value();
    }
    return absl::OkStatus();
  };
}

bool LockStoreAtVolumeWrite::WaitTaken(std::chrono::seconds timeout) {
  return takenFuture_.wait_for(timeout) == std::future_status::ready;
}

void LockStoreAtVolumeWrite::Release() {
  if (lock_) lock_->Release();
}

v1::JobSpec SmallJob(int probes, uint64_t seed) {
  std::string json = R"({
    "scene": {
      "materials": [{"name": "white", "albedo": [0.5, 0.5, 0.5]}],
      "meshes": [{"name": "floor", "positions": [-5,-5,0, 5,-5,0, 5,5,0, -5,5,0],
                  "indices": [0,1,2, 0,2,3], "material": "white"}],
      "lights": [{"point": {"position": [0, 0, 3], "intensity": [10, 10, 10]}}]
    },
    "grid": {"min": [-2, 0, 1], "max": [2, 0, 1], "counts": [)" +
                     std::to_string(probes) + R"(, 1, 1], "placement": "ALL"},
    "settings": {"shOrder": 1, "samplesPerProbe": 16, "maxDepth": 2, "seed": )" +
                     std::to_string(seed) + R"(}
  })";
  auto spec = ParseJobJson(json);
  EXPECT_TRUE(spec.ok()) << spec.status();
  return spec.ok() ? *spec : v1::JobSpec();
}

void ExpectFakeVolume(const std::string& bytes, int probes, uint64_t seed) {
  TempDir scratch;
  std::filesystem::path file = scratch.path() / "volume.bin";
  std::ofstream(file, std::ios::binary) << bytes;
  auto volume = server::ReadCheckpoint(file, kFakeVolumeTag);
  ASSERT_TRUE(volume.ok()) << volume.status();
  const ProbeVolume& v = volume->volume;
  ASSERT_EQ(v.grid.ProbeCount(), probes);
  ASSERT_EQ(v.radiance.size(), 4u);
  for (int64_t p = 0; p < probes; ++p)
    for (int c = 0; c < 4; ++c)
      for (int ch = 0; ch < 3; ++ch)
        ASSERT_EQ(v.radiance[size_t(c)][size_t(3 * p + ch)], FakeProbeValue(seed, p, c, ch))
            << "probe " << p << " coefficient " << c << " channel " << ch;
}

BakeStats FakeVolumeStats(const std::string& bytes) {
  TempDir scratch;
  std::filesystem::path file = scratch.path() / "volume.bin";
  std::ofstream(file, std::ios::binary) << bytes;
  auto volume = server::ReadCheckpoint(file, kFakeVolumeTag);
  EXPECT_TRUE(volume.ok()) << volume.status();
  return volume.ok() ? volume->volume.stats : BakeStats();
}

TestServer::TestServer(TestServerOptions options, std::filesystem::path dataDir)
    : options_(std::move(options)) {
  if (dataDir.empty()) {
    ownDir_.emplace();
    dataDir_ = ownDir_->path() / "data";
  } else {
    dataDir_ = std::move(dataDir);
  }
  Start();
}

TestServer::~TestServer() {
  Stop();
}

void TestServer::Start() {
  server::ServerOptions o;
  o.listen = "127.0.0.1:0";
  o.dataDir = dataDir_;
  o.maxConcurrentJobs = options_.maxConcurrentJobs;
  o.maxQueuedJobs = options_.maxQueuedJobs;
  o.threadsPerJob = 1;
  o.limits = options_.limits;
  o.checkpointIntervalSeconds = options_.checkpointIntervalSeconds;
  o.gc.grace = options_.blobGrace;
  o.gc.interval = std::chrono::seconds(0);
  if (!options_.token.empty()) {
    o.tokenFile = dataDir_.parent_path() / "token";
    std::filesystem::create_directories(dataDir_.parent_path());
    std::ofstream(o.tokenFile) << options_.token << "\n";
  }
  stats_ = std::make_unique<FakeBakeStats>();
  auto delay = options_.probeDelay;
  FakeBakeStats* stats = stats_.get();
  auto started = server::ProbebakeServer::Start(
      o,
      [delay, stats, fault = options_.volumeWriteFault](
          const server::BackendContext& context) -> absl::StatusOr<server::BakeBackend> {
        server::BakeBackend backend = FakeBackend(context.blobs, context.limits, delay, stats);
        if (fault) {
          backend.writeVolume = [fault, write = backend.writeVolume](const std::string& path,
                                                                     const ProbeVolume& volume,
                                                                     const VolumeMetadata& meta) {
            if (absl::Status failed = fault(); !failed.ok()) return failed;
            return write(path, volume, meta);
          };
        }
        return backend;
      });
  ASSERT_TRUE(started.ok()) << started.status();
  server_ = std::move(*started);
  channel_ = grpc::CreateChannel("127.0.0.1:" + std::to_string(server_->port()),
                                 grpc::InsecureChannelCredentials());
}

void TestServer::Stop() {
  if (server_) server_->Shutdown();
  server_.reset();
}

void TestServer::Restart() {
  Stop();
  Start();
}

std::shared_ptr<grpc::Channel> TestServer::channel() {
  return channel_;
}
std::unique_ptr<v1::Capabilities::Stub> TestServer::Capabilities() {
  return v1::Capabilities::NewStub(channel_);
}
std::unique_ptr<v1::ContentStorage::Stub> TestServer::Content() {
  return v1::ContentStorage::NewStub(channel_);
}
std::unique_ptr<v1::BakeJobs::Stub> TestServer::Jobs() {
  return v1::BakeJobs::NewStub(channel_);
}

std::unique_ptr<grpc::ClientContext> TestServer::Context(bool withToken) const {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  if (withToken && !options_.token.empty())
    context->AddMetadata("authorization", "Bearer " + options_.token);
  return context;
}

v1::Digest TestServer::Upload(const std::string& data, size_t chunk) {
  v1::Digest digest = DigestOf(data);
  auto context = Context();
  v1::WriteBlobResponse response;
  auto stub = Content();
  auto writer = stub->WriteBlob(context.get(), &response);
  size_t offset = 0;
  do {
    v1::WriteBlobRequest request;
    if (offset == 0) *request.mutable_digest() = digest;
    request.set_write_offset(int64_t(offset));
    request.set_data(data.substr(offset, chunk));
    offset = std::min(data.size(), offset + chunk);
    request.set_finish_write(offset == data.size());
    if (!writer->Write(request)) break;
  } while (offset < data.size());
  writer->WritesDone();
  grpc::Status status = writer->Finish();
  EXPECT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.committed_size(), int64_t(data.size()));
  return digest;
}

std::string TestServer::Download(const v1::Digest& digest) {
  auto context = Context();
  v1::ReadBlobRequest request;
  *request.mutable_digest() = digest;
  auto stub = Content();
  auto reader = stub->ReadBlob(context.get(), request);
  std::string data;
  v1::ReadBlobResponse chunk;
  while (reader->Read(&chunk)) data += chunk.data();
  grpc::Status status = reader->Finish();
  EXPECT_TRUE(status.ok()) << status.error_message();
  return data;
}

v1::BakeJob TestServer::Create(const v1::JobSpec& spec, const std::string& requestId,
                               bool skipCache) {
  v1::CreateBakeJobRequest request;
  *request.mutable_job() = spec;
  request.set_request_id(requestId);
  request.set_skip_cache(skipCache);
  v1::BakeJob job;
  auto context = Context();
  grpc::Status status = Jobs()->CreateBakeJob(context.get(), request, &job);
  EXPECT_TRUE(status.ok()) << status.error_code() << " " << status.error_message();
  return job;
}

v1::BakeJob TestServer::WaitFinal(const std::string& name, std::vector<v1::BakeJob>* messages) {
  auto context = Context();
  v1::WatchBakeJobRequest request;
  request.set_name(name);
  auto stub = Jobs();
  auto reader = stub->WatchBakeJob(context.get(), request);
  v1::BakeJob job, last;
  while (reader->Read(&job)) {
    if (messages) messages->push_back(job);
    last = job;
  }
  grpc::Status status = reader->Finish();
  EXPECT_TRUE(status.ok()) << status.error_code() << " " << status.error_message();
  return last;
}

std::string TestServer::WaitUntilWaiting(const std::string& name) {
  for (int i = 0; i < 2000; ++i) {
    std::string waiting = Get(name).progress().waiting();
    if (!waiting.empty()) return waiting;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return "";
}

v1::BakeJob TestServer::Get(const std::string& name) {
  v1::GetBakeJobRequest request;
  request.set_name(name);
  v1::BakeJob job;
  auto context = Context();
  grpc::Status status = Jobs()->GetBakeJob(context.get(), request, &job);
  EXPECT_TRUE(status.ok()) << status.error_message();
  return job;
}

int TestServer::Health() {
  // grpc.health.v1.Health/Check with HealthCheckRequest{service: ""} (empty bytes); the
  // response's field 1 is the status enum: bytes 08 01 (SERVING) or 08 02 (NOT_SERVING).
  grpc::GenericStub stub(channel_);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  grpc::ByteBuffer request, response;
  grpc::Slice empty;
  request = grpc::ByteBuffer(&empty, 1);
  std::promise<grpc::Status> done;
  stub.UnaryCall(&context, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                 [&](grpc::Status s) { done.set_value(s); });
  grpc::Status status = done.get_future().get();
  if (!status.ok()) return -1;
  std::vector<grpc::Slice> slices;
  if (!response.Dump(&slices).ok()) return -1;
  std::string bytes;
  for (const grpc::Slice& s : slices)
    bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  if (bytes.size() == 2 && bytes[0] == 0x08) return bytes[1];
  return bytes.empty() ? 0 : -1;
}

}  // namespace probebake::testing
