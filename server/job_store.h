// The durable job store: an SQLite database (WAL journal, synchronous=FULL) under DATA, holding
// every accepted job and the result cache. A write returns only once it is committed to disk, so
// a job the server acknowledged survives a crash (docs/service.md).
//
// Rows: a job is its BakeJob record (every field but the spec, serialized) plus its JobSpec
// (serialized, separately, since it can be large and most reads do not need it). The result cache
// maps a job digest to the BakeJobResult that baked it. A cluster backend keeps its runs (a job's
// array ids and shard attempts, opaque bytes here) beside the jobs, so that they survive a restart.
//
// Thread safety: one connection guarded by a mutex; every method may be called from any thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/v1/service.pb.h"

struct sqlite3;

namespace probebake::server {

struct StoredJob {
  int64_t seq = 0;     // insertion order, increasing, never reused
  v1::BakeJob record;  // `job` (the spec) is not set
};

class JobStore {
 public:
  static absl::StatusOr<std::unique_ptr<JobStore>> Open(const std::filesystem::path& dbPath);
  ~JobStore();
  JobStore(const JobStore&) = delete;
  JobStore& operator=(const JobStore&) = delete;

  // Adds a job (record.name unique, record.request_id unique when not empty).
  absl::Status Insert(const v1::BakeJob& record, const v1::JobSpec& spec);
  // Replaces the record of the job named record.name (NOT_FOUND when absent).
  absl::Status Update(const v1::BakeJob& record);
  absl::StatusOr<std::optional<StoredJob>> Get(const std::string& name);
  absl::StatusOr<std::optional<v1::JobSpec>> GetSpec(const std::string& name);
  absl::StatusOr<std::optional<StoredJob>> FindByRequestId(const std::string& requestId);
  // Up to `limit` jobs with seq > afterSeq, in seq order.
  absl::StatusOr<std::vector<StoredJob>> List(int64_t afterSeq, int limit);
  // Every job in `state`, in seq order.
  absl::StatusOr<std::vector<StoredJob>> ListInState(v1::BakeJob::State state);
  absl::StatusOr<int64_t> CountInState(v1::BakeJob::State state);
  // False when there was no such job.
  absl::StatusOr<bool> Delete(const std::string& name);

  // Calls `visit` with every job's record and spec, in seq order, reading them in pages (a job
  // added or deleted meanwhile may or may not be visited).
  absl::Status ForEachJob(
      const std::function<void(const v1::BakeJob& record, const v1::JobSpec& spec)>& visit);

  absl::StatusOr<std::optional<v1::BakeJobResult>> GetCached(const std::string& jobDigest);
  // Every result-cache entry: (job digest, result).
  absl::StatusOr<std::vector<std::pair<std::string, v1::BakeJobResult>>> ListCached();
  absl::Status PutCached(const std::string& jobDigest, const v1::BakeJobResult& result);
  absl::Status DeleteCached(const std::string& jobDigest);

  // The run a cluster backend keeps for job `name` (its own serialization), if any.
  absl::StatusOr<std::optional<std::string>> GetClusterRun(const std::string& name);
  absl::Status PutClusterRun(const std::string& name, const std::string& run);
  absl::Status DeleteClusterRun(const std::string& name);  // OK when there was none
  // The names of the jobs with a cluster run, in name order.
  absl::StatusOr<std::vector<std::string>> ListClusterRuns();

  // Runs `body` (which calls this store's methods) in one transaction: committed when it
  // returns OK, rolled back otherwise.
  absl::Status Transaction(const std::function<absl::Status()>& body);

  // `reclaim` is called when a write (or a whole transaction) fails for lack of space
  // (RESOURCE_EXHAUSTED); when it returns true (it freed some) the write is tried once more, and
  // `restore` is called after that try.
  void SetSpaceReclaimer(std::function<bool()> reclaim, std::function<void()> restore);
  // For tests: the database may grow to `pages` pages at most, past which writes fail as on a
  // full disk.
  absl::Status SetMaxPageCountForTesting(int64_t pages);

 private:
  explicit JobStore(sqlite3* db) : db_(db) {}
  absl::Status Exec(const char* sql);
  absl::Status TransactionOnce(const std::function<absl::Status()>& body);
  // Runs a write under the lock, retried once when it failed for lack of space and reclaim_
  // freed some (outside transactions).
  template <typename Op>
  auto Writing(Op&& op) -> decltype(op());
  class Statement;

  sqlite3* db_;
  std::recursive_mutex mutex_;
  std::function<bool()> reclaim_;
  std::function<void()> restore_;
  int transactionDepth_ = 0;
};

}  // namespace probebake::server
