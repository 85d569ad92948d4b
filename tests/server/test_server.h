// Test helpers for the service: an in-process probebake server on a free loopback port with its
// own data folder and the fake baker, stubs that carry the token, and small job specs.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <string>

#include <grpcpp/grpcpp.h>
#include <sqlite3.h>

#include "fake_backend.h"
#include "probebake/v1/service.grpc.pb.h"
#include "server/server.h"
#include "temp_dir.h"

namespace probebake::testing {

// A job over an inline floor quad lit by a point light: `probes` probes along x, placement ALL.
v1::JobSpec SmallJob(int probes, uint64_t seed = 1);

// Checks that `bytes` is the volume the fake baker writes for SmallJob(probes, seed), value by
// value (bit for bit).
void ExpectFakeVolume(const std::string& bytes, int probes, uint64_t seed);

// The `stats` a volume written by the fake baker records (zeros, with a test failure, when the
// bytes are not such a volume).
BakeStats FakeVolumeStats(const std::string& bytes);

struct TestServerOptions {
  std::chrono::microseconds probeDelay{2000};
  int maxConcurrentJobs = 1;
  int maxQueuedJobs = 16;
  std::string token;  // empty: no auth
  double checkpointIntervalSeconds = 0.05;
  JobLimits limits;
  // Called before each volume write; a status other than OK fails that write with it (a full
  // disk: RESOURCE_EXHAUSTED). Unset: writes succeed.
  std::function<absl::Status()> volumeWriteFault;
  // The garbage collector's; no periodic collection (tests call server().gc().CollectNow()).
  std::chrono::seconds blobGrace{std::chrono::hours(1)};
};

// Holds the server's job store write-locked from another SQLite connection until Release: the
// server's writes wait out its 5 s busy timeout and fail, as they do on a full disk. Reads go on.
class StoreWriteLock {
 public:
  explicit StoreWriteLock(const std::filesystem::path& dataDir);
  ~StoreWriteLock() { Release(); }
  StoreWriteLock(const StoreWriteLock&) = delete;
  StoreWriteLock& operator=(const StoreWriteLock&) = delete;
  void Release();

 private:
  sqlite3* db_ = nullptr;
  bool locked_ = false;
};

// Takes a StoreWriteLock on the data folder from the job's worker just before its first volume
// write (after the bake), so the job's end meets a locked store. Arm before the server starts;
// the object must outlive the server.
class LockStoreAtVolumeWrite {
 public:
  void Arm(TestServerOptions* options, std::filesystem::path dataDir);
  // Whether the lock was taken within `timeout`.
  bool WaitTaken(std::chrono::seconds timeout);
  void Release();

 private:
  std::unique_ptr<StoreWriteLock> lock_;
  std::promise<void> taken_;
  std::future<void> takenFuture_ = taken_.get_future();
};

class TestServer {
 public:
  // Starts a server on `dataDir` (a fresh temp folder when empty).
  explicit TestServer(TestServerOptions options = {}, std::filesystem::path dataDir = {});
  ~TestServer();

  void Restart();  // graceful Shutdown, then Start on the same data folder
  void Stop();

  const std::filesystem::path& dataDir() const { return dataDir_; }
  server::ProbebakeServer& server() { return *server_; }
  FakeBakeStats& bakeStats() { return *stats_; }

  // Stubs on a fresh channel.
  std::unique_ptr<v1::Capabilities::Stub> Capabilities();
  std::unique_ptr<v1::ContentStorage::Stub> Content();
  std::unique_ptr<v1::BakeJobs::Stub> Jobs();
  std::shared_ptr<grpc::Channel> channel();

  // A client context with a 30 s deadline and, unless `withToken` is false, the token.
  std::unique_ptr<grpc::ClientContext> Context(bool withToken = true) const;

  // Uploads `data` in `chunk`-byte messages and returns its digest (fails the test on error).
  v1::Digest Upload(const std::string& data, size_t chunk = 1 << 20);
  // Reads a whole blob back.
  std::string Download(const v1::Digest& digest);

  // CreateBakeJob, expecting success.
  v1::BakeJob Create(const v1::JobSpec& spec, const std::string& requestId = "",
                     bool skipCache = false);
  // Watches until a final state; `states` gets every message's state.
  v1::BakeJob WaitFinal(const std::string& name, std::vector<v1::BakeJob>* messages = nullptr);
  v1::BakeJob Get(const std::string& name);
  // Polls the job until its progress.waiting is set (up to 20 s) and returns it ("" on timeout).
  std::string WaitUntilWaiting(const std::string& name);

  // grpc.health.v1 Check of the whole server: 1 SERVING, 2 NOT_SERVING, -1 call failed.
  int Health();

 private:
  void Start();

  TestServerOptions options_;
  std::optional<TempDir> ownDir_;
  std::filesystem::path dataDir_;
  std::unique_ptr<FakeBakeStats> stats_;
  std::unique_ptr<server::ProbebakeServer> server_;
  std::shared_ptr<grpc::Channel> channel_;
};

// Wall-clock seconds since `start`.
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace probebake::testing
