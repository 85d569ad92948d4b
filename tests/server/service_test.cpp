// RPC-level tests of probebake-server in process, over loopback, with the fake baker (so they
// test the service, not the tracer, and stay fast and deterministic).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <future>
#include <limits>
#include <memory>
#include <random>
#include <thread>

#include <grpcpp/generic/generic_stub.h>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "probebake/job/digest.h"
#include "server/job_manager.h"
#include "test_server.h"

namespace probebake::testing {
namespace {

using std::chrono::steady_clock;

grpc::Status CreateStatus(TestServer& s, const v1::CreateBakeJobRequest& request,
                          v1::BakeJob* job = nullptr,
                          std::multimap<std::string, std::string>* trailers = nullptr,
                          bool withToken = true) {
  v1::BakeJob ignored;
  auto context = s.Context(withToken);
  grpc::Status status = s.Jobs()->CreateBakeJob(context.get(), request, job ? job : &ignored);
  if (trailers) {
    for (const auto& [k, v] : context->GetServerTrailingMetadata())
      trailers->emplace(std::string(k.data(), k.size()), std::string(v.data(), v.size()));
  }
  return status;
}

v1::CreateBakeJobRequest Request(const v1::JobSpec& spec, const std::string& requestId = "") {
  v1::CreateBakeJobRequest request;
  *request.mutable_job() = spec;
  request.set_request_id(requestId);
  return request;
}

TEST(Service, CapabilitiesReportTheConfiguredLimits) {
  TestServerOptions options;
  options.limits.maxProbes = 1234;
  options.maxQueuedJobs = 7;
  TestServer s(options);
  v1::ServerCapabilities caps;
  auto context = s.Context();
  ASSERT_TRUE(s.Capabilities()->GetCapabilities(context.get(), {}, &caps).ok());
  EXPECT_EQ(caps.job_limits().max_probes(), 1234);
  EXPECT_EQ(caps.max_queued_jobs(), 7);
  EXPECT_EQ(caps.digest_function(), "SHA256");
  EXPECT_EQ(caps.chunk_bytes(), 1 << 20);
  EXPECT_EQ(caps.max_message_bytes(), 4 << 20);
  EXPECT_EQ(s.Health(), 1);
}

TEST(Service, BlobsRoundTripInChunksAndRanges) {
  TestServer s;
  std::string data(3 * 1024 * 1024 + 123, '\0');
  std::mt19937 rng(7);
  for (char& c : data) c = char(rng());
  v1::Digest digest = s.Upload(data, 1 << 20);
  EXPECT_EQ(s.Download(digest), data);

  // FindMissingBlobs answers only for the absent one.
  v1::FindMissingBlobsRequest find;
  *find.add_blob_digests() = digest;
  v1::Digest absent = DigestOf("absent");
  *find.add_blob_digests() = absent;
  v1::FindMissingBlobsResponse missing;
  auto c1 = s.Context();
  ASSERT_TRUE(s.Content()->FindMissingBlobs(c1.get(), find, &missing).ok());
  ASSERT_EQ(missing.missing_blob_digests_size(), 1);
  EXPECT_EQ(missing.missing_blob_digests(0).hash(), absent.hash());

  // A range, and the end of the blob.
  auto read = [&](int64_t offset, int64_t limit, std::string* out) {
    v1::ReadBlobRequest request;
    *request.mutable_digest() = digest;
    request.set_read_offset(offset);
    request.set_read_limit(limit);
    auto context = s.Context();
    auto stub = s.Content();
    auto reader = stub->ReadBlob(context.get(), request);
    v1::ReadBlobResponse chunk;
    out->clear();
    while (reader->Read(&chunk)) {
      EXPECT_LE(chunk.data().size(), size_t(1 << 20));
      *out += chunk.data();
    }
    return reader->Finish();
  };
  std::string part;
  ASSERT_TRUE(read(1000000, 2500000, &part).ok());
  EXPECT_EQ(part, data.substr(1000000, 2500000));
  ASSERT_TRUE(read(int64_t(data.size()), 0, &part).ok());
  EXPECT_TRUE(part.empty());
  EXPECT_EQ(read(int64_t(data.size()) + 1, 0, &part).error_code(), grpc::StatusCode::OUT_OF_RANGE);
  EXPECT_EQ(read(-1, 0, &part).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  digest = absent;
  EXPECT_EQ(read(0, 0, &part).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST(Service, WrongDigestIsInvalidArgumentAndUploadsResume) {
  TestServer s;
  std::string data(200000, 'x');
  for (size_t i = 0; i < data.size(); ++i) data[i] = char(i * 31 + 7);
  v1::Digest digest = DigestOf(data);

  auto write = [&](int64_t offset, const std::string& bytes, bool finish, const v1::Digest& d,
                   v1::WriteBlobResponse* response) {
    auto context = s.Context();
    auto stub = s.Content();
    auto writer = stub->WriteBlob(context.get(), response);
    v1::WriteBlobRequest request;
    *request.mutable_digest() = d;
    request.set_write_offset(offset);
    request.set_data(bytes);
    request.set_finish_write(finish);
    writer->Write(request);
    writer->WritesDone();
    return writer->Finish();
  };
  v1::WriteBlobResponse response;
  // Bytes that do not hash to the digest.
  v1::Digest wrong = digest;
  wrong.set_hash(Sha256Hex("something else"));
  grpc::Status status = write(0, data, true, wrong, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("hash"), std::string::npos) << status.error_message();
  // A size that disagrees with the digest.
  v1::Digest shortDigest = digest;
  shortDigest.set_size_bytes(10);
  EXPECT_EQ(write(0, data, true, shortDigest, &response).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);

  // Half an upload, the stream closed without finishWrite: the server keeps the bytes.
  status = write(0, data.substr(0, 120000), false, digest, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  v1::QueryWriteStatusRequest query;
  *query.mutable_digest() = digest;
  v1::QueryWriteStatusResponse progress;
  auto c = s.Context();
  ASSERT_TRUE(s.Content()->QueryWriteStatus(c.get(), query, &progress).ok());
  EXPECT_EQ(progress.committed_size(), 120000);
  EXPECT_FALSE(progress.complete());
  // Resuming at the wrong offset is refused; at the committed size it completes.
  EXPECT_EQ(write(0, data, true, digest, &response).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  ASSERT_TRUE(write(120000, data.substr(120000), true, digest, &response).ok());
  EXPECT_EQ(response.committed_size(), int64_t(data.size()));
  auto c2 = s.Context();
  ASSERT_TRUE(s.Content()->QueryWriteStatus(c2.get(), query, &progress).ok());
  EXPECT_TRUE(progress.complete());
  EXPECT_EQ(s.Download(digest), data);
  // Writing it again is answered at once.
  ASSERT_TRUE(write(0, "", false, digest, &response).ok());
  EXPECT_TRUE(response.already_present());
  EXPECT_EQ(s.Health(), 1);
}

TEST(Service, RefusedUploadsLeaveNothingBehind) {
  TestServer s;
  std::string data(50000, 'x');
  for (size_t i = 0; i < data.size(); ++i) data[i] = char(i * 131 + 3);
  const v1::Digest digest = DigestOf(data);
  struct Message {
    v1::Digest digest;
    int64_t offset = 0;
    std::string bytes;
    bool finish = false;
  };
  // One stream of `messages`; the status it ends with.
  auto write = [&](const std::vector<Message>& messages) {
    auto context = s.Context();
    auto stub = s.Content();
    v1::WriteBlobResponse response;
    auto writer = stub->WriteBlob(context.get(), &response);
    for (const Message& m : messages) {
      v1::WriteBlobRequest request;
      *request.mutable_digest() = m.digest;
      request.set_write_offset(m.offset);
      request.set_data(m.bytes);
      request.set_finish_write(m.finish);
      if (!writer->Write(request)) break;
    }
    writer->WritesDone();
    return writer->Finish();
  };
  const std::filesystem::path uploads = s.dataDir() / "uploads";
  auto leftovers = [&] {
    std::vector<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(uploads))
      names.push_back(entry.path().filename().string());
    return names;
  };
  v1::Digest wrongHash = digest, shortSize = digest, other = DigestOf("another blob");
  wrongHash.set_hash(Sha256Hex("something else"));
  shortSize.set_size_bytes(10);
  const std::string half = data.substr(0, 20000);
  const struct {
    const char* what;
    std::vector<Message> messages;
  } refusals[] = {
      {"bytes that hash to another digest", {{wrongHash, 0, data, true}}},
      {"more bytes than the digest's size", {{shortSize, 0, data, true}}},
      {"finishWrite before every byte", {{digest, 0, half, true}}},
      {"finishWrite in a later message, short", {{digest, 0, half}, {digest, 20000, "", true}}},
      {"an offset skipping ahead on a new upload", {{digest, 100, data, true}}},
      {"a negative offset on a new upload", {{digest, -5, data, true}}},
      {"a digest changing mid-stream", {{digest, 0, half}, {other, 20000, data.substr(20000)}}},
      {"an offset skipping ahead after good chunks", {{digest, 0, half}, {digest, 30000, "x"}}},
  };
  for (const auto& refusal : refusals) {
    const grpc::Status status = write(refusal.messages);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
        << refusal.what << ": " << status.error_message();
    EXPECT_EQ(leftovers(), std::vector<std::string>{}) << refusal.what;
  }
  // What the contract keeps: a broken stream's bytes, and those bytes through a resume at the
  // wrong offset, until the upload completes.
  EXPECT_EQ(write({{digest, 0, half}}).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(leftovers().size(), 1u);
  EXPECT_EQ(write({{digest, 0, data, true}}).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(leftovers().size(), 1u);
  EXPECT_TRUE(write({{digest, 20000, data.substr(20000), true}}).ok());
  EXPECT_EQ(leftovers(), std::vector<std::string>{});
  EXPECT_EQ(s.Download(digest), data);
  EXPECT_EQ(s.Health(), 1);
}

TEST(Service, SubmitWatchFetch) {
  TestServer s;
  const int probes = 24;
  v1::BakeJob created = s.Create(SmallJob(probes, 5));
  EXPECT_EQ(created.state(), v1::BakeJob::QUEUED);
  EXPECT_EQ(created.name().rfind("bakeJobs/", 0), 0u);
  EXPECT_EQ(created.job_digest().size(), 64u);
  std::vector<v1::BakeJob> messages;
  v1::BakeJob final = s.WaitFinal(created.name(), &messages);
  ASSERT_EQ(final.state(), v1::BakeJob::SUCCEEDED) << final.DebugString();
  EXPECT_FALSE(final.result().cached_result());
  EXPECT_EQ(final.result().source_job(), created.name());
  EXPECT_EQ(final.attempts(), 1);
  EXPECT_EQ(final.progress().probes_done(), probes);
  EXPECT_EQ(final.progress().error_estimate(), 0.01);
  EXPECT_EQ(final.progress().probes_error_unknown(), probes / 8);  // the fake's count
  EXPECT_TRUE(final.has_end_time());
  // States only move forward; progress never goes back.
  int64_t lastDone = 0;
  for (size_t i = 1; i < messages.size(); ++i) {
    EXPECT_GE(int(messages[i].state()), int(messages[i - 1].state()));
    EXPECT_GE(messages[i].progress().probes_done(), lastDone);
    lastDone = messages[i].progress().probes_done();
  }
  ExpectFakeVolume(s.Download(final.result().volume()), probes, 5);
  // Get (FULL) carries the spec; BASIC does not.
  v1::BakeJob full = s.Get(created.name());
  EXPECT_EQ(full.job().grid().counts(0), probes);
  EXPECT_EQ(full.state(), v1::BakeJob::SUCCEEDED);
}

TEST(Service, WatchUpdatesAreRateLimited) {
  TestServerOptions options;
  options.probeDelay = std::chrono::milliseconds(10);  // 100 probes: ~1 s of baking
  TestServer s(options);
  v1::BakeJob created = s.Create(SmallJob(100));
  auto start = steady_clock::now();
  std::vector<v1::BakeJob> messages;
  v1::BakeJob final = s.WaitFinal(created.name(), &messages);
  double seconds = SecondsSince(start);
  ASSERT_EQ(final.state(), v1::BakeJob::SUCCEEDED);
  // Progress comes every 0.25 s (BakeOptions.progressIntervalSeconds) plus the state changes
  // (queued, running, succeeded) and the final report: at most 4/s + 4, and at least one
  // progress message mid-bake (a watch that only saw the end would not be a watch).
  EXPECT_LE(double(messages.size()), 4.0 * seconds + 4.0 + 1.0)
      << messages.size() << " messages in " << seconds << " s";
  int midBake = 0;
  for (const v1::BakeJob& m : messages)
    midBake += m.state() == v1::BakeJob::RUNNING && m.progress().probes_done() > 0 &&
               m.progress().probes_done() < 100;
  EXPECT_GE(midBake, 1);
}

TEST(Service, RequestIdIsIdempotent) {
  TestServer s;
  v1::BakeJob first = s.Create(SmallJob(4), "req-1");
  v1::BakeJob again = s.Create(SmallJob(4), "req-1");
  EXPECT_EQ(again.name(), first.name());
  // The same id with another job, or the same job with another skip_cache, is refused with the
  // field and the job that holds the id, and creates nothing.
  const grpc::Status otherJob = CreateStatus(s, Request(SmallJob(5), "req-1"));
  EXPECT_EQ(otherJob.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(otherJob.error_message().find("requestId: \"req-1\" was already used by " +
                                          first.name() + " for a different request"),
            std::string::npos)
      << otherJob.error_message();
  v1::CreateBakeJobRequest skip = Request(SmallJob(4), "req-1");
  skip.set_skip_cache(true);
  EXPECT_EQ(CreateStatus(s, skip).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  v1::ListBakeJobsResponse list;
  auto c = s.Context();
  ASSERT_TRUE(s.Jobs()->ListBakeJobs(c.get(), {}, &list).ok());
  EXPECT_EQ(list.bake_jobs_size(), 1);
  s.WaitFinal(first.name());
  EXPECT_EQ(s.bakeStats().bakes.load(), 1);
}

TEST(Service, ResultCacheHitSkipCacheAndMissingVolume) {
  TestServer s;
  v1::BakeJob first = s.Create(SmallJob(6, 3));
  v1::BakeJob done = s.WaitFinal(first.name());
  ASSERT_EQ(done.state(), v1::BakeJob::SUCCEEDED);

  auto start = steady_clock::now();
  v1::BakeJob cached = s.Create(SmallJob(6, 3));
  EXPECT_LT(SecondsSince(start), 1.0);
  EXPECT_EQ(cached.state(), v1::BakeJob::SUCCEEDED);
  EXPECT_TRUE(cached.result().cached_result());
  EXPECT_EQ(cached.result().source_job(), first.name());
  EXPECT_EQ(cached.result().volume().hash(), done.result().volume().hash());
  EXPECT_NE(cached.name(), first.name());
  EXPECT_EQ(s.bakeStats().bakes.load(), 1);

  // Another seed is another job digest: no hit.
  EXPECT_EQ(s.Create(SmallJob(6, 4)).state(), v1::BakeJob::QUEUED);
  // skipCache bakes again, with the same bits.
  v1::BakeJob forced = s.Create(SmallJob(6, 3), "", /*skipCache=*/true);
  EXPECT_EQ(forced.state(), v1::BakeJob::QUEUED);
  v1::BakeJob rebaked = s.WaitFinal(forced.name());
  EXPECT_EQ(rebaked.result().volume().hash(), done.result().volume().hash());

  // A cache entry whose volume blob is gone is not served.
  std::string hash = done.result().volume().hash();
  std::filesystem::remove(s.dataDir() / "blobs" / hash.substr(0, 2) / hash);
  v1::BakeJob afterLoss = s.Create(SmallJob(6, 3));
  EXPECT_EQ(afterLoss.state(), v1::BakeJob::QUEUED);
  EXPECT_EQ(s.WaitFinal(afterLoss.name()).state(), v1::BakeJob::SUCCEEDED);
}

TEST(Service, CancelRunningJobReachesTheBakerQuickly) {
  TestServerOptions options;
  options.probeDelay = std::chrono::milliseconds(20);
  TestServer s(options);
  v1::BakeJob created = s.Create(SmallJob(500));
  // Wait until it runs and has baked some probes.
  v1::BakeJob now;
  for (int i = 0; i < 200; ++i) {
    now = s.Get(created.name());
    if (now.state() == v1::BakeJob::RUNNING && now.progress().probes_done() > 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_EQ(now.state(), v1::BakeJob::RUNNING);
  auto start = steady_clock::now();
  v1::CancelBakeJobRequest cancel;
  cancel.set_name(created.name());
  v1::BakeJob answer;
  auto c = s.Context();
  ASSERT_TRUE(s.Jobs()->CancelBakeJob(c.get(), cancel, &answer).ok());
  EXPECT_TRUE(answer.cancel_requested());
  v1::BakeJob final = s.WaitFinal(created.name());
  double seconds = SecondsSince(start);
  EXPECT_EQ(final.state(), v1::BakeJob::CANCELLED);
  EXPECT_EQ(final.error().code(), int(grpc::StatusCode::CANCELLED));
  // The baker checks the flag between probes (20 ms): well under half a second end to end.
  EXPECT_LT(seconds, 0.5);
  EXPECT_LT(final.progress().probes_done(), 500);
  // Cancelling a final job changes nothing.
  auto c2 = s.Context();
  ASSERT_TRUE(s.Jobs()->CancelBakeJob(c2.get(), cancel, &answer).ok());
  EXPECT_EQ(answer.state(), v1::BakeJob::CANCELLED);
}

TEST(Service, QueueBoundCancelQueuedAndDelete) {
  TestServerOptions options;
  options.probeDelay = std::chrono::milliseconds(20);
  options.maxQueuedJobs = 1;
  TestServer s(options);
  v1::BakeJob a = s.Create(SmallJob(200, 1));
  for (int i = 0; i < 100 && s.Get(a.name()).state() != v1::BakeJob::RUNNING; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  v1::BakeJob b = s.Create(SmallJob(10, 2));
  EXPECT_EQ(b.state(), v1::BakeJob::QUEUED);
  // The queue holds one job: the next is refused with a retry delay.
  std::multimap<std::string, std::string> trailers;
  grpc::Status full = CreateStatus(s, Request(SmallJob(10, 3)), nullptr, &trailers);
  EXPECT_EQ(full.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << full.error_message();
  auto retry = trailers.find("retry-after-ms");
  ASSERT_NE(retry, trailers.end());
  int retryMs = std::stoi(retry->second);
  EXPECT_GE(retryMs, 1000);
  EXPECT_LE(retryMs, 60000);

  // Delete refuses a running job; a queued one is cancelled at once.
  v1::DeleteBakeJobRequest del;
  del.set_name(a.name());
  google::protobuf::Empty empty;
  auto c1 = s.Context();
  EXPECT_EQ(s.Jobs()->DeleteBakeJob(c1.get(), del, &empty).error_code(),
            grpc::StatusCode::FAILED_PRECONDITION);
  v1::CancelBakeJobRequest cancel;
  cancel.set_name(b.name());
  v1::BakeJob cancelled;
  auto c2 = s.Context();
  ASSERT_TRUE(s.Jobs()->CancelBakeJob(c2.get(), cancel, &cancelled).ok());
  EXPECT_EQ(cancelled.state(), v1::BakeJob::CANCELLED);
  // Now there is room again.
  v1::BakeJob c = s.Create(SmallJob(10, 3));
  EXPECT_EQ(c.state(), v1::BakeJob::QUEUED);
  // Delete a final job: gone afterwards.
  del.set_name(b.name());
  auto c3 = s.Context();
  ASSERT_TRUE(s.Jobs()->DeleteBakeJob(c3.get(), del, &empty).ok());
  v1::GetBakeJobRequest get;
  get.set_name(b.name());
  v1::BakeJob gone;
  auto c4 = s.Context();
  EXPECT_EQ(s.Jobs()->GetBakeJob(c4.get(), get, &gone).error_code(), grpc::StatusCode::NOT_FOUND);
  cancel.set_name(a.name());
  auto c5 = s.Context();
  ASSERT_TRUE(s.Jobs()->CancelBakeJob(c5.get(), cancel, &cancelled).ok());
  EXPECT_EQ(s.WaitFinal(c.name()).state(), v1::BakeJob::SUCCEEDED);
}

TEST(Service, BadRequestsGetTheRightStatusAndTheServerStaysHealthy) {
  TestServerOptions options;
  options.limits.maxProbes = 1000;
  TestServer s(options);
  auto expectStatus = [&](const v1::JobSpec& spec, grpc::StatusCode code,
                          const std::string& messagePart) {
    grpc::Status status = CreateStatus(s, Request(spec));
    EXPECT_EQ(status.error_code(), code) << status.error_message();
    EXPECT_NE(status.error_message().find(messagePart), std::string::npos)
        << "expected \"" << messagePart << "\" in: " << status.error_message();
  };
  // A client path: the server never reads it.
  v1::JobSpec withFile = SmallJob(4);
  v1::Mesh* mesh = withFile.mutable_scene()->mutable_meshes(0);
  mesh->clear_positions();
  mesh->clear_indices();
  mesh->set_file("/etc/passwd");
  expectStatus(withFile, grpc::StatusCode::INVALID_ARGUMENT,
               "scene.meshes[0].file: the server does not read client paths; upload the file and "
               "reference it by blob");
  // A blob the server does not have.
  v1::JobSpec withBlob = SmallJob(4);
  mesh = withBlob.mutable_scene()->mutable_meshes(0);
  mesh->clear_positions();
  mesh->clear_indices();
  *mesh->mutable_blob() = DigestOf("v 0 0 0\n");
  mesh->set_format("obj");
  expectStatus(withBlob, grpc::StatusCode::FAILED_PRECONDITION,
               "scene.meshes[0].blob sha256:" + DigestOf("v 0 0 0\n").hash());
  // NaN.
  v1::JobSpec nan = SmallJob(4);
  nan.mutable_scene()->mutable_materials(0)->set_albedo(1, std::nan(""));
  expectStatus(nan, grpc::StatusCode::INVALID_ARGUMENT, "scene.materials[0].albedo[1]");
  // Past the probe limit.
  v1::JobSpec huge = SmallJob(4);
  huge.mutable_grid()->set_counts(0, 100000);
  huge.mutable_grid()->set_max(1, 10);
  huge.mutable_grid()->set_counts(1, 100000);
  expectStatus(huge, grpc::StatusCode::INVALID_ARGUMENT, "grid");
  // No job at all, a bad request id.
  expectStatus(v1::JobSpec(), grpc::StatusCode::INVALID_ARGUMENT, "");
  v1::CreateBakeJobRequest noJob;
  EXPECT_EQ(CreateStatus(s, noJob).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(CreateStatus(s, Request(SmallJob(4), std::string(200, 'r'))).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  // Names, pages.
  for (std::string name : {"", "bakeJobs/", "bakeJobs/../../etc", "jobs/0123456789abcdef",
                           "bakeJobs/0123456789ABCDEF"}) {
    v1::GetBakeJobRequest get;
    get.set_name(name);
    v1::BakeJob job;
    auto c = s.Context();
    EXPECT_EQ(s.Jobs()->GetBakeJob(c.get(), get, &job).error_code(),
              grpc::StatusCode::INVALID_ARGUMENT)
        << name;
  }
  v1::GetBakeJobRequest get;
  get.set_name("bakeJobs/0123456789abcdef");
  v1::BakeJob job;
  auto c1 = s.Context();
  EXPECT_EQ(s.Jobs()->GetBakeJob(c1.get(), get, &job).error_code(), grpc::StatusCode::NOT_FOUND);
  v1::ListBakeJobsRequest list;
  list.set_page_token("garbage");
  v1::ListBakeJobsResponse page;
  auto c2 = s.Context();
  EXPECT_EQ(s.Jobs()->ListBakeJobs(c2.get(), list, &page).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  list.set_page_token("");
  list.set_page_size(-1);
  auto c3 = s.Context();
  EXPECT_EQ(s.Jobs()->ListBakeJobs(c3.get(), list, &page).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  // Watching an unknown job: NOT_FOUND (resubmit).
  v1::WatchBakeJobRequest watch;
  watch.set_name("bakeJobs/0123456789abcdef");
  auto c4 = s.Context();
  auto stub = s.Jobs();
  auto reader = stub->WatchBakeJob(c4.get(), watch);
  v1::BakeJob ignored;
  EXPECT_FALSE(reader->Read(&ignored));
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
  // Nothing was accepted, the server is healthy and still bakes.
  v1::ListBakeJobsResponse all;
  auto c5 = s.Context();
  ASSERT_TRUE(s.Jobs()->ListBakeJobs(c5.get(), {}, &all).ok());
  EXPECT_EQ(all.bake_jobs_size(), 0);
  EXPECT_EQ(s.Health(), 1);
  EXPECT_EQ(s.WaitFinal(s.Create(SmallJob(3)).name()).state(), v1::BakeJob::SUCCEEDED);
}

TEST(Service, TokenIsRequiredOnEveryCallButHealth) {
  TestServerOptions options;
  options.token = "s3cret-token";
  TestServer s(options);
  EXPECT_EQ(s.Health(), 1);  // no token needed
  auto call = [&](const std::string* authorization) {
    grpc::ClientContext context;
    if (authorization) context.AddMetadata("authorization", *authorization);
    v1::ServerCapabilities caps;
    return s.Capabilities()->GetCapabilities(&context, {}, &caps);
  };
  EXPECT_EQ(call(nullptr).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  std::string wrong = "Bearer s3cret-tokex", scheme = "Basic s3cret-token",
              good = "Bearer s3cret-token", prefix = "Bearer s3cret";
  EXPECT_EQ(call(&wrong).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(call(&scheme).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(call(&prefix).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_TRUE(call(&good).ok());
  // Streams and job calls too.
  EXPECT_EQ(
      CreateStatus(s, Request(SmallJob(2)), nullptr, nullptr, /*withToken=*/false).error_code(),
      grpc::StatusCode::UNAUTHENTICATED);
  {
    grpc::ClientContext context;
    v1::ReadBlobRequest request;
    *request.mutable_digest() = DigestOf("x");
    auto stub = s.Content();
    auto reader = stub->ReadBlob(&context, request);
    v1::ReadBlobResponse chunk;
    EXPECT_FALSE(reader->Read(&chunk));
    EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::UNAUTHENTICATED);
  }
  {
    grpc::ClientContext context;
    v1::WriteBlobResponse response;
    auto stub = s.Content();
    auto writer = stub->WriteBlob(&context, &response);
    v1::WriteBlobRequest request;
    *request.mutable_digest() = DigestOf("x");
    request.set_data("x");
    request.set_finish_write(true);
    writer->Write(request);
    writer->WritesDone();
    EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::UNAUTHENTICATED);
  }
  // With the token everything works.
  v1::BakeJob job = s.Create(SmallJob(2));
  EXPECT_EQ(s.WaitFinal(job.name()).state(), v1::BakeJob::SUCCEEDED);
}

TEST(Service, ListPagesThroughEveryJobOnce) {
  TestServer s;
  std::vector<std::string> names;
  for (int i = 0; i < 7; ++i) names.push_back(s.Create(SmallJob(2, uint64_t(100 + i))).name());
  std::vector<std::string> listed;
  v1::ListBakeJobsRequest request;
  request.set_page_size(3);
  int pages = 0;
  while (true) {
    v1::ListBakeJobsResponse page;
    auto c = s.Context();
    ASSERT_TRUE(s.Jobs()->ListBakeJobs(c.get(), request, &page).ok());
    ++pages;
    EXPECT_LE(page.bake_jobs_size(), 3);
    for (const v1::BakeJob& job : page.bake_jobs()) {
      listed.push_back(job.name());
      EXPECT_FALSE(job.has_job());  // BASIC view by default
    }
    if (page.next_page_token().empty()) break;
    request.set_page_token(page.next_page_token());
  }
  EXPECT_EQ(pages, 3);
  EXPECT_EQ(listed, names);
}

TEST(Service, GracefulRestartResumesFromTheCheckpointWithTheSameBits) {
  TestServerOptions options;
  options.probeDelay = std::chrono::milliseconds(5);
  options.checkpointIntervalSeconds = 0.05;
  TempDir dir;
  TestServer s(options, dir.path() / "data");
  const int probes = 200;
  v1::BakeJob created = s.Create(SmallJob(probes, 9));
  v1::BakeJob now;
  for (int i = 0; i < 400; ++i) {
    now = s.Get(created.name());
    if (now.progress().probes_done() >= 40) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(now.state(), v1::BakeJob::RUNNING);
  auto start = steady_clock::now();
  s.Stop();  // SIGTERM path: cancel, checkpoint kept, requeued
  double stopSeconds = SecondsSince(start);
  EXPECT_LT(stopSeconds, 3.0);
  s.Restart();
  std::vector<v1::BakeJob> messages;
  v1::BakeJob final = s.WaitFinal(created.name(), &messages);
  ASSERT_EQ(final.state(), v1::BakeJob::SUCCEEDED) << final.DebugString();
  EXPECT_EQ(final.attempts(), 2);
  EXPECT_EQ(s.bakeStats().resumed.load(), 1);
  // Fewer probes baked after the restart than in all: the checkpoint was used.
  EXPECT_LT(s.bakeStats().probesBaked.load(), probes);
  EXPECT_LE(s.bakeStats().maxActivePerJob, 1);
  std::string volume = s.Download(final.result().volume());
  ExpectFakeVolume(volume, probes, 9);
  // The counts cover both attempts: the fake baker traces 16 samples and 32 rays per probe and
  // checkpointed every probe of the first attempt when it stopped, so the totals are exact.
  const int64_t samples = int64_t(probes) * 16;
  EXPECT_EQ(final.result().stats().samples(), samples);
  EXPECT_EQ(final.result().stats().rays(), 2 * samples);
  EXPECT_EQ(final.progress().samples(), samples);
  BakeStats stored = FakeVolumeStats(volume);  // the volume's `stats` metadata
  EXPECT_EQ(stored.samples, samples);
  EXPECT_EQ(stored.rays, 2 * samples);
  EXPECT_GT(stored.wallSeconds, 0.0);  // the first attempt's time (the fake's own is 0)
  EXPECT_EQ(stored.wallSeconds, final.result().stats().wall_seconds());
  // Progress mid-way through the second attempt counts the resumed probes' samples too.
  int resumedMessages = 0;
  for (const v1::BakeJob& m : messages) {
    if (m.state() != v1::BakeJob::RUNNING || m.progress().probes_resumed() == 0) continue;
    EXPECT_EQ(m.progress().samples(), m.progress().probes_done() * 16) << m.DebugString();
    ++resumedMessages;
  }
  EXPECT_GE(resumedMessages, 1);
}

TEST(Service, AJobsEndIsAnnouncedOnlyOnceStored) {
  // The job store cannot be written when a bake ends: another connection takes SQLite's write
  // lock just before the volume is written and holds it past the server's 5 s busy timeout,
  // failing the write as a full disk does. The end is retried with the job RUNNING, its progress
  // saying why; watchers learn SUCCEEDED only once it is stored, and a restart finds it so. (It
  // was announced SUCCEEDED at once while the store kept RUNNING, so the job ran again after a
  // restart.)
  TempDir dir;
  const std::filesystem::path dataDir = dir.path() / "data";
  LockStoreAtVolumeWrite lock;
  TestServerOptions options;
  lock.Arm(&options, dataDir);
  TestServer s(options, dataDir);
  const v1::BakeJob created = s.Create(SmallJob(4, 21));
  std::vector<v1::BakeJob> messages;
  auto watched =
      std::async(std::launch::async, [&] { return s.WaitFinal(created.name(), &messages); });
  ASSERT_TRUE(lock.WaitTaken(std::chrono::seconds(20)));
  // The end's first try waits out the busy timeout and fails; the job says so.
  const std::string waiting = s.WaitUntilWaiting(created.name());
  EXPECT_TRUE(absl::StartsWith(waiting, "waiting to store the job's end: ")) << waiting;
  EXPECT_EQ(watched.wait_for(std::chrono::seconds(0)), std::future_status::timeout);
  const auto released = steady_clock::now();
  lock.Release();
  const v1::BakeJob final = watched.get();
  EXPECT_GE(steady_clock::now(), released);
  ASSERT_EQ(final.state(), v1::BakeJob::SUCCEEDED) << final.DebugString();
  EXPECT_TRUE(std::all_of(messages.begin(), messages.end() - 1, [](const v1::BakeJob& m) {
    return m.state() == v1::BakeJob::QUEUED || m.state() == v1::BakeJob::RUNNING;
  }));
  EXPECT_EQ(final.progress().waiting(), "");
  EXPECT_EQ(s.bakeStats().bakes.load(), 1);
  s.Restart();
  const v1::BakeJob stored = s.Get(created.name());
  EXPECT_EQ(stored.state(), v1::BakeJob::SUCCEEDED);
  EXPECT_EQ(stored.attempts(), 1);
  EXPECT_EQ(stored.result().volume().hash(), final.result().volume().hash());
}

TEST(Service, ACancelTheStoreRefusesChangesNothing) {
  // The job store cannot be written (another connection holds SQLite's write lock past the busy
  // timeout) when a running job is cancelled: the cancel is an error, and the job neither shows
  // cancel_requested nor stops; it ends SUCCEEDED once the store works. (It read "(cancelling)"
  // after the refused cancel.)
  TestServerOptions options;
  options.probeDelay = std::chrono::milliseconds(100);
  TempDir dir;
  TestServer s(options, dir.path() / "data");
  const v1::BakeJob created = s.Create(SmallJob(40, 23));
  for (int i = 0; i < 200 && s.Get(created.name()).state() != v1::BakeJob::RUNNING; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  StoreWriteLock lock(s.dataDir());
  v1::CancelBakeJobRequest cancel;
  cancel.set_name(created.name());
  v1::BakeJob answer;
  auto c = s.Context();
  const grpc::Status refused = s.Jobs()->CancelBakeJob(c.get(), cancel, &answer);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::UNAVAILABLE) << refused.error_message();
  const v1::BakeJob after = s.Get(created.name());
  EXPECT_FALSE(after.cancel_requested());
  lock.Release();
  const v1::BakeJob final = s.WaitFinal(created.name());
  EXPECT_EQ(final.state(), v1::BakeJob::SUCCEEDED) << final.DebugString();
  EXPECT_FALSE(final.cancel_requested());
}

TEST(Service, AJobToldSucceededCanBeCancelledAndDeletedAtOnce) {
  // The job's worker leaves after announcing the end: a client acting on SUCCEEDED at once got
  // "the job is running; cancel it first" from DeleteBakeJob, and CancelBakeJob stored
  // cancel_requested on the finished job. Repeated, since the window is short.
  TestServerOptions options;
  options.probeDelay = std::chrono::microseconds(100);
  TestServer s(options);
  for (int i = 0; i < 30; ++i) {
    const v1::BakeJob final = s.WaitFinal(s.Create(SmallJob(1, 100 + i)).name());
    ASSERT_EQ(final.state(), v1::BakeJob::SUCCEEDED);
    v1::CancelBakeJobRequest cancel;
    cancel.set_name(final.name());
    v1::BakeJob cancelled;
    auto c1 = s.Context();
    ASSERT_TRUE(s.Jobs()->CancelBakeJob(c1.get(), cancel, &cancelled).ok());
    EXPECT_EQ(cancelled.state(), v1::BakeJob::SUCCEEDED);
    EXPECT_FALSE(cancelled.cancel_requested()) << "iteration " << i;
    v1::DeleteBakeJobRequest del;
    del.set_name(final.name());
    google::protobuf::Empty empty;
    auto c2 = s.Context();
    const grpc::Status deleted = s.Jobs()->DeleteBakeJob(c2.get(), del, &empty);
    EXPECT_TRUE(deleted.ok()) << "iteration " << i << ": " << deleted.error_message();
  }
}

// A volume write failing as on a full disk (what WriteProbeVolume returns for ENOSPC).
absl::Status DiskFull() {
  return absl::ResourceExhaustedError(
      "data/tmp/x.vdb: writing grid radiance_sh_00 failed: No "
      "space left on device");
}

// Whether any RUNNING message says the job waits for disk space.
bool SawWaitingForSpace(const std::vector<v1::BakeJob>& messages) {
  return std::any_of(messages.begin(), messages.end(), [](const v1::BakeJob& m) {
    return m.state() == v1::BakeJob::RUNNING &&
           absl::StartsWith(m.progress().waiting(),
                            "waiting for disk space to store the volume: ") &&
           absl::StrContains(m.progress().waiting(), "No space left on device");
  });
}

TEST(Service, AFullDiskPausesTheVolumeWriteAndLosesNoBake) {
  // The volume cannot be written twice (a full disk), then can: the job stays RUNNING, its
  // progress says it waits for space, and it succeeds with the volume of its one bake. (The job
  // ended FAILED at stage "store", its bake lost.)
  std::atomic<int> writes{0};
  TestServerOptions options;
  options.volumeWriteFault = [&] { return ++writes <= 2 ? DiskFull() : absl::OkStatus(); };
  TestServer s(options);
  const v1::BakeJob created = s.Create(SmallJob(4, 31));
  std::vector<v1::BakeJob> messages;
  const v1::BakeJob final = s.WaitFinal(created.name(), &messages);
  ASSERT_EQ(final.state(), v1::BakeJob::SUCCEEDED) << final.DebugString();
  EXPECT_EQ(writes.load(), 3);
  EXPECT_EQ(s.bakeStats().bakes.load(), 1);
  EXPECT_EQ(final.attempts(), 1);
  EXPECT_TRUE(SawWaitingForSpace(messages));
  EXPECT_EQ(final.progress().waiting(), "");
  ExpectFakeVolume(s.Download(final.result().volume()), 4, 31);
}

TEST(Service, AJobWaitingForDiskSpaceCanBeCancelledOrRestarted) {
  // While a job waits to store its volume, a cancel ends it CANCELLED, and a shutdown requeues
  // it: after the restart, with space back, it bakes again and succeeds.
  std::atomic<bool> full{true};
  std::atomic<int> writes{0};
  TestServerOptions options;
  options.volumeWriteFault = [&] {
    ++writes;
    return full ? DiskFull() : absl::OkStatus();
  };
  TempDir dir;
  TestServer s(options, dir.path() / "data");

  const v1::BakeJob first = s.Create(SmallJob(3, 32));
  EXPECT_NE(s.WaitUntilWaiting(first.name()), "");
  v1::CancelBakeJobRequest cancel;
  cancel.set_name(first.name());
  v1::BakeJob answer;
  auto c = s.Context();
  ASSERT_TRUE(s.Jobs()->CancelBakeJob(c.get(), cancel, &answer).ok());
  const v1::BakeJob cancelled = s.WaitFinal(first.name());
  EXPECT_EQ(cancelled.state(), v1::BakeJob::CANCELLED) << cancelled.DebugString();
  EXPECT_EQ(cancelled.error().code(), int(grpc::StatusCode::CANCELLED));

  const v1::BakeJob second = s.Create(SmallJob(3, 33));
  EXPECT_NE(s.WaitUntilWaiting(second.name()), "");
  s.Stop();
  EXPECT_EQ(s.bakeStats().bakes.load(), 2);
  full = false;
  s.Restart();
  const v1::BakeJob final = s.WaitFinal(second.name());
  ASSERT_EQ(final.state(), v1::BakeJob::SUCCEEDED) << final.DebugString();
  EXPECT_EQ(final.attempts(), 2);
  ExpectFakeVolume(s.Download(final.result().volume()), 3, 33);
}

TEST(Service, AVolumeWriteFailingForAnotherReasonFailsTheJob) {
  // Only a lack of space is waited out: another write error ends the job FAILED at stage
  // "store" at once, without a retry. Its message names the data folder as DATA: clients are not
  // told where the server keeps its files.
  std::atomic<int> writes{0};
  TempDir dir;
  const std::filesystem::path dataDir = dir.path() / "data";
  TestServerOptions options;
  options.volumeWriteFault = [&] {
    ++writes;
    return absl::InternalError(
        absl::StrCat((dataDir / "tmp/x.vdb").string(), ": OpenVDB: something broke"));
  };
  TestServer s(options, dataDir);
  const v1::BakeJob final = s.WaitFinal(s.Create(SmallJob(2, 34)).name());
  EXPECT_EQ(final.state(), v1::BakeJob::FAILED);
  EXPECT_EQ(final.error().code(), int(grpc::StatusCode::INTERNAL));
  EXPECT_EQ(final.error().details().at("stage"), "store");
  EXPECT_EQ(final.error().message(), "DATA/tmp/x.vdb: OpenVDB: something broke");
  EXPECT_EQ(s.Get(final.name()).error().message(), final.error().message());
  EXPECT_EQ(writes.load(), 1);
}

// SmallJob with an extra inline mesh of about `bytes` bytes (one triangle, many unused vertices).
v1::JobSpec JobOfAbout(int64_t bytes, uint64_t seed) {
  v1::JobSpec spec = SmallJob(2, seed);
  v1::Mesh* mesh = spec.mutable_scene()->add_meshes();
  mesh->set_material("white");
  for (int64_t i = 0; i < bytes / 24 * 3; ++i) mesh->add_positions(double((i * 7919) % 1013));
  for (uint32_t i : {0u, 1u, 3u}) mesh->add_indices(i);
  return spec;
}

TEST(Service, EveryJobsFullViewFitsInOneMessage) {
  // A job may take max_message_bytes less 65536 (room for its record): one over that is refused
  // naming the field; FULL list pages of large jobs end early instead of outgrowing a message
  // (a GetBakeJob or ListBakeJobs of such jobs failed with "Sent message larger than max").
  TestServer s;
  const int64_t limit = (4 << 20) - 65536;
  v1::JobSpec over = JobOfAbout(limit + 1000, 1);
  ASSERT_GT(int64_t(over.ByteSizeLong()), limit);
  v1::BakeJob ignored;
  const grpc::Status refused = CreateStatus(s, Request(over));
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(refused.error_message().rfind("job: ", 0), 0u) << refused.error_message();
  v1::JobSpec under = JobOfAbout(limit - 2000, 2);
  ASSERT_LE(int64_t(under.ByteSizeLong()), limit);
  const v1::BakeJob big = s.Create(under);
  v1::GetBakeJobRequest get;
  get.set_name(big.name());
  get.set_view(v1::FULL);
  v1::BakeJob full;
  auto c = s.Context();
  const grpc::Status got = s.Jobs()->GetBakeJob(c.get(), get, &full);
  EXPECT_TRUE(got.ok()) << got.error_message();
  EXPECT_EQ(full.job().ByteSizeLong(), under.ByteSizeLong());
  // Three more of 1.5 MB: at most two fit in a page; paging still visits all four, once each.
  for (uint64_t seed = 3; seed < 6; ++seed) s.Create(JobOfAbout(1500000, seed));
  v1::ListBakeJobsRequest list;
  list.set_page_size(5);
  list.set_view(v1::FULL);
  int seen = 0, pages = 0;
  do {
    v1::ListBakeJobsResponse page;
    auto lc = s.Context();
    const grpc::Status listed = s.Jobs()->ListBakeJobs(lc.get(), list, &page);
    ASSERT_TRUE(listed.ok()) << listed.error_message();
    EXPECT_LE(int64_t(page.ByteSizeLong()), 4 << 20);
    EXPECT_GE(page.bake_jobs_size(), 1);
    seen += page.bake_jobs_size();
    ++pages;
    list.set_page_token(page.next_page_token());
  } while (!list.page_token().empty());
  EXPECT_EQ(seen, 4);
  EXPECT_GE(pages, 3);
}

TEST(Service, DrainingIsNotServingAndRefusesNewJobs) {
  TestServer s;
  // An upload in flight keeps the draining server up (up to 2 s) while we look at it.
  std::string data(300000, 'd');
  v1::Digest digest = DigestOf(data);
  auto context = s.Context();
  v1::WriteBlobResponse response;
  auto stub = s.Content();
  auto writer = stub->WriteBlob(context.get(), &response);
  v1::WriteBlobRequest first;
  *first.mutable_digest() = digest;
  first.set_data(data.substr(0, 100000));
  ASSERT_TRUE(writer->Write(first));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::thread stopper([&] { s.Stop(); });
  int health = 1;
  for (int i = 0; i < 100 && health == 1; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    health = s.Health();
  }
  EXPECT_EQ(health, 2);  // NOT_SERVING
  grpc::Status refused = CreateStatus(s, Request(SmallJob(2)));
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::UNAVAILABLE) << refused.error_message();
  // The upload in flight still completes.
  v1::WriteBlobRequest rest;
  rest.set_write_offset(100000);
  rest.set_data(data.substr(100000));
  rest.set_finish_write(true);
  EXPECT_TRUE(writer->Write(rest));
  writer->WritesDone();
  grpc::Status finished = writer->Finish();
  EXPECT_TRUE(finished.ok()) << finished.error_message();
  EXPECT_EQ(response.committed_size(), int64_t(data.size()));
  stopper.join();
}

TEST(Service, WatchersOfADeletedJobGetNotFound) {
  TestServerOptions options;
  options.probeDelay = std::chrono::milliseconds(20);
  TestServer s(options);
  v1::BakeJob running = s.Create(SmallJob(200, 1));
  v1::BakeJob queued = s.Create(SmallJob(10, 2));
  auto context = s.Context();
  v1::WatchBakeJobRequest watch;
  watch.set_name(queued.name());
  auto stub = s.Jobs();
  auto reader = stub->WatchBakeJob(context.get(), watch);
  v1::BakeJob first;
  ASSERT_TRUE(reader->Read(&first));
  EXPECT_EQ(first.state(), v1::BakeJob::QUEUED);
  v1::DeleteBakeJobRequest del;
  del.set_name(queued.name());
  google::protobuf::Empty empty;
  auto c = s.Context();
  ASSERT_TRUE(s.Jobs()->DeleteBakeJob(c.get(), del, &empty).ok());
  v1::BakeJob more;
  while (reader->Read(&more)) {
  }
  grpc::Status status = reader->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND) << status.error_message();
  v1::CancelBakeJobRequest cancel;
  cancel.set_name(running.name());
  v1::BakeJob cancelled;
  auto c2 = s.Context();
  ASSERT_TRUE(s.Jobs()->CancelBakeJob(c2.get(), cancel, &cancelled).ok());
}

TEST(Service, AWatcherThatGoesAwayFromAQueuedJobIsReleasedAtOnce) {
  TestServerOptions options;
  options.probeDelay = std::chrono::milliseconds(20);
  TestServer s(options);
  // 1000 probes x 20 ms: the running job outlasts the wait below by far (it is cancelled at the
  // end), so the queued job cannot start and release its watchers by changing state.
  v1::BakeJob running = s.Create(SmallJob(1000, 1));
  v1::BakeJob queued = s.Create(SmallJob(10, 2));
  {
    auto context = s.Context();
    v1::WatchBakeJobRequest watch;
    watch.set_name(queued.name());
    auto stub = s.Jobs();
    auto reader = stub->WatchBakeJob(context.get(), watch);
    v1::BakeJob first;
    ASSERT_TRUE(reader->Read(&first));
    EXPECT_EQ(first.state(), v1::BakeJob::QUEUED);
    EXPECT_EQ(s.server().jobs().WatcherCount(queued.name()), 1);
    context->TryCancel();  // the client goes away; the queued job does not change meanwhile
    EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::CANCELLED);
  }
  // Released once gRPC has run the call's reactions (OnCancel and the first write's OnWriteDone,
  // in either order, then OnDone) on its executor: milliseconds when idle. The bound is generous
  // for a loaded machine, and far below the running job's 20 s, so a release can only come from
  // the cancellation, never from a change of the queued job. (Before the fix, an OnCancel run
  // before that OnWriteDone was lost and the stream held until the job's next change.)
  auto start = std::chrono::steady_clock::now();
  int count = -1;
  while (count != 0 && SecondsSince(start) < 10) {
    count = s.server().jobs().WatcherCount(queued.name());
    if (count != 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(count, 0) << "the watch stream of a client that left is still held after "
                      << SecondsSince(start) << " s";
  EXPECT_EQ(s.Get(running.name()).state(), v1::BakeJob::RUNNING);
  EXPECT_EQ(s.Get(queued.name()).state(), v1::BakeJob::QUEUED);  // it never changed
  EXPECT_EQ(s.server().jobs().PruneWatchers(), 1);               // the expired entry, dropped
  v1::CancelBakeJobRequest cancel;
  cancel.set_name(running.name());
  v1::BakeJob cancelled;
  auto c = s.Context();
  ASSERT_TRUE(s.Jobs()->CancelBakeJob(c.get(), cancel, &cancelled).ok());
  // A new watcher of the queued job still sees it through.
  EXPECT_EQ(s.WaitFinal(queued.name()).state(), v1::BakeJob::SUCCEEDED);
}

TEST(Service, RunsUpToMaxConcurrentJobsAtOnce) {
  TestServerOptions options;
  options.probeDelay = std::chrono::milliseconds(10);
  options.maxConcurrentJobs = 2;
  TestServer s(options);
  std::vector<v1::BakeJob> jobs;
  for (int i = 0; i < 3; ++i) jobs.push_back(s.Create(SmallJob(40, uint64_t(50 + i))));
  int most = 0;
  for (int poll = 0; poll < 300; ++poll) {
    // One ListBakeJobs call, answered under the manager's lock, is a snapshot: three GetBakeJob
    // calls in a row are not (on a loaded machine the first can see a job still RUNNING and the
    // third, a moment later, the job that took its place).
    v1::ListBakeJobsRequest request;
    request.set_page_size(10);
    v1::ListBakeJobsResponse list;
    auto context = s.Context();
    ASSERT_TRUE(s.Jobs()->ListBakeJobs(context.get(), request, &list).ok());
    ASSERT_EQ(list.bake_jobs_size(), 3);
    int running = 0, final = 0;
    for (const v1::BakeJob& now : list.bake_jobs()) {
      running += now.state() == v1::BakeJob::RUNNING;
      final += now.state() == v1::BakeJob::SUCCEEDED;
    }
    most = std::max(most, running);
    if (final == 3) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(most, 2);
  for (const v1::BakeJob& job : jobs)
    EXPECT_EQ(s.WaitFinal(job.name()).state(), v1::BakeJob::SUCCEEDED);
}

TEST(Service, GarbageAssetsAreRefusedUpFront) {
  TestServer s;
  std::mt19937 rng(99);
  for (const char* format : {"obj", "ply", "glb", "gltf"}) {
    std::string garbage(2000, '\0');
    for (char& c : garbage) c = char(rng());
    v1::Digest digest = s.Upload(garbage);
    v1::JobSpec spec = SmallJob(3);
    v1::Mesh* mesh = spec.mutable_scene()->mutable_meshes(0);
    mesh->clear_positions();
    mesh->clear_indices();
    *mesh->mutable_blob() = digest;
    mesh->set_format(format);
    grpc::Status status = CreateStatus(s, Request(spec));
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
        << format << ": " << status.error_message();
    EXPECT_NE(status.error_message().find("scene.meshes[0]"), std::string::npos)
        << status.error_message();
  }
  EXPECT_EQ(s.Health(), 1);
}

TEST(Service, GarbageRequestsDoNotHurtTheServer) {
  TestServer s;
  grpc::GenericStub stub(s.channel());
  std::mt19937 rng(12345);
  const char* methods[] = {"/probebake.v1.BakeJobs/CreateBakeJob",
                           "/probebake.v1.BakeJobs/GetBakeJob",
                           "/probebake.v1.BakeJobs/ListBakeJobs",
                           "/probebake.v1.ContentStorage/FindMissingBlobs",
                           "/probebake.v1.ContentStorage/QueryWriteStatus",
                           "/probebake.v1.Capabilities/GetCapabilities"};
  // Random bytes, and a valid job with random byte flips (which often still parse).
  std::string valid = Request(SmallJob(3)).SerializeAsString();
  int calls = 0;
  for (int i = 0; i < 300; ++i) {
    std::string payload;
    if (i % 2 == 0) {
      payload.resize(rng() % 200);
      for (char& c : payload) c = char(rng());
    } else {
      payload = valid;
      for (int k = 0; k < 3; ++k) payload[rng() % payload.size()] = char(rng());
    }
    grpc::Slice slice(payload);
    grpc::ByteBuffer request(&slice, 1), response;
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    std::promise<grpc::Status> done;
    stub.UnaryCall(&context, methods[i % std::size(methods)], grpc::StubOptions(), &request,
                   &response, [&](grpc::Status st) { done.set_value(st); });
    grpc::Status status = done.get_future().get();
    EXPECT_NE(status.error_code(), grpc::StatusCode::UNAVAILABLE) << "server died at call " << i;
    if (status.error_code() == grpc::StatusCode::UNAVAILABLE) break;
    ++calls;
  }
  EXPECT_EQ(calls, 300);
  EXPECT_EQ(s.Health(), 1);
}

}  // namespace
}  // namespace probebake::testing
