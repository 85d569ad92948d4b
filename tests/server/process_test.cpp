// Process-level tests of the server with the fake baker (probebake_fake_server): SIGKILL in the
// middle of a bake and restart, SIGTERM drain, and the data folder lock. The client side is the
// CLI's client library.
#include <gtest/gtest.h>

#include <signal.h>

#include <future>
#include <thread>

#include "client/client.h"
#include "probebake/job/digest.h"
#include "server/checkpoint.h"
#include "subprocess.h"
#include "test_server.h"

namespace probebake::testing {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using std::chrono::steady_clock;

class FakeServerProcess {
 public:
  FakeServerProcess(const std::filesystem::path& dataDir, const std::filesystem::path& logFile,
                    std::vector<std::string> extra = {}) {
    portFile_ = dataDir.parent_path() / ("port-" + std::to_string(++counter_));
    std::vector<std::string> argv = {PROBEBAKE_FAKE_SERVER, "--listen",       "127.0.0.1:0",
                                     "--data-dir",          dataDir.string(), "--port-file",
                                     portFile_.string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    process_ = std::make_unique<Subprocess>(argv, logFile);
  }
  std::optional<int> Port() { return WaitForPortFile(portFile_, seconds(20)); }
  Subprocess& process() { return *process_; }

 private:
  static inline int counter_ = 0;
  std::filesystem::path portFile_;
  std::unique_ptr<Subprocess> process_;
};

std::unique_ptr<client::Client> Connect(int port) {
  client::ConnectOptions options;
  options.server = "127.0.0.1:" + std::to_string(port);
  auto connected = client::Client::Connect(options);
  EXPECT_TRUE(connected.ok()) << connected.status();
  return connected.ok() ? std::move(*connected) : nullptr;
}

v1::BakeJob WaitProgress(client::Client& c, const std::string& name, int64_t probes) {
  v1::BakeJob job;
  for (int i = 0; i < 1000; ++i) {
    auto got = c.GetJob(name);
    EXPECT_TRUE(got.ok()) << got.status();
    if (!got.ok()) break;
    job = *got;
    if (job.state() == v1::BakeJob::RUNNING && job.progress().probes_done() >= probes) break;
    std::this_thread::sleep_for(milliseconds(10));
  }
  return job;
}

std::string FetchBytes(client::Client& c, const v1::Digest& digest,
                       const std::filesystem::path& dir) {
  std::filesystem::path out = dir / (digest.hash() + ".bin");
  absl::Status fetched = c.FetchBlob(digest, out);
  EXPECT_TRUE(fetched.ok()) << fetched;
  return ReadFile(out);
}

TEST(ServerProcess, SigkillMidBakeThenRestartCompletesOnceWithTheSameBits) {
  TempDir dir;
  auto data = dir.path() / "data";
  auto log = dir.path() / "server.log";
  const int probes = 300;
  std::string nameA, nameB;
  int64_t doneAtKill = 0, checkpointedAtKill = 0;
  {
    FakeServerProcess server(data, log,
                             {"--probe-delay-us", "5000", "--checkpoint-interval", "0.05"});
    auto port = server.Port();
    ASSERT_TRUE(port) << ReadFile(log);
    auto c = Connect(*port);
    ASSERT_TRUE(c);
    auto a = c->CreateJob(SmallJob(probes, 11), "kill-a", false);
    auto b = c->CreateJob(SmallJob(20, 12), "kill-b", false);  // queued behind a
    ASSERT_TRUE(a.ok() && b.ok());
    nameA = a->name();
    nameB = b->name();
    v1::BakeJob running = WaitProgress(*c, nameA, 100);
    ASSERT_EQ(running.state(), v1::BakeJob::RUNNING);
    // The baker reports a tick's progress before it writes that tick's checkpoint, so progress
    // says nothing of what is on disk: wait for a checkpoint with 50 probes (one is written on
    // every progress tick, 0.25 s apart, about 50 probes at 5 ms), bounded at 30 s.
    const std::filesystem::path checkpointFile = server::CheckpointFilePath(data, nameA);
    int64_t checkpointed = 0;
    for (auto start = steady_clock::now(); checkpointed < 50 && SecondsSince(start) < 30;) {
      auto read = server::ReadCheckpointOfAnyJob(checkpointFile);
      if (read.ok()) checkpointed = read->DoneCount();
      if (checkpointed < 50) std::this_thread::sleep_for(milliseconds(10));
    }
    ASSERT_GE(checkpointed, 50) << ReadFile(log);
    doneAtKill = c->GetJob(nameA).value_or(running).progress().probes_done();
    server.process().Signal(SIGKILL);
    EXPECT_EQ(server.process().Wait(seconds(10)), -SIGKILL);
    // Written atomically: the file the restarted server resumes from.
    auto read = server::ReadCheckpointOfAnyJob(checkpointFile);
    ASSERT_TRUE(read.ok()) << read.status();
    checkpointedAtKill = read->DoneCount();
    ASSERT_LT(checkpointedAtKill, probes) << "job a finished before it was killed";
  }
  auto restartStart = steady_clock::now();
  FakeServerProcess server(data, log,
                           {"--probe-delay-us", "5000", "--checkpoint-interval", "0.05"});
  auto port = server.Port();
  ASSERT_TRUE(port) << ReadFile(log);
  double servingSeconds = SecondsSince(restartStart);
  auto c = Connect(*port);
  ASSERT_TRUE(c);
  // The request ids still name the same jobs: nothing was lost or duplicated.
  auto again = c->CreateJob(SmallJob(probes, 11), "kill-a", false);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->name(), nameA);
  auto finalA = c->Watch(nameA, [](const v1::BakeJob&) {});
  ASSERT_TRUE(finalA.ok()) << finalA.status();
  double completeSeconds = SecondsSince(restartStart);
  EXPECT_EQ(finalA->state(), v1::BakeJob::SUCCEEDED) << finalA->DebugString();
  EXPECT_EQ(finalA->attempts(), 2);
  // It resumed from the checkpoint left by the kill.
  EXPECT_EQ(finalA->progress().probes_resumed(), checkpointedAtKill);
  auto finalB = c->Watch(nameB, [](const v1::BakeJob&) {});
  ASSERT_TRUE(finalB.ok());
  EXPECT_EQ(finalB->state(), v1::BakeJob::SUCCEEDED);
  EXPECT_EQ(finalB->attempts(), 1);
  auto list = c->ListJobs(100, "");
  ASSERT_TRUE(list.ok());
  EXPECT_EQ(list->bake_jobs_size(), 2);
  // Bits: the expected values, as an uninterrupted bake of the job gives them. (The files differ
  // in their stats: the resumed one counts the first attempt's time too.)
  std::string resumedBytes = FetchBytes(*c, finalA->result().volume(), dir.path());
  ExpectFakeVolume(resumedBytes, probes, 11);
  auto fresh = c->CreateJob(SmallJob(probes, 11), "", /*skipCache=*/true);
  ASSERT_TRUE(fresh.ok());
  auto freshFinal = c->Watch(fresh->name(), [](const v1::BakeJob&) {});
  ASSERT_TRUE(freshFinal.ok());
  ExpectFakeVolume(FetchBytes(*c, freshFinal->result().volume(), dir.path()), probes, 11);
  // Samples over both attempts (16 per probe): the first attempt's as of its last checkpoint
  // (exactly the probes it holds; what the killed process did after it is not counted), the
  // second's for the rest: every probe once, as in the uninterrupted bake.
  EXPECT_EQ(finalA->result().stats().samples(), probes * 16);
  EXPECT_EQ(freshFinal->result().stats().samples(), probes * 16);
  EXPECT_EQ(FakeVolumeStats(resumedBytes).samples, probes * 16);
  std::printf(
      "killed at %lld/%d probes (progress), %lld in the checkpoint; restart serving after "
      "%.3f s; resumed %lld probes; job done %.3f s after restart\n",
      (long long)doneAtKill, probes, (long long)checkpointedAtKill, servingSeconds,
      (long long)finalA->progress().probes_resumed(), completeSeconds);
  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(10)), 0);
}

TEST(ServerProcess, SigtermDrainsRequeuesAndExitsZero) {
  TempDir dir;
  auto data = dir.path() / "data";
  auto log = dir.path() / "server.log";
  std::string name;
  {
    FakeServerProcess server(data, log,
                             {"--probe-delay-us", "10000", "--checkpoint-interval", "0.1"});
    auto port = server.Port();
    ASSERT_TRUE(port) << ReadFile(log);
    auto c = Connect(*port);
    auto job = c->CreateJob(SmallJob(400, 21), "", false);
    ASSERT_TRUE(job.ok());
    name = job->name();
    ASSERT_EQ(WaitProgress(*c, name, 10).state(), v1::BakeJob::RUNNING);
    // A watcher is told UNAVAILABLE (come back later), not a final state.
    absl::StatusOr<v1::BakeJob> watched;
    std::thread watcher([&] {
      watched = c->Watch(
          name, [](const v1::BakeJob&) {}, seconds(0));
    });
    std::this_thread::sleep_for(milliseconds(100));
    auto start = steady_clock::now();
    server.process().Signal(SIGTERM);
    EXPECT_EQ(server.process().Wait(seconds(10)), 0) << ReadFile(log);
    double drainSeconds = SecondsSince(start);
    EXPECT_LT(drainSeconds, 3.0);
    watcher.join();
    EXPECT_EQ(watched.status().code(), absl::StatusCode::kUnavailable) << watched.status();
    std::printf("SIGTERM to exit: %.3f s\n", drainSeconds);
  }
  FakeServerProcess server(data, log, {"--probe-delay-us", "1000"});
  auto port = server.Port();
  ASSERT_TRUE(port);
  auto c = Connect(*port);
  auto final = c->Watch(name, [](const v1::BakeJob&) {});
  ASSERT_TRUE(final.ok());
  EXPECT_EQ(final->state(), v1::BakeJob::SUCCEEDED);
  EXPECT_EQ(final->attempts(), 2);
  EXPECT_GT(final->progress().probes_resumed(), 0);
}

TEST(ServerProcess, OneServerPerDataFolder) {
  TempDir dir;
  auto data = dir.path() / "data";
  auto log = dir.path() / "server.log";
  FakeServerProcess first(data, log);
  ASSERT_TRUE(first.Port());
  FakeServerProcess second(data, dir.path() / "second.log");
  EXPECT_EQ(second.process().Wait(seconds(20)), 1);
  EXPECT_NE(ReadFile(dir.path() / "second.log").find("in use by another probebake-server"),
            std::string::npos)
      << ReadFile(dir.path() / "second.log");
}

TEST(ServerProcess, AnUploadOfABlobAnotherClientIsUploadingWaitsForIt) {
  // Two clients upload the same new blob (a build farm's shared asset): the server takes one
  // upload of a digest at a time and answers the other ABORTED, which the CLI used to report as
  // a failed submit. The second waits while the first moves, then finds the blob stored; it gives
  // up only when that upload stalls for its limit.
  TempDir dir;
  FakeServerProcess server(dir.path() / "data", dir.path() / "server.log");
  const std::optional<int> port = server.Port();
  ASSERT_TRUE(port);
  const std::string bytes(3 << 20, 'x');
  const v1::Digest digest = DigestOf(bytes);
  auto channel =
      grpc::CreateChannel("127.0.0.1:" + std::to_string(*port), grpc::InsecureChannelCredentials());
  auto content = v1::ContentStorage::NewStub(channel);
  // Until the server holds `n` bytes of the upload of `d`: then that upload is open there (a
  // written message may still be in flight when Write returns).
  auto waitCommitted = [&](const v1::Digest& d, int64_t n) {
    for (int i = 0; i < 1000; ++i) {
      grpc::ClientContext context;
      v1::QueryWriteStatusRequest query;
      *query.mutable_digest() = d;
      v1::QueryWriteStatusResponse status;
      if (content->QueryWriteStatus(&context, query, &status).ok() && status.committed_size() >= n)
        return true;
      std::this_thread::sleep_for(milliseconds(20));
    }
    return false;
  };
  // The first client: a raw upload holding half the bytes, left open.
  auto openHalf = [&](grpc::ClientContext* context, v1::WriteBlobResponse* response) {
    auto writer = content->WriteBlob(context, response);
    v1::WriteBlobRequest first;
    *first.mutable_digest() = digest;
    first.set_data(bytes.substr(0, bytes.size() / 2));
    EXPECT_TRUE(writer->Write(first));
    EXPECT_TRUE(waitCommitted(digest, int64_t(bytes.size() / 2)));
    return writer;
  };
  {
    grpc::ClientContext context;
    v1::WriteBlobResponse response;
    auto writer = openHalf(&context, &response);
    std::unique_ptr<client::Client> second = Connect(*port);
    ASSERT_TRUE(second);
    const auto start = steady_clock::now();
    auto waited = std::async(std::launch::async, [&] { return second->UploadBlob(digest, bytes); });
    EXPECT_EQ(waited.wait_for(seconds(2)), std::future_status::timeout);
    v1::WriteBlobRequest rest;
    rest.set_write_offset(int64_t(bytes.size() / 2));
    rest.set_data(bytes.substr(bytes.size() / 2));
    rest.set_finish_write(true);
    EXPECT_TRUE(writer->Write(rest));
    writer->WritesDone();
    EXPECT_TRUE(writer->Finish().ok());
    const absl::Status uploaded = waited.get();
    EXPECT_TRUE(uploaded.ok()) << uploaded;
    EXPECT_GT(steady_clock::now() - start, seconds(2));
  }
  // A stalled first upload: the second gives up after its stall limit, naming the reason.
  const std::string other(1 << 20, 'y');
  const v1::Digest otherDigest = DigestOf(other);
  grpc::ClientContext context;
  v1::WriteBlobResponse response;
  auto writer = content->WriteBlob(&context, &response);
  v1::WriteBlobRequest first;
  *first.mutable_digest() = otherDigest;
  first.set_data(other.substr(0, 1000));
  ASSERT_TRUE(writer->Write(first));
  ASSERT_TRUE(waitCommitted(otherDigest, 1000));
  std::unique_ptr<client::Client> second = Connect(*port);
  ASSERT_TRUE(second);
  const absl::Status stalled = second->UploadBlob(otherDigest, other, nullptr, seconds(1));
  EXPECT_TRUE(absl::IsAborted(stalled)) << stalled;
  EXPECT_NE(stalled.message().find("made no progress for 1 s"), std::string::npos) << stalled;
  context.TryCancel();
}

}  // namespace
}  // namespace probebake::testing
