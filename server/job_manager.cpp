#include "server/job_manager.h"

#include <openssl/rand.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>

#include <google/protobuf/util/message_differencer.h>
#include <google/protobuf/util/time_util.h>

#include "absl/cleanup/cleanup.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "probebake/base/check.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/validate.h"
#include "probebake/volume/vdb_io.h"
#include "server/blob_store.h"
#include "server/checkpoint.h"
#include "server/job_store.h"

namespace probebake::server {
namespace {

using google::protobuf::util::TimeUtil;

constexpr absl::string_view kNamePrefix = "bakeJobs/";
constexpr size_t kIdLength = 16;
constexpr size_t kMaxRequestIdLength = 128;
// Backoff while the job store cannot be written (a full disk): the first wait, and the longest.
constexpr std::chrono::seconds kStoreRetryFirst{1};
constexpr std::chrono::seconds kStoreRetryMax{30};

// The wait after `backoff`: doubled, up to kStoreRetryMax.
std::chrono::seconds NextBackoff(std::chrono::seconds backoff) {
  return std::min(2 * backoff, kStoreRetryMax);
}

google::protobuf::Timestamp Now() {
  return TimeUtil::GetCurrentTime();
}

google::protobuf::Duration SecondsToDuration(double seconds) {
  return TimeUtil::NanosecondsToDuration(int64_t(std::llround(seconds * 1e9)));
}

std::string NewJobName() {
  unsigned char bytes[kIdLength / 2];
  PB_CHECK(RAND_bytes(bytes, sizeof(bytes)) == 1);
  return absl::StrCat(kNamePrefix, absl::BytesToHexString(absl::string_view(
                                       reinterpret_cast<const char*>(bytes), sizeof(bytes))));
}

// A name quoted for a message, bounded and escaped (it is client input).
std::string Quoted(absl::string_view text) {
  std::string shown = absl::CHexEscape(text.substr(0, 80));
  if (text.size() > 80) shown += "...";
  return absl::StrCat("\"", shown, "\"");
}

v1::BakeJobError ErrorOf(const absl::Status& status, std::string_view stage) {
  v1::BakeJobError error;
  error.set_code(int(status.code()));
  error.set_message(std::string(status.message()));
  (*error.mutable_details())["stage"] = std::string(stage);
  if (absl::IsInvalidArgument(status)) {
    std::string message(status.message());
    size_t colon = message.find(": ");
    if (colon != std::string::npos && message.find_first_of(" \n") > colon)
      (*error.mutable_details())["field"] = message.substr(0, colon);
  }
  return error;
}

std::string PageToken(int64_t afterSeq) {
  return absl::WebSafeBase64Escape(absl::StrCat("after:", afterSeq));
}

absl::StatusOr<int64_t> ParsePageToken(const std::string& token) {
  if (token.empty()) return 0;
  std::string decoded;
  int64_t seq = 0;
  if (!absl::WebSafeBase64Unescape(token, &decoded) || decoded.rfind("after:", 0) != 0 ||
      !absl::SimpleAtoi(absl::string_view(decoded).substr(6), &seq) || seq < 0)
    return FieldError("pageToken", "not a token this server issued");
  return seq;
}

}  // namespace

JobManager::JobManager(JobManagerConfig config, BlobStore* blobs, JobStore* store,
                       BakeBackend backend)
    : config_(std::move(config)),
      blobs_(blobs),
      store_(store),
      backend_(std::move(backend)),
      arena_(std::max(1, config_.maxConcurrentJobs) + 1, 1),
      redact_(config_.dataDir) {
  PB_CHECK_GE(config_.maxConcurrentJobs, 1);
  PB_CHECK_GE(config_.maxQueuedJobs, 1);
  // Every running job holds one worker for its task and asks Bake for threadsPerJob threads;
  // TBB's default pool (hardware threads - 1 workers) would leave concurrent bakes starved.
  int perJob =
      config_.threadsPerJob > 0 ? config_.threadsPerJob : tbb::this_task_arena::max_concurrency();
  size_t wanted = size_t(config_.maxConcurrentJobs) * size_t(std::max(1, perJob)) + 1;
  if (wanted > tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism))
    parallelism_ =
        std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, wanted);
}

JobManager::~JobManager() {
  Shutdown();
}

std::filesystem::path JobManager::CheckpointPath(const std::string& name) const {
  return CheckpointFilePath(config_.dataDir, name);
}

absl::Status JobManager::Start() {
  std::error_code ec;
  std::filesystem::create_directories(config_.dataDir / "checkpoints", ec);
  if (ec) return absl::InternalError(absl::StrCat("create checkpoints folder: ", ec.message()));
  // The server stopped while these ran: queue them again, ahead of the jobs queued after them
  // (creation order), to resume from their checkpoints.
  PB_ASSIGN_OR_RETURN(std::vector<StoredJob> interrupted,
                      store_->ListInState(v1::BakeJob::RUNNING));
  for (StoredJob& job : interrupted) {
    job.record.set_state(v1::BakeJob::QUEUED);
    *job.record.mutable_update_time() = Now();
    PB_RETURN_IF_ERROR(store_->Update(job.record));
    Logger("jobs")->info("{}: requeued (it was running when the server stopped)",
                         job.record.name());
  }
  PB_ASSIGN_OR_RETURN(std::vector<StoredJob> queued, store_->ListInState(v1::BakeJob::QUEUED));
  std::lock_guard lock(mutex_);
  for (const StoredJob& job : queued) queue_.push_back(job.record.name());
  if (!queued.empty()) Logger("jobs")->info("{} queued job(s) recovered", queued.size());
  dispatcher_ = std::thread([this] { DispatchLoop(); });
  return absl::OkStatus();
}

void JobManager::Shutdown() {
  {
    std::lock_guard lock(mutex_);
    draining_ = true;
    if (stopping_) return;
    stopping_ = true;
    for (auto& [name, job] : running_) {
      int none = int(CancelReason::kNone);
      job->reason.compare_exchange_strong(none, int(CancelReason::kShutdown));
      job->cancel = true;
      Logger("jobs")->info("{}: stopping for shutdown (will resume after restart)", name);
    }
  }
  wake_.notify_all();
  backoff_.notify_all();
  if (dispatcher_.joinable()) dispatcher_.join();
  auto start = std::chrono::steady_clock::now();
  {
    std::unique_lock lock(mutex_);
    jobsIdle_.wait(lock, [&] { return running_.empty(); });
  }
  arena_.execute([&] { tasks_.wait(); });
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  Logger("jobs")->info("job workers stopped in {:.3f} s", seconds);
  std::lock_guard lock(mutex_);
  for (auto& [name, weak] : subscribers_) {
    if (std::shared_ptr<JobSubscriber> subscriber = weak.lock())
      subscriber->OnJobGone(absl::UnavailableError(
          "the server is shutting down; watch the job again once it is back"));
  }
  subscribers_.clear();
}

absl::StatusOr<std::string> JobManager::CheckName(const std::string& name) const {
  bool ok = name.size() == kNamePrefix.size() + kIdLength && absl::StartsWith(name, kNamePrefix) &&
            std::all_of(name.begin() + kNamePrefix.size(), name.end(),
                        [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
  if (!ok)
    return FieldError("name",
                      absl::StrCat("expected \"bakeJobs/<16 hex digits>\", got ", Quoted(name)));
  return name;
}

absl::Status JobManager::ValidateForServer(const v1::JobSpec& spec) const {
  std::vector<std::string> refusals;
  for (const FileReference& ref : ListFileReferences(spec))
    refusals.push_back(ClientPathRefusal(ref.fieldPath));
  if (!refusals.empty()) return absl::InvalidArgumentError(absl::StrJoin(refusals, "\n"));
  PB_RETURN_IF_ERROR(ValidateJobSpec(spec, config_.limits));

  std::vector<std::string> missing;
  auto check = [&](const v1::Digest& digest, const std::string& field) {
    if (!blobs_->Touch(digest)) missing.push_back(absl::StrCat(field, " ", DigestString(digest)));
  };
  for (const BlobReference& ref : ListBlobReferences(spec)) check(ref.digest, ref.fieldPath);
  if (!missing.empty())
    return absl::FailedPreconditionError(absl::StrCat(
        "missing blobs (upload them with WriteBlob, then retry): ", absl::StrJoin(missing, "; ")));
  return absl::OkStatus();
}

int64_t JobManager::RetryDelayMsLocked() const {
  // A queue slot frees when a running job ends: the soonest ETA, within [1 s, 60 s].
  double soonest = 5.0;
  bool known = false;
  for (const auto& [name, job] : running_) {
    if (!job->record.progress().has_eta()) continue;
    double eta = TimeUtil::DurationToMilliseconds(job->record.progress().eta()) / 1000.0;
    soonest = known ? std::min(soonest, eta) : eta;
    known = true;
  }
  return int64_t(std::clamp(soonest, 1.0, 60.0) * 1000);
}

absl::StatusOr<v1::BakeJob> JobManager::CreateJob(const v1::CreateBakeJobRequest& request) {
  auto unavailable = [] {
    return absl::UnavailableError("the server is shutting down; submit again once it is back");
  };
  if (draining_) return unavailable();
  const std::string& requestId = request.request_id();
  if (requestId.size() > kMaxRequestIdLength)
    return FieldError("requestId",
                      absl::StrCat("longer than ", kMaxRequestIdLength, " characters"));
  if (!std::all_of(requestId.begin(), requestId.end(),
                   [](char c) { return c >= 0x20 && c < 0x7f; }))
    return FieldError("requestId", "only printable ASCII characters are allowed");
  // mutex_ held.
  auto findRequest = [&]() -> absl::StatusOr<std::optional<v1::BakeJob>> {
    if (requestId.empty()) return std::optional<v1::BakeJob>();
    PB_ASSIGN_OR_RETURN(std::optional<StoredJob> existing, store_->FindByRequestId(requestId));
    if (!existing) return std::optional<v1::BakeJob>();
    // An idempotency key names one request: reused for another job it is a client's mistake
    // (a copied id, a script that fixes it), and answering with the first job would report a
    // bake of something the client did not ask for.
    const std::string& name = existing->record.name();
    PB_ASSIGN_OR_RETURN(std::optional<v1::JobSpec> spec, store_->GetSpec(name));
    if (!spec || !google::protobuf::util::MessageDifferencer::Equals(*spec, request.job()) ||
        existing->record.skip_cache() != request.skip_cache())
      return FieldError("requestId", absl::StrCat("\"", requestId, "\" was already used by ", name,
                                                  " for a different request; a request id "
                                                  "names one request, use a new one"));
    return LoadLocked(name, false);
  };
  {
    std::lock_guard lock(mutex_);
    PB_ASSIGN_OR_RETURN(std::optional<v1::BakeJob> existing, findRequest());
    if (existing) return *existing;
  }
  if (!request.has_job()) return FieldError("job", "required");
  if (const int64_t bytes = int64_t(request.job().ByteSizeLong()),
      limit = config_.maxMessageBytes - runtime::kJobRecordReserve;
      bytes > limit)
    return FieldError(
        "job",
        absl::StrCat(bytes, " bytes, over the ", limit, " a job may take (max_message_bytes less ",
                     runtime::kJobRecordReserve, " for its record); put large meshes in files"));
  PB_RETURN_IF_ERROR(ValidateForServer(request.job()));
  // Reads every asset, so a mesh or map that does not parse is refused now, not mid-bake; the
  // built job also gives the digest that keys the result cache.
  PB_ASSIGN_OR_RETURN(BakeJob built, backend_.build(request.job()));

  std::lock_guard lock(mutex_);
  if (draining_) return unavailable();
  {
    PB_ASSIGN_OR_RETURN(std::optional<v1::BakeJob> existing, findRequest());
    if (existing) return *existing;  // the same request id raced with this one
  }
  v1::BakeJob record;
  record.set_request_id(requestId);
  record.set_job_digest(built.jobDigest);
  record.set_skip_cache(request.skip_cache());
  *record.mutable_create_time() = Now();
  *record.mutable_update_time() = record.create_time();

  std::optional<v1::BakeJobResult> cached;
  if (!request.skip_cache()) {
    PB_ASSIGN_OR_RETURN(cached, store_->GetCached(built.jobDigest));
    if (cached && !blobs_->Touch(cached->volume())) {
      Logger("jobs")->warn("result cache entry {} refers to missing volume {}; dropped",
                           built.jobDigest, DigestString(cached->volume()));
      PB_RETURN_IF_ERROR(store_->DeleteCached(built.jobDigest));
      cached.reset();
    }
  }
  if (cached) {
    record.set_state(v1::BakeJob::SUCCEEDED);
    *record.mutable_result() = *cached;
    record.mutable_result()->set_cached_result(true);
    v1::BakeJobProgress* progress = record.mutable_progress();
    progress->set_probes_done(cached->stats().probes());
    progress->set_probes_total(cached->stats().probes());
    progress->set_samples(cached->stats().samples());
    progress->set_rays(cached->stats().rays());
    *record.mutable_end_time() = record.create_time();
  } else {
    if (int64_t(queue_.size()) >= config_.maxQueuedJobs) {
      int64_t retryMs = RetryDelayMsLocked();
      absl::Status full = absl::ResourceExhaustedError(
          absl::StrCat("the job queue is full (", queue_.size(), " queued, ", running_.size(),
                       " running); retry in ", retryMs, " ms"));
      full.SetPayload(kRetryAfterPayload, absl::Cord(absl::StrCat(retryMs)));
      return full;
    }
    record.set_state(v1::BakeJob::QUEUED);
  }
  // Ids are random: a collision is astronomically unlikely, but costs only a retry.
  absl::Status inserted;
  for (int attempt = 0; attempt < 4; ++attempt) {
    record.set_name(NewJobName());
    inserted = store_->Insert(record, request.job());
    if (!absl::IsAlreadyExists(inserted)) break;
  }
  PB_RETURN_IF_ERROR(inserted);
  if (cached) {
    Logger("jobs")->info("{}: served from the result cache (volume {}, baked by {})", record.name(),
                         DigestString(cached->volume()), cached->source_job());
  } else {
    queue_.push_back(record.name());
    Logger("jobs")->info("{}: queued (job digest {}, {} probes, position {})", record.name(),
                         built.jobDigest, built.grid.ProbeCount(), queue_.size());
    wake_.notify_one();
  }
  return record;
}

absl::StatusOr<std::optional<v1::BakeJob>> JobManager::LoadLocked(const std::string& name,
                                                                  bool full) {
  v1::BakeJob record;
  auto running = running_.find(name);
  if (running != running_.end()) {
    record = running->second->record;
  } else {
    PB_ASSIGN_OR_RETURN(std::optional<StoredJob> stored, store_->Get(name));
    if (!stored) return std::optional<v1::BakeJob>();
    record = std::move(stored->record);
  }
  if (full) {
    PB_ASSIGN_OR_RETURN(std::optional<v1::JobSpec> spec, store_->GetSpec(name));
    if (spec) *record.mutable_job() = std::move(*spec);
  }
  return std::optional<v1::BakeJob>(std::move(record));
}

absl::StatusOr<v1::BakeJob> JobManager::GetJob(const std::string& name, v1::BakeJobView view) {
  PB_RETURN_IF_ERROR(CheckName(name).status());
  std::lock_guard lock(mutex_);
  PB_ASSIGN_OR_RETURN(std::optional<v1::BakeJob> job, LoadLocked(name, view != v1::BASIC));
  if (!job) return absl::NotFoundError(absl::StrCat(name, ": no such job"));
  return *job;
}

absl::StatusOr<v1::ListBakeJobsResponse> JobManager::ListJobs(
    const v1::ListBakeJobsRequest& request) {
  if (request.page_size() < 0) return FieldError("pageSize", "must be >= 0");
  int pageSize = request.page_size() == 0 ? config_.defaultPageSize
                                          : std::min(request.page_size(), config_.maxPageSize);
  PB_ASSIGN_OR_RETURN(int64_t afterSeq, ParsePageToken(request.page_token()));
  bool full = request.view() == v1::FULL;
  std::lock_guard lock(mutex_);
  PB_ASSIGN_OR_RETURN(std::vector<StoredJob> jobs, store_->List(afterSeq, pageSize + 1));
  v1::ListBakeJobsResponse response;
  // A page ends early rather than outgrow one message (FULL views of large jobs): it holds at
  // least one job, which fits by kJobRecordReserve.
  // 1024 bytes stay for the response's own fields (the page token).
  const size_t budget = size_t(config_.maxMessageBytes - 1024);
  size_t taken = 0, bytes = 0;
  for (; taken < jobs.size() && int(taken) < pageSize; ++taken) {
    auto running = running_.find(jobs[taken].record.name());
    v1::BakeJob job = running != running_.end() ? running->second->record : jobs[taken].record;
    if (full) {
      PB_ASSIGN_OR_RETURN(std::optional<v1::JobSpec> spec, store_->GetSpec(job.name()));
      if (spec) *job.mutable_job() = std::move(*spec);
    }
    // A repeated message field costs its size plus a tag and a length prefix (at most 6 bytes).
    const size_t jobBytes = job.ByteSizeLong() + 6;
    if (taken > 0 && bytes + jobBytes > budget) break;
    bytes += jobBytes;
    *response.add_bake_jobs() = std::move(job);
  }
  if (taken < jobs.size()) response.set_next_page_token(PageToken(jobs[taken - 1].seq));
  return response;
}

absl::StatusOr<v1::BakeJob> JobManager::CancelJob(const std::string& name) {
  PB_RETURN_IF_ERROR(CheckName(name).status());
  std::lock_guard lock(mutex_);
  auto running = running_.find(name);
  // A job whose end is stored (and announced) is finished, though its worker is still leaving.
  if (running != running_.end() && !runtime::IsFinal(running->second->record.state())) {
    RunningJob& job = *running->second;
    if (!job.record.cancel_requested()) {
      // Stored first: a cancel the store refuses (a full disk) is an error, and neither stops
      // the bake nor shows the job as cancelling.
      v1::BakeJob record = job.record;
      record.set_cancel_requested(true);
      *record.mutable_update_time() = Now();
      PB_RETURN_IF_ERROR(store_->Update(record));
      job.record = std::move(record);
      Logger("jobs")->info("{}: cancellation requested", name);
      NotifyLocked(job.record);
    }
    int none = int(CancelReason::kNone);
    job.reason.compare_exchange_strong(none, int(CancelReason::kUser));
    job.cancel = true;
    backoff_.notify_all();  // a job waiting to store its volume stops waiting
    return job.record;
  }
  PB_ASSIGN_OR_RETURN(std::optional<StoredJob> stored, store_->Get(name));
  if (!stored) return absl::NotFoundError(absl::StrCat(name, ": no such job"));
  v1::BakeJob record = std::move(stored->record);
  if (runtime::IsFinal(record.state())) return record;
  // Queued (running jobs are all in running_).
  record.set_state(v1::BakeJob::CANCELLED);
  record.set_cancel_requested(true);
  *record.mutable_error() =
      ErrorOf(absl::CancelledError("cancelled by CancelBakeJob before it ran"), "queue");
  *record.mutable_update_time() = Now();
  *record.mutable_end_time() = record.update_time();
  PB_RETURN_IF_ERROR(store_->Update(record));
  queue_.erase(std::remove(queue_.begin(), queue_.end(), name), queue_.end());
  std::error_code ec;
  std::filesystem::remove(CheckpointPath(name), ec);
  Logger("jobs")->info("{}: cancelled while queued", name);
  NotifyLocked(record);
  return record;
}

absl::Status JobManager::DeleteJob(const std::string& name) {
  PB_RETURN_IF_ERROR(CheckName(name).status());
  PB_RETURN_IF_ERROR(ForgetJob(name));
  // A job deleted before its end was released (a crash between the two) releases now.
  if (backend_.release) backend_.release(name);
  return absl::OkStatus();
}

absl::Status JobManager::ForgetJob(const std::string& name) {
  std::lock_guard lock(mutex_);
  // A job whose end is stored (and announced) is finished, though its worker is still leaving.
  if (auto running = running_.find(name);
      running != running_.end() && !runtime::IsFinal(running->second->record.state()))
    return absl::FailedPreconditionError(
        absl::StrCat(name, ": the job is running; cancel it first"));
  PB_ASSIGN_OR_RETURN(bool existed, store_->Delete(name));
  if (!existed) return absl::NotFoundError(absl::StrCat(name, ": no such job"));
  queue_.erase(std::remove(queue_.begin(), queue_.end(), name), queue_.end());
  std::error_code ec;
  std::filesystem::remove(CheckpointPath(name), ec);
  EndSubscribersLocked(name, absl::NotFoundError(absl::StrCat(name, " was deleted; resubmit")));
  Logger("jobs")->info("{}: deleted", name);
  return absl::OkStatus();
}

absl::Status JobManager::Subscribe(const std::string& name,
                                   const std::shared_ptr<JobSubscriber>& subscriber) {
  PB_RETURN_IF_ERROR(CheckName(name).status());
  std::lock_guard lock(mutex_);
  PB_ASSIGN_OR_RETURN(std::optional<v1::BakeJob> job, LoadLocked(name, false));
  if (!job) return absl::NotFoundError(absl::StrCat(name, ": no such job; resubmit"));
  if (!runtime::IsFinal(job->state()) && stopping_)
    return absl::UnavailableError("the server is shutting down; watch again once it is back");
  subscriber->OnJobUpdate(*job);
  if (runtime::IsFinal(job->state())) return absl::OkStatus();
  // Entries of this job's freed streams go now, so they never outnumber its live watchers.
  auto [begin, end] = subscribers_.equal_range(name);
  for (auto it = begin; it != end;) it = it->second.expired() ? subscribers_.erase(it) : ++it;
  subscribers_.emplace(name, subscriber);
  return absl::OkStatus();
}

int JobManager::WatcherCount(const std::string& name) {
  std::lock_guard lock(mutex_);
  auto [begin, end] = subscribers_.equal_range(name);
  return int(std::count_if(begin, end, [](const auto& entry) { return !entry.second.expired(); }));
}

int JobManager::PruneWatchers() {
  std::lock_guard lock(mutex_);
  int pruned = 0;
  for (auto it = subscribers_.begin(); it != subscribers_.end();) {
    if (it->second.expired()) {
      it = subscribers_.erase(it);
      ++pruned;
    } else {
      ++it;
    }
  }
  return pruned;
}

void JobManager::NotifyLocked(const v1::BakeJob& record) {
  auto [begin, end] = subscribers_.equal_range(record.name());
  for (auto it = begin; it != end;) {
    // Held for the call: a reaction run inline may free the stream's owner meanwhile.
    std::shared_ptr<JobSubscriber> subscriber = it->second.lock();
    if (!subscriber || subscriber->Detached()) {
      it = subscribers_.erase(it);
      continue;
    }
    subscriber->OnJobUpdate(record);
    ++it;
  }
  if (runtime::IsFinal(record.state())) subscribers_.erase(record.name());
}

void JobManager::EndSubscribersLocked(const std::string& name, const absl::Status& status) {
  auto [begin, end] = subscribers_.equal_range(name);
  for (auto it = begin; it != end; ++it) {
    if (std::shared_ptr<JobSubscriber> subscriber = it->second.lock())
      subscriber->OnJobGone(status);
  }
  subscribers_.erase(begin, end);
}

void JobManager::DispatchLoop() {
  std::unique_lock lock(mutex_);
  auto startBackoff = kStoreRetryFirst;
  while (true) {
    wake_.wait(lock, [&] {
      return stopping_ || (!queue_.empty() && int(running_.size()) < config_.maxConcurrentJobs);
    });
    if (stopping_) return;
    std::string name = queue_.front();
    queue_.erase(queue_.begin());
    // A store that cannot be read or written (a full disk) leaves the job first in the queue and
    // pauses dispatch with backoff; the job starts once the store works again.
    auto retryLater = [&](const absl::Status& status) {
      Logger("jobs")->error("{}: cannot start ({}); retrying in {} s", name,
                            std::string(status.message()), startBackoff.count());
      queue_.insert(queue_.begin(), name);
      wake_.wait_for(lock, startBackoff, [&] { return stopping_; });
      startBackoff = NextBackoff(startBackoff);
    };
    absl::StatusOr<std::optional<StoredJob>> stored = store_->Get(name);
    if (!stored.ok()) {
      retryLater(stored.status());
      continue;
    }
    if (!*stored) {
      Logger("jobs")->warn("{}: not started: no longer in the store", name);
      continue;
    }
    auto job = std::make_shared<RunningJob>();
    job->name = name;
    job->record = std::move((*stored)->record);
    v1::BakeJob& record = job->record;
    record.set_state(v1::BakeJob::RUNNING);
    record.set_attempts(record.attempts() + 1);
    *record.mutable_start_time() = Now();
    *record.mutable_update_time() = record.start_time();
    record.mutable_progress()->clear_elapsed();
    record.mutable_progress()->clear_eta();
    if (absl::Status updated = store_->Update(record); !updated.ok()) {
      retryLater(updated);  // still QUEUED on disk
      continue;
    }
    startBackoff = kStoreRetryFirst;
    running_[name] = job;
    NotifyLocked(record);
    Logger("jobs")->info("{}: running (attempt {})", name, record.attempts());
    arena_.execute([&] { tasks_.run([this, job] { RunJob(job); }); });
  }
}

void JobManager::RunJob(const std::shared_ptr<RunningJob>& job) {
  Outcome outcome;
  try {
    outcome = Execute(*job);
  } catch (const std::exception& e) {
    outcome.state = v1::BakeJob::FAILED;
    outcome.error = ErrorOf(absl::InternalError(absl::StrCat("bake failed: ", e.what())), "bake");
  } catch (...) {
    outcome.state = v1::BakeJob::FAILED;
    outcome.error = ErrorOf(absl::InternalError("bake failed: unknown exception"), "bake");
  }
  Finish(*job, outcome);
}

JobManager::Outcome JobManager::Execute(RunningJob& job) {
  absl::StatusOr<BakeJob> built = LoadJob(job);
  if (!built.ok()) return Stopped(job, built.status(), "load");
  absl::StatusOr<ProbeVolume> volume =
      BakeVolume(job, *built, ReadResumePoint(job, built->jobDigest));
  if (!volume.ok()) return Stopped(job, volume.status(), "bake");
  const BakeStats stats = CountEveryAttempt(job, *volume);
  absl::StatusOr<v1::Digest> digest = StoreVolume(job, *volume, VolumeMetadataFor(*built));
  if (!digest.ok()) return Stopped(job, digest.status(), "store");
  return Succeeded(job.name, *digest, stats);
}

JobManager::Outcome JobManager::Stopped(RunningJob& job, const absl::Status& status,
                                        std::string_view stage) {
  Outcome outcome;
  if (absl::IsCancelled(status) && job.cancel) {
    if (job.reason.load() == int(CancelReason::kShutdown)) {
      outcome.state = v1::BakeJob::QUEUED;
    } else {
      outcome.state = v1::BakeJob::CANCELLED;
      outcome.error = ErrorOf(absl::CancelledError("cancelled by CancelBakeJob"), "bake");
    }
    return outcome;
  }
  outcome.state = v1::BakeJob::FAILED;
  outcome.error = ErrorOf(status, stage);
  Logger("jobs")->warn("{}: failed ({}): {}", job.name, std::string(stage),
                       std::string(status.message()));
  return outcome;
}

JobManager::Outcome JobManager::Succeeded(const std::string& name, const v1::Digest& volume,
                                          const BakeStats& stats) {
  Outcome outcome;
  outcome.state = v1::BakeJob::SUCCEEDED;
  v1::BakeJobResult& result = outcome.result;
  *result.mutable_volume() = volume;
  v1::BakeStats* s = result.mutable_stats();
  s->set_wall_seconds(stats.wallSeconds);
  s->set_threads(stats.threads);
  s->set_probes(stats.probes);
  s->set_samples(stats.samples);
  s->set_rays(stats.rays);
  s->set_invalid_probes(stats.invalidProbes);
  result.set_cached_result(false);
  result.set_source_job(name);
  return outcome;
}

absl::StatusOr<BakeJob> JobManager::LoadJob(RunningJob& job) {
  absl::StatusOr<std::optional<v1::JobSpec>> spec = store_->GetSpec(job.name);
  if (!spec.ok()) return spec.status();
  if (!*spec) return absl::InternalError("the job's spec is gone from the store");
  if (job.cancel) return absl::CancelledError("cancelled before the job was built");
  job.spec = std::move(**spec);
  absl::StatusOr<BakeJob> built = backend_.build(job.spec);
  if (!built.ok()) return built.status();
  std::lock_guard lock(mutex_);
  if (job.record.job_digest() != built->jobDigest) {
    // The baker changed since the job was accepted: its digest (and any checkpoint) is stale.
    Logger("jobs")->warn("{}: job digest changed from {} to {}", job.name, job.record.job_digest(),
                         built->jobDigest);
    job.record.set_job_digest(built->jobDigest);
  }
  return built;
}

std::optional<Checkpoint> JobManager::ReadResumePoint(RunningJob& job,
                                                      const std::string& jobDigest) {
  absl::StatusOr<Checkpoint> read = ReadCheckpoint(CheckpointPath(job.name), jobDigest);
  if (!read.ok()) {
    if (!absl::IsNotFound(read.status()))
      Logger("jobs")->warn("{}: ignoring checkpoint: {}", job.name,
                           std::string(read.status().message()));
    return std::nullopt;
  }
  job.probesResumed = read->DoneCount();
  {
    std::lock_guard lock(mutex_);
    job.carried = read->work;
  }
  Logger("jobs")->info(
      "{}: resuming from a checkpoint with {} of {} probes done ({} samples, {:.3f} s so far)",
      job.name, job.probesResumed, read->done.size(), read->work.samples, read->work.wallSeconds);
  return std::move(*read);
}

absl::StatusOr<ProbeVolume> JobManager::BakeVolume(RunningJob& job, const BakeJob& built,
                                                   std::optional<Checkpoint> checkpoint) {
  BakeOptions options;
  options.threads = config_.threadsPerJob;
  options.cancel = &job.cancel;
  options.progressIntervalSeconds = config_.progressIntervalSeconds;
  options.progress = [&](const BakeProgress& progress) { OnProgress(job, progress); };
  options.checkpointIntervalSeconds = config_.checkpointIntervalSeconds;
  options.checkpoint = [&](const ProbeVolume& volume, const std::vector<uint8_t>& done) {
    OnCheckpoint(job, built.jobDigest, volume, done);
  };
  if (checkpoint) {
    options.resumeFrom = &checkpoint->volume;
    options.resumeDone = &checkpoint->done;
  }
  if (job.cancel) return absl::CancelledError("cancelled before the bake started");
  BakeRun run;
  run.jobName = job.name;
  run.spec = &job.spec;
  {
    std::lock_guard lock(mutex_);
    run.attempt = job.record.attempts();
  }
  run.cancelledByClient = [&job] { return job.reason.load() == int(CancelReason::kUser); };
  run.setWaiting = [this, &job](const std::string& why) {
    std::lock_guard lock(mutex_);
    SetWaitingLocked(job, why);
  };
  return backend_.bake(run, built, options);
}

BakeStats JobManager::CountEveryAttempt(RunningJob& job, ProbeVolume& volume) {
  std::lock_guard lock(mutex_);
  volume.stats.wallSeconds += job.carried.wallSeconds;
  volume.stats.samples += job.carried.samples;
  volume.stats.rays += job.carried.rays;
  return volume.stats;
}

absl::StatusOr<v1::Digest> JobManager::StoreVolume(RunningJob& job, ProbeVolume& volume,
                                                   const VolumeMetadata& meta) {
  // Not written to the file; freed so the write holds no more memory than it needs.
  std::vector<std::vector<float>>().swap(volume.radianceStdError);
  std::vector<float>().swap(volume.autoWindowT);
  const std::filesystem::path tmp =
      blobs_->tmpDir() / absl::StrCat(job.name.substr(kNamePrefix.size()), ".vdb");
  // Gone however this ends (ImportFile consumes it when it succeeds).
  absl::Cleanup removeTmp = [&tmp] {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
  };
  absl::StatusOr<v1::Digest> digest = WriteAndImportVolume(tmp, volume, meta);
  int tries = 1;
  for (auto backoff = kStoreRetryFirst; absl::IsResourceExhausted(digest.status());
       backoff = NextBackoff(backoff)) {
    const std::string reason(digest.status().message());
    Logger("jobs")->warn("{}: volume not stored ({}); retrying in {} s", job.name, reason,
                         backoff.count());
    {
      std::unique_lock lock(mutex_);
      SetWaitingLocked(job, absl::StrCat("waiting for disk space to store the volume: ", reason));
      backoff_.wait_for(lock, backoff, [&] { return stopping_ || job.cancel.load(); });
      if (job.cancel) {
        SetWaitingLocked(job, "");
        return absl::CancelledError("cancelled while waiting for disk space");
      }
    }
    digest = WriteAndImportVolume(tmp, volume, meta);
    ++tries;
  }
  if (tries > 1) {
    std::lock_guard lock(mutex_);
    SetWaitingLocked(job, "");
    if (digest.ok()) Logger("jobs")->info("{}: volume stored at try {}", job.name, tries);
  }
  return digest;
}

absl::StatusOr<v1::Digest> JobManager::WriteAndImportVolume(const std::filesystem::path& tmp,
                                                            const ProbeVolume& volume,
                                                            const VolumeMetadata& meta) {
  std::multiset<std::filesystem::file_time_type>::iterator started;
  {
    std::lock_guard lock(volumesMutex_);
    started = importsUnderWay_.insert(std::filesystem::file_time_type::clock::now());
  }
  absl::StatusOr<v1::Digest> stored = [&]() -> absl::StatusOr<v1::Digest> {
    PB_RETURN_IF_ERROR(backend_.writeVolume(tmp.string(), volume, meta));
    return blobs_->ImportFile(tmp);
  }();
  std::lock_guard lock(volumesMutex_);
  importsUnderWay_.erase(started);
  if (stored.ok()) volumesNotYetReferenced_.insert(stored->hash());
  return stored;
}

void JobManager::OnProgress(RunningJob& job, const BakeProgress& progress) {
  std::lock_guard lock(mutex_);
  v1::BakeJobProgress* p = job.record.mutable_progress();
  job.attempt.wallSeconds = std::max(0.0, progress.elapsedSeconds);
  job.attempt.samples = progress.samples;
  job.attempt.rays = progress.rays;
  p->set_probes_done(progress.probesDone);
  p->set_probes_total(progress.probesTotal);
  p->set_samples(job.carried.samples + progress.samples);
  p->set_rays(job.carried.rays + progress.rays);
  *p->mutable_elapsed() = SecondsToDuration(std::max(0.0, progress.elapsedSeconds));
  if (progress.etaSeconds >= 0 && std::isfinite(progress.etaSeconds))
    *p->mutable_eta() = SecondsToDuration(progress.etaSeconds);
  else
    p->clear_eta();
  if (progress.errorEstimate >= 0 && std::isfinite(progress.errorEstimate))
    p->set_error_estimate(progress.errorEstimate);
  else
    p->clear_error_estimate();
  p->set_probes_error_unknown(progress.probesErrorUnknown);
  p->set_probes_resumed(job.probesResumed);
  *job.record.mutable_update_time() = Now();
  NotifyLocked(job.record);
}

std::set<std::string> JobManager::VolumesNotYetReferenced(
    std::filesystem::file_time_type* importsSince) {
  std::lock_guard lock(volumesMutex_);
  *importsSince = importsUnderWay_.empty() ? std::filesystem::file_time_type::clock::now()
                                           : *importsUnderWay_.begin();
  return {volumesNotYetReferenced_.begin(), volumesNotYetReferenced_.end()};
}

void JobManager::SetWaitingLocked(RunningJob& job, const std::string& why) {
  const std::string shown = redact_(why);
  if (job.record.progress().waiting() == shown) return;
  job.record.mutable_progress()->set_waiting(shown);
  *job.record.mutable_update_time() = Now();
  NotifyLocked(job.record);
}

void JobManager::OnCheckpoint(RunningJob& job, const std::string& jobDigest,
                              const ProbeVolume& volume, const std::vector<uint8_t>& done) {
  auto start = std::chrono::steady_clock::now();
  BakeWork work;
  {
    std::lock_guard lock(mutex_);
    work = job.carried;
    work += job.attempt;
  }
  absl::Status written = WriteCheckpoint(CheckpointPath(job.name), jobDigest, volume, done, work);
  if (!written.ok()) {
    Logger("jobs")->warn("{}: checkpoint not written: {}", job.name,
                         std::string(written.message()));
    return;
  }
  int64_t doneCount = std::count_if(done.begin(), done.end(), [](uint8_t d) { return d != 0; });
  Logger("jobs")->debug(
      "{}: checkpoint with {} of {} probes ({:.1f} ms)", job.name, doneCount, done.size(),
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  // Persist the progress too, so a job requeued after a crash shows where it was.
  std::lock_guard lock(mutex_);
  if (absl::Status updated = store_->Update(job.record); !updated.ok())
    Logger("jobs")->warn("{}: progress not stored: {}", job.name, std::string(updated.message()));
}

void JobManager::Finish(RunningJob& job, const Outcome& outcome) {
  const bool final = runtime::IsFinal(outcome.state);
  v1::BakeJob record;
  {
    std::lock_guard lock(mutex_);
    record = job.record;
  }
  record.set_state(outcome.state);
  if (outcome.state == v1::BakeJob::SUCCEEDED) {
    *record.mutable_result() = outcome.result;
    v1::BakeJobProgress* p = record.mutable_progress();
    p->set_probes_done(outcome.result.stats().probes());
    p->set_probes_total(outcome.result.stats().probes());
    p->set_samples(outcome.result.stats().samples());
    p->set_rays(outcome.result.stats().rays());
    p->clear_eta();
  } else if (final) {
    *record.mutable_error() = outcome.error;
    record.mutable_error()->set_message(redact_(outcome.error.message()));
  }
  // A state is announced only once stored: a client told SUCCEEDED or FAILED must find the job
  // so after a restart too. A store that cannot write (a full disk) is retried with backoff, the
  // job staying RUNNING meanwhile; at shutdown it stays RUNNING on disk and runs again.
  // Once stored, the record refers to the volume; not stored (a shutdown), the job runs again
  // and the volume is garbage. Either way the collector need not hold it for this job any more,
  // and no one is told SUCCEEDED before.
  auto releaseVolume = [&] {
    if (outcome.state != v1::BakeJob::SUCCEEDED) return;
    std::lock_guard lock(volumesMutex_);
    auto it = volumesNotYetReferenced_.find(outcome.result.volume().hash());
    if (it != volumesNotYetReferenced_.end()) volumesNotYetReferenced_.erase(it);
  };
  bool stored = false;
  int tries = 0;
  for (auto backoff = kStoreRetryFirst;; backoff = NextBackoff(backoff)) {
    ++tries;
    std::unique_lock lock(mutex_);
    *record.mutable_update_time() = Now();
    if (final) *record.mutable_end_time() = record.update_time();
    const absl::Status committed = store_->Transaction([&]() -> absl::Status {
      PB_RETURN_IF_ERROR(store_->Update(record));
      if (outcome.state == v1::BakeJob::SUCCEEDED)
        PB_RETURN_IF_ERROR(store_->PutCached(record.job_digest(), outcome.result));
      return absl::OkStatus();
    });
    if (committed.ok()) {
      stored = true;
      releaseVolume();
      job.record = record;
      NotifyLocked(job.record);
      if (tries > 1)
        Logger("jobs")->info("{}: {} stored at try {}", job.name,
                             v1::BakeJob::State_Name(outcome.state), tries);
      break;
    }
    if (stopping_) {
      releaseVolume();
      Logger("jobs")->error("{}: {} not stored ({}); it runs again after the restart", job.name,
                            v1::BakeJob::State_Name(outcome.state),
                            std::string(committed.message()));
      break;
    }
    Logger("jobs")->error("{}: {} not stored ({}); retrying in {} s", job.name,
                          v1::BakeJob::State_Name(outcome.state), std::string(committed.message()),
                          backoff.count());
    // Watchers see why the job, its work done, stays RUNNING (the record stored clears it).
    SetWaitingLocked(job, absl::StrCat("waiting to store the job's end: ", committed.message()));
    backoff_.wait_for(lock, backoff, [&] { return stopping_; });
  }
  if (stored) {
    switch (outcome.state) {
      case v1::BakeJob::SUCCEEDED:
        Logger("jobs")->info("{}: succeeded in {:.3f} s: volume {}", job.name,
                             outcome.result.stats().wall_seconds(),
                             DigestString(outcome.result.volume()));
        break;
      case v1::BakeJob::CANCELLED:
        Logger("jobs")->info("{}: cancelled", job.name);
        break;
      case v1::BakeJob::QUEUED:
        Logger("jobs")->info("{}: requeued (checkpoint kept)", job.name);
        break;
      default:
        break;
    }
  }
  if (final && stored) {
    std::error_code ec;
    std::filesystem::remove(CheckpointPath(job.name), ec);
    if (backend_.release) backend_.release(job.name);
  }
  // Last: once running_ is empty, Shutdown may tear the manager down.
  std::lock_guard lock(mutex_);
  if (outcome.state == v1::BakeJob::QUEUED && !stopping_) queue_.insert(queue_.begin(), job.name);
  running_.erase(job.name);
  if (running_.empty()) jobsIdle_.notify_all();
  wake_.notify_one();
}

}  // namespace probebake::server
