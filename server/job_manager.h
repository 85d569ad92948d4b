// Bake jobs as long-running operations (docs/service.md): admission (validation, request ids, the
// result cache, the queue bound), scheduling on the oneTBB worker pool, cancellation, progress
// fan-out to watchers, checkpoints and recovery after a restart. Knows nothing of gRPC: errors are
// absl::Status (the service maps them to gRPC codes), watchers implement JobSubscriber.
//
// Durability: a job is committed to the JobStore before CreateJob returns; every state change is
// committed before it is announced. On Start, jobs found RUNNING (the server died) are queued
// again and resume from their last checkpoint; queued jobs stay queued in their order.
//
// Scheduling: a dispatcher thread starts queued jobs in creation order, at most
// maxConcurrentJobs at a time, each as a task of one tbb::task_group in a tbb::task_arena; the
// task runs the backend's Bake with threadsPerJob worker threads. A job is started by the
// dispatcher only, once, so it never runs twice at the same time.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include "absl/status/statusor.h"
#include "probebake/job/limits.h"
#include "probebake/v1/service.pb.h"
#include "runtime/job_state.h"
#include "server/bake_backend.h"
#include "server/checkpoint.h"
#include "server/path_redactor.h"

namespace probebake::server {

class BlobStore;
class JobStore;

// The payload URL under which a RESOURCE_EXHAUSTED status carries its retry delay (decimal
// milliseconds); the service sends it as trailing metadata "retry-after-ms".
inline constexpr const char* kRetryAfterPayload = "probebake.dev/retry-after-ms";

struct JobManagerConfig {
  std::filesystem::path dataDir;  // checkpoints go to dataDir/checkpoints
  JobLimits limits;
  int maxConcurrentJobs = 1;  // >= 1
  int maxQueuedJobs = 64;     // >= 1: queued (not running) jobs before RESOURCE_EXHAUSTED
  int threadsPerJob = 0;      // BakeOptions.threads (0: every hardware thread)
  double progressIntervalSeconds = 0.25;  // BakeOptions.progressIntervalSeconds
  double checkpointIntervalSeconds = 10;  // BakeOptions.checkpointIntervalSeconds
  int defaultPageSize = 50;
  int maxPageSize = 1000;
  // The server's gRPC message limit (ServerCapabilities.max_message_bytes): a job's spec may use
  // all of it but kJobRecordReserve, so that its FULL view fits in one response; list pages stop
  // short of it.
  int64_t maxMessageBytes = int64_t(4) << 20;
};

// A WatchBakeJob stream. Called with the manager's lock held, from any thread: implementations
// must not block and must not call back into the manager (not even from gRPC reactions that run
// inline in a call made here).
//
// The manager holds subscribers weakly: the stream's owner (the gRPC reactor) keeps it alive, and
// when the call ends (client gone, OnDone) the stream is freed at once, whether or not the job
// changes again. The manager's entry for it is then an expired weak pointer, dropped by the next
// Subscribe or update of that job, or by PruneWatchers().
class JobSubscriber {
 public:
  virtual ~JobSubscriber() = default;
  // A new state of the job (BASIC view). After a final state no more calls come.
  virtual void OnJobUpdate(const v1::BakeJob& job) = 0;
  // The stream must end with `status` (NOT_FOUND: deleted; UNAVAILABLE: shutting down).
  virtual void OnJobGone(const absl::Status& status) = 0;
  // True once the stream ended on its own (client gone): the manager then forgets it.
  virtual bool Detached() const = 0;
};

class JobManager {
 public:
  JobManager(JobManagerConfig config, BlobStore* blobs, JobStore* store, BakeBackend backend);
  ~JobManager();  // Shutdown() if still running
  JobManager(const JobManager&) = delete;
  JobManager& operator=(const JobManager&) = delete;

  // Recovers the queue from the store and starts the dispatcher.
  absl::Status Start();
  // Drains: new jobs are refused (UNAVAILABLE), running jobs are cancelled and queued again (their
  // checkpoints kept), watchers end with UNAVAILABLE. Returns once no job task runs. Idempotent.
  void Shutdown();
  bool draining() const { return draining_.load(); }

  absl::StatusOr<v1::BakeJob> CreateJob(const v1::CreateBakeJobRequest& request);
  absl::StatusOr<v1::BakeJob> GetJob(const std::string& name, v1::BakeJobView view);
  absl::StatusOr<v1::ListBakeJobsResponse> ListJobs(const v1::ListBakeJobsRequest& request);
  absl::StatusOr<v1::BakeJob> CancelJob(const std::string& name);
  absl::Status DeleteJob(const std::string& name);

  // Hands `subscriber` the job as it is now (OnJobUpdate, called before this returns) and, when
  // that state is not final, registers it (weakly: the caller owns it) for every later state.
  // Subscribers whose stream ended (JobSubscriber::Detached, or freed by their owner) are dropped
  // at the next update.
  absl::Status Subscribe(const std::string& name, const std::shared_ptr<JobSubscriber>& subscriber);
  // Watch streams of job `name` still registered and alive (not freed by their owner).
  int WatcherCount(const std::string& name);
  // Forgets the entries of every freed watch stream; returns how many.
  int PruneWatchers();

  const JobManagerConfig& config() const { return config_; }

  // For the garbage collector: the result volumes stored as blobs whose jobs' records do not
  // refer to them yet (a job between importing its volume and storing its end), and the start of
  // the earliest volume import still under way (now when none is). A blob stored or touched
  // since then is newer than it (BlobStore stamps a blob's time when it is stored).
  std::set<std::string> VolumesNotYetReferenced(std::filesystem::file_time_type* importsSince);

 private:
  enum class CancelReason : int { kNone = 0, kUser = 1, kShutdown = 2 };
  struct RunningJob {
    std::string name;
    v1::BakeJob record;  // guarded by mutex_
    std::atomic<bool> cancel{false};
    std::atomic<int> reason{int(CancelReason::kNone)};
    v1::JobSpec spec;  // as stored, read by LoadJob
    int64_t probesResumed = 0;
    // Work of earlier attempts (from the checkpoint resumed), and this attempt's as of its last
    // progress report (Bake reports progress right before every checkpoint); mutex_ guards both.
    BakeWork carried, attempt;
  };

  void DispatchLoop();
  // How a run ended: the state to commit (QUEUED when requeued at shutdown) and its payload.
  struct Outcome {
    v1::BakeJob::State state = v1::BakeJob::FAILED;
    v1::BakeJobError error;
    v1::BakeJobResult result;
  };
  void RunJob(const std::shared_ptr<RunningJob>& job);

  // A run of a job, stage by stage: LoadJob, ReadResumePoint, BakeVolume, CountEveryAttempt,
  // StoreVolume, then Succeeded, or Stopped at the first stage that returns an error. A stage
  // returns CANCELLED only when job.cancel stopped it.
  Outcome Execute(RunningJob& job);
  // The BakeJob built from the job's stored spec. The record's job digest becomes the one built
  // (a baker changed since the job was accepted gives a new digest; its checkpoint, made for the
  // old one, is then not resumed).
  absl::StatusOr<BakeJob> LoadJob(RunningJob& job);
  // The checkpoint of the job for `jobDigest`, when one is on disk and whole; sets
  // job.probesResumed and job.carried from it. A checkpoint that cannot be used is logged and
  // ignored: the bake starts over.
  std::optional<Checkpoint> ReadResumePoint(RunningJob& job, const std::string& jobDigest);
  // Bakes `built` with the backend, resuming from `checkpoint` when there is one (freed when the
  // bake ends), reporting progress (OnProgress) and writing checkpoints (OnCheckpoint) as the
  // config's intervals say.
  absl::StatusOr<ProbeVolume> BakeVolume(RunningJob& job, const BakeJob& built,
                                         std::optional<Checkpoint> checkpoint);
  // Bake counts this attempt only: adds the work of earlier attempts (job.carried) to the
  // volume's stats, so the volume's metadata and the result count every attempt (threads,
  // probes and invalidProbes describe the volume as it is). Returns the stats.
  BakeStats CountEveryAttempt(RunningJob& job, ProbeVolume& volume);
  // Writes the volume (its planes the file does not hold are freed first) and imports it into the
  // blob store; the blob's digest. A full disk must not cost the bake (hours, on a farm): on
  // RESOURCE_EXHAUSTED the volume stays in memory and the write is retried with backoff, the job
  // RUNNING with progress.waiting saying why, until space returns, the job is cancelled, or the
  // server stops (the job runs again after the restart, from its checkpoint). Any other error is
  // returned.
  absl::StatusOr<v1::Digest> StoreVolume(RunningJob& job, ProbeVolume& volume,
                                         const VolumeMetadata& meta);
  // One write of the volume to `tmp` and its import. The garbage collector knows of the volume
  // from before the import until Finish has stored the job's end, which refers to it
  // (VolumesNotYetReferenced).
  absl::StatusOr<v1::Digest> WriteAndImportVolume(const std::filesystem::path& tmp,
                                                  const ProbeVolume& volume,
                                                  const VolumeMetadata& meta);
  // How a run stopped by `status` at `stage` ends: QUEUED when the server's shutdown cancelled it
  // (it runs again after the restart), CANCELLED when a client did, FAILED otherwise (logged).
  Outcome Stopped(RunningJob& job, const absl::Status& status, std::string_view stage);
  // A SUCCEEDED run of job `name`: its volume blob and stats.
  static Outcome Succeeded(const std::string& name, const v1::Digest& volume,
                           const BakeStats& stats);

  void OnProgress(RunningJob& job, const BakeProgress& progress);
  void OnCheckpoint(RunningJob& job, const std::string& jobDigest, const ProbeVolume& volume,
                    const std::vector<uint8_t>& done);
  // Sets progress.waiting (why a running job is not advancing; empty: it is) and announces a
  // change; mutex_ held.
  void SetWaitingLocked(RunningJob& job, const std::string& why);
  // Commits the record of a job leaving RUNNING (and its cache entry) and announces it.
  void Finish(RunningJob& job, const Outcome& outcome);

  // DeleteJob but for the backend's release: the record, queue entry, checkpoint and watchers go
  // (takes mutex_).
  absl::Status ForgetJob(const std::string& name);
  absl::Status ValidateForServer(const v1::JobSpec& spec) const;
  absl::StatusOr<std::string> CheckName(const std::string& name) const;
  // DB record overlaid with live progress; mutex_ held.
  absl::StatusOr<std::optional<v1::BakeJob>> LoadLocked(const std::string& name, bool full);
  void NotifyLocked(const v1::BakeJob& record);
  void EndSubscribersLocked(const std::string& name, const absl::Status& status);
  int64_t RetryDelayMsLocked() const;
  std::filesystem::path CheckpointPath(const std::string& name) const;

  JobManagerConfig config_;
  BlobStore* blobs_;
  JobStore* store_;
  BakeBackend backend_;

  std::mutex mutex_;
  std::condition_variable wake_;      // dispatcher: queue or slots changed, or stopping
  std::condition_variable jobsIdle_;  // running_ became empty
  // Running jobs waiting out a backoff (the store or the volume cannot be written): a job was
  // cancelled, or stopping. Apart from wake_, whose notify_one must reach the dispatcher.
  std::condition_variable backoff_;
  // VolumesNotYetReferenced's: imports under way (their start times) and volumes imported whose
  // jobs' ends are not stored yet.
  std::mutex volumesMutex_;
  std::multiset<std::filesystem::file_time_type> importsUnderWay_;
  std::multiset<std::string> volumesNotYetReferenced_;
  std::vector<std::string> queue_;  // names of QUEUED jobs, creation order
  std::map<std::string, std::shared_ptr<RunningJob>> running_;
  std::multimap<std::string, std::weak_ptr<JobSubscriber>> subscribers_;
  bool stopping_ = false;
  std::atomic<bool> draining_{false};

  std::unique_ptr<tbb::global_control> parallelism_;
  // maxConcurrentJobs worker slots plus one slot reserved for the dispatcher, so spawning a job
  // never waits for a running one.
  tbb::task_arena arena_;
  const PathRedactor redact_;  // job errors and waiting texts name the data folder as DATA
  tbb::task_group tasks_;
  std::thread dispatcher_;
};

}  // namespace probebake::server
