// Frees the data folder of what no job needs: stored blobs that no job in the store refers to
// (as an input of its spec or as its result volume), partial uploads abandoned by their clients,
// and result-cache entries whose volume is gone.
//
// Deleting a job is how space is reclaimed: its inputs and volume go once no other job refers to
// them and they have not been used for `grace` (stored, touched by FindMissingBlobs or an
// upload of the same bytes, referenced by a new job, or served from the result cache). The grace
// period protects a client between uploading its files and creating the job that uses them, and
// keeps a cached volume while identical jobs keep arriving. A result-cache entry lives as long as
// its volume.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "absl/status/statusor.h"
#include "probebake/v1/job.pb.h"

namespace probebake::server {

class BlobStore;
class JobStore;

struct GcConfig {
  // How long an unreferenced blob or a partial upload is kept after its last use; at least
  // kMinGrace (it also covers the moments between a client's FindMissingBlobs or a cache hit and
  // the job that then refers to the blob).
  std::chrono::seconds grace{std::chrono::hours(24)};
  static constexpr std::chrono::seconds kMinGrace{60};
  // How often the server collects by itself; 0: never (CollectNow only).
  std::chrono::seconds interval{std::chrono::hours(1)};
};

struct GcReport {
  int64_t liveBlobs = 0;                   // distinct blobs the jobs in the store refer to
  int64_t blobs = 0, blobBytes = 0;        // stored blobs removed
  int64_t partials = 0, partialBytes = 0;  // partial uploads removed
  int64_t cacheEntries = 0;                // result-cache entries dropped
};

// The hashes of every Digest in `spec` (each blob a job reads).
std::set<std::string> BlobsOfSpec(const v1::JobSpec& spec);

// Blobs in use that no job record refers to yet, and the time since which a blob stored or
// touched may be one of them (JobManager::VolumesNotYetReferenced).
using PendingBlobs = std::function<std::set<std::string>(std::filesystem::file_time_type* since)>;

class GarbageCollector {
 public:
  // The stores must outlive the collector, as must what `pending` calls.
  GarbageCollector(JobStore* jobs, BlobStore* blobs, PendingBlobs pending, GcConfig config);
  ~GarbageCollector();  // Stop()
  GarbageCollector(const GarbageCollector&) = delete;
  GarbageCollector& operator=(const GarbageCollector&) = delete;

  // Called after every periodic collection (before Start only), e.g. to take back disk space
  // held in reserve once the collection freed some.
  void SetAfterCollection(std::function<void()> after) { after_ = std::move(after); }
  // Collects every config.interval on a thread of its own (nothing when the interval is 0).
  void Start();
  // Ends that thread; a collection under way finishes first.
  void Stop();
  // One collection now (serialized with the periodic ones). Logged at info when it removed
  // something. Errors: the job store could not be read (nothing is removed then).
  absl::StatusOr<GcReport> CollectNow();

 private:
  void Loop();

  JobStore* jobs_;
  BlobStore* blobs_;
  PendingBlobs pending_;
  GcConfig config_;
  std::function<void()> after_;
  std::mutex collecting_;  // one collection at a time
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace probebake::server
