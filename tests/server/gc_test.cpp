// The data folder's garbage collection (server/garbage_collector.h) through the service: what a
// deleted job leaves goes once nothing refers to it and its grace period has passed, and
// nothing a job or a client relies on goes.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <future>
#include <memory>
#include <thread>

#include "probebake/job/digest.h"
#include "server/garbage_collector.h"
#include "test_server.h"

namespace probebake::testing {
namespace {

namespace fs = std::filesystem;

fs::path BlobFile(const TestServer& s, const v1::Digest& digest) {
  return s.dataDir() / "blobs" / digest.hash().substr(0, 2) / digest.hash();
}

fs::path PartialFile(const TestServer& s, const v1::Digest& digest) {
  return s.dataDir() / "uploads" / (digest.hash() + "_" + std::to_string(digest.size_bytes()));
}

// Makes `path` look last used `minutes` ago.
void AgeMinutes(const fs::path& path, int minutes) {
  std::error_code ec;
  fs::last_write_time(path, fs::file_time_type::clock::now() - std::chrono::minutes(minutes), ec);
  ASSERT_FALSE(ec) << path << ": " << ec.message();
}

// Past the test server's grace period of 1 h.
void Age(const fs::path& path, int hours) {
  AgeMinutes(path, 60 * hours);
}

server::GcReport Collect(TestServer& s) {
  absl::StatusOr<server::GcReport> report = s.server().gc().CollectNow();
  EXPECT_TRUE(report.ok()) << report.status();
  return report.ok() ? *report : server::GcReport{};
}

// SmallJob with a second mesh read from an uploaded OBJ blob.
v1::JobSpec JobWithMeshBlob(const v1::Digest& obj, int probes, uint64_t seed) {
  v1::JobSpec spec = SmallJob(probes, seed);
  v1::Mesh* mesh = spec.mutable_scene()->add_meshes();
  mesh->set_name("box");
  mesh->set_material("white");
  mesh->set_format("obj");
  *mesh->mutable_blob() = obj;
  return spec;
}

const std::string kQuadObj = "v 3 3 0.5\nv 4 3 0.5\nv 4 4 0.5\nv 3 4 0.5\nf 1 2 3 4\n";

void Delete(TestServer& s, const std::string& name) {
  v1::DeleteBakeJobRequest request;
  request.set_name(name);
  google::protobuf::Empty empty;
  auto c = s.Context();
  ASSERT_TRUE(s.Jobs()->DeleteBakeJob(c.get(), request, &empty).ok());
}

TEST(GarbageCollection, ADeletedJobsVolumeAndInputsGoOnceUnused) {
  TestServer s;
  const v1::Digest obj = s.Upload(kQuadObj);
  const v1::BakeJob job = s.WaitFinal(s.Create(JobWithMeshBlob(obj, 3, 41)).name());
  ASSERT_EQ(job.state(), v1::BakeJob::SUCCEEDED) << job.DebugString();
  const v1::Digest volume = job.result().volume();
  Age(BlobFile(s, obj), 2);
  Age(BlobFile(s, volume), 2);

  // Referenced by a job: kept however old.
  server::GcReport report = Collect(s);
  EXPECT_EQ(report.liveBlobs, 2);
  EXPECT_EQ(report.blobs, 0);
  EXPECT_TRUE(fs::exists(BlobFile(s, obj)));
  EXPECT_TRUE(fs::exists(BlobFile(s, volume)));

  // Deleted: both go, and the cache entry with its volume.
  Delete(s, job.name());
  report = Collect(s);
  EXPECT_EQ(report.liveBlobs, 0);
  EXPECT_EQ(report.blobs, 2);
  EXPECT_EQ(report.blobBytes, obj.size_bytes() + volume.size_bytes());
  EXPECT_EQ(report.cacheEntries, 1);
  EXPECT_FALSE(fs::exists(BlobFile(s, obj)));
  EXPECT_FALSE(fs::exists(BlobFile(s, volume)));

  // The same job again is baked anew (its inputs uploaded again), not served from a cache entry
  // whose volume is gone.
  s.Upload(kQuadObj);
  const v1::BakeJob again = s.WaitFinal(s.Create(JobWithMeshBlob(obj, 3, 41)).name());
  ASSERT_EQ(again.state(), v1::BakeJob::SUCCEEDED);
  EXPECT_FALSE(again.result().cached_result());
  EXPECT_EQ(s.bakeStats().bakes.load(), 2);
  ExpectFakeVolume(s.Download(again.result().volume()), 3, 41);
}

TEST(GarbageCollection, AVolumeStaysWhileAnyJobRefersToIt) {
  // A job served from the cache refers to the first job's volume: deleting the first job frees
  // nothing, and the cache goes on serving it.
  TestServer s;
  const v1::BakeJob first = s.WaitFinal(s.Create(SmallJob(3, 42)).name());
  ASSERT_EQ(first.state(), v1::BakeJob::SUCCEEDED);
  const v1::BakeJob second = s.Create(SmallJob(3, 42));
  ASSERT_TRUE(second.result().cached_result());
  Delete(s, first.name());
  Age(BlobFile(s, first.result().volume()), 2);
  const server::GcReport report = Collect(s);
  EXPECT_EQ(report.blobs, 0);
  EXPECT_EQ(report.cacheEntries, 0);
  ExpectFakeVolume(s.Download(second.result().volume()), 3, 42);
  EXPECT_TRUE(s.Create(SmallJob(3, 42)).result().cached_result());
  EXPECT_EQ(s.bakeStats().bakes.load(), 1);
}

TEST(GarbageCollection, AVolumeWhoseJobsEndIsNotStoredYetStays) {
  // The job store cannot be written as a bake ends (another connection takes its write lock
  // just before the volume is written), so the imported volume waits for its job's end to be
  // stored, referred to by no record. A collection meanwhile must keep it, however old it looks.
  // (It took it, and the job then SUCCEEDED with a volume that was gone.)
  TempDir dir;
  const std::filesystem::path dataDir = dir.path() / "data";
  LockStoreAtVolumeWrite lock;
  TestServerOptions options;
  lock.Arm(&options, dataDir);
  TestServer s(options, dataDir);
  const v1::BakeJob created = s.Create(SmallJob(4, 43));
  auto watched = std::async(std::launch::async, [&] { return s.WaitFinal(created.name()); });
  ASSERT_TRUE(lock.WaitTaken(std::chrono::seconds(20)));
  // Once the end's first try has failed (the job says so), the volume waits for it, however long
  // (made to look old below).
  ASSERT_NE(s.WaitUntilWaiting(created.name()), "");
  fs::path volumeFile;  // the only blob: SmallJob has no input files
  std::error_code ec;
  for (const auto& entry : fs::recursive_directory_iterator(dataDir / "blobs", ec))
    if (entry.is_regular_file()) volumeFile = entry.path();
  ASSERT_FALSE(volumeFile.empty());
  Age(volumeFile, 2);
  const server::GcReport report = Collect(s);
  EXPECT_EQ(report.blobs, 0);
  EXPECT_EQ(report.liveBlobs, 1);
  EXPECT_TRUE(fs::exists(volumeFile));
  lock.Release();
  const v1::BakeJob final = watched.get();
  ASSERT_EQ(final.state(), v1::BakeJob::SUCCEEDED) << final.DebugString();
  EXPECT_EQ(final.result().volume().hash(), volumeFile.filename().string());
  ExpectFakeVolume(s.Download(final.result().volume()), 4, 43);
}

TEST(GarbageCollection, TheGracePeriodKeepsBlobsInUse) {
  // An upload no job refers to yet is kept for the grace period (1 h here) after its last use;
  // FindMissingBlobs finding it counts as a use, since the client then relies on it.
  TestServer s;
  const v1::Digest blob = s.Upload("bytes a client is about to use");
  EXPECT_EQ(Collect(s).blobs, 0);
  Age(BlobFile(s, blob), 2);
  v1::FindMissingBlobsRequest find;
  *find.add_blob_digests() = blob;
  v1::FindMissingBlobsResponse missing;
  auto c1 = s.Context();
  ASSERT_TRUE(s.Content()->FindMissingBlobs(c1.get(), find, &missing).ok());
  EXPECT_EQ(missing.missing_blob_digests_size(), 0);
  EXPECT_EQ(Collect(s).blobs, 0);
  EXPECT_TRUE(fs::exists(BlobFile(s, blob)));

  Age(BlobFile(s, blob), 2);
  const server::GcReport report = Collect(s);
  EXPECT_EQ(report.blobs, 1);
  EXPECT_EQ(report.blobBytes, blob.size_bytes());
  auto c2 = s.Context();
  ASSERT_TRUE(s.Content()->FindMissingBlobs(c2.get(), find, &missing).ok());
  EXPECT_EQ(missing.missing_blob_digests_size(), 1);
}

TEST(GarbageCollection, AbandonedPartialUploadsGoAndOpenOnesStay) {
  TestServer s;
  const std::string data(4000, 'p');
  const v1::Digest digest = DigestOf(data);
  {
    auto context = s.Context();
    v1::WriteBlobResponse response;
    auto stub = s.Content();
    auto writer = stub->WriteBlob(context.get(), &response);
    v1::WriteBlobRequest request;
    *request.mutable_digest() = digest;
    request.set_data(data.substr(0, 1000));
    ASSERT_TRUE(writer->Write(request));
    for (int i = 0; i < 500 && !fs::exists(PartialFile(s, digest)); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    Age(PartialFile(s, digest), 2);
    EXPECT_EQ(Collect(s).partials, 0);  // the upload is open
    EXPECT_TRUE(fs::exists(PartialFile(s, digest)));
    writer->WritesDone();
    EXPECT_FALSE(writer->Finish().ok());  // incomplete: the bytes are kept for a resume
  }
  // Abandoned within the grace period: kept for the client to resume.
  AgeMinutes(PartialFile(s, digest), 30);
  EXPECT_EQ(Collect(s).partials, 0);
  ASSERT_TRUE(fs::exists(PartialFile(s, digest)));
  Age(PartialFile(s, digest), 2);
  // The server may still be closing the upload: collected once it has.
  server::GcReport report;
  for (int i = 0; i < 100 && report.partials == 0; ++i) {
    report = Collect(s);
    if (report.partials == 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(report.partials, 1);
  EXPECT_EQ(report.partialBytes, 1000);
  EXPECT_FALSE(fs::exists(PartialFile(s, digest)));
}

TEST(GarbageCollection, BlobsOfSpecFindsEveryDigest) {
  v1::JobSpec spec = JobWithMeshBlob(DigestOf("mesh"), 2, 1);
  *spec.mutable_scene()->mutable_environment()->mutable_map()->mutable_blob() = DigestOf("sky");
  EXPECT_EQ(server::BlobsOfSpec(spec),
            (std::set<std::string>{DigestOf("mesh").hash(), DigestOf("sky").hash()}));
  EXPECT_TRUE(server::BlobsOfSpec(SmallJob(2)).empty());
}

}  // namespace
}  // namespace probebake::testing
