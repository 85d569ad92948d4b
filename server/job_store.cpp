#include "server/job_store.h"

#include <sqlite3.h>

#include "absl/strings/str_cat.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"

namespace probebake::server {

namespace {

constexpr int kSchemaVersion = 1;

constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS jobs (
  seq INTEGER PRIMARY KEY AUTOINCREMENT,
  name TEXT NOT NULL UNIQUE,
  request_id TEXT UNIQUE,
  state INTEGER NOT NULL,
  record BLOB NOT NULL,
  spec BLOB NOT NULL
);
CREATE INDEX IF NOT EXISTS jobs_by_state ON jobs(state, seq);
CREATE TABLE IF NOT EXISTS result_cache (
  job_digest TEXT PRIMARY KEY,
  result BLOB NOT NULL
);
CREATE TABLE IF NOT EXISTS cluster_runs (
  name TEXT PRIMARY KEY,
  run BLOB NOT NULL
);
)sql";

}  // namespace

namespace {

// A failed SQLite call as a status whose code tells a client what it can do: a full disk is
// RESOURCE_EXHAUSTED and says so, a database held by another writer UNAVAILABLE (retry), the rest
// INTERNAL.
absl::Status SqliteStatus(int rc, const std::string& message) {
  switch (rc & 0xff) {  // the primary result code
    case SQLITE_FULL:
      return absl::ResourceExhaustedError(
          absl::StrCat("the server's disk is full (job store: ", message, ")"));
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      return absl::UnavailableError(absl::StrCat("the job store is busy (", message, ")"));
    default:
      return absl::InternalError(message);
  }
}

}  // namespace

// A prepared statement; reset and finalized by its destructor.
class JobStore::Statement {
 public:
  Statement(sqlite3* db, const char* sql) : db_(db) {
    rc_ = sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr);
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  absl::Status status() const {
    if (rc_ == SQLITE_OK) return absl::OkStatus();
    return absl::InternalError(absl::StrCat("sqlite prepare: ", sqlite3_errmsg(db_)));
  }
  void Bind(int i, int64_t v) { sqlite3_bind_int64(stmt_, i, v); }
  void Bind(int i, const std::string& v) {
    sqlite3_bind_blob(stmt_, i, v.data(), int(v.size()), SQLITE_TRANSIENT);
  }
  void BindText(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.data(), int(v.size()), SQLITE_TRANSIENT);
  }
  void BindNull(int i) { sqlite3_bind_null(stmt_, i); }
  // SQLITE_ROW: true; SQLITE_DONE: false; else an error.
  absl::StatusOr<bool> Step() {
    int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    if (rc == SQLITE_CONSTRAINT)
      return absl::AlreadyExistsError(absl::StrCat("sqlite: ", sqlite3_errmsg(db_)));
    return SqliteStatus(rc, absl::StrCat("sqlite step: ", sqlite3_errmsg(db_)));
  }
  int64_t Int(int col) const { return sqlite3_column_int64(stmt_, col); }
  std::string Blob(int col) const {
    const void* data = sqlite3_column_blob(stmt_, col);
    int size = sqlite3_column_bytes(stmt_, col);
    return data ? std::string(static_cast<const char*>(data), size_t(size)) : std::string();
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  int rc_;
};

namespace {

absl::StatusOr<StoredJob> RowToJob(int64_t seq, const std::string& record) {
  StoredJob job;
  job.seq = seq;
  if (!job.record.ParseFromString(record))
    return absl::DataLossError(absl::StrCat("job row ", seq, ": unreadable record"));
  return job;
}

}  // namespace

absl::StatusOr<std::unique_ptr<JobStore>> JobStore::Open(const std::filesystem::path& dbPath) {
  sqlite3* db = nullptr;
  int rc =
      sqlite3_open_v2(dbPath.c_str(), &db,
                      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    std::string message = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    return absl::InternalError(absl::StrCat("open ", dbPath.string(), ": ", message));
  }
  std::unique_ptr<JobStore> store(new JobStore(db));
  sqlite3_busy_timeout(db, 5000);
  // WAL: readers do not block the writer; synchronous=FULL: a commit is on disk when it returns
  // (NORMAL could lose the last commits on power loss, and an accepted job must survive).
  PB_RETURN_IF_ERROR(store->Exec("PRAGMA journal_mode=WAL"));
  PB_RETURN_IF_ERROR(store->Exec("PRAGMA synchronous=FULL"));
  PB_RETURN_IF_ERROR(store->Exec(kSchema));
  {
    Statement version(db, "PRAGMA user_version");
    PB_RETURN_IF_ERROR(version.status());
    PB_ASSIGN_OR_RETURN(bool row, version.Step());
    int64_t v = row ? version.Int(0) : 0;
    if (v != 0 && v != kSchemaVersion)
      return absl::FailedPreconditionError(absl::StrCat(dbPath.string(),
                                                        ": job store schema version ", v,
                                                        ", this server knows ", kSchemaVersion));
  }
  PB_RETURN_IF_ERROR(store->Exec(absl::StrCat("PRAGMA user_version=", kSchemaVersion).c_str()));
  return store;
}

JobStore::~JobStore() {
  // Closing the last connection checkpoints the WAL into the database file.
  sqlite3_close(db_);
}

void JobStore::SetSpaceReclaimer(std::function<bool()> reclaim, std::function<void()> restore) {
  std::lock_guard lock(mutex_);
  reclaim_ = std::move(reclaim);
  restore_ = std::move(restore);
}

absl::Status JobStore::SetMaxPageCountForTesting(int64_t pages) {
  std::lock_guard lock(mutex_);
  return Exec(absl::StrCat("PRAGMA max_page_count = ", pages).c_str());
}

namespace {
const absl::Status& StatusOf(const absl::Status& status) {
  return status;
}
template <typename T>
const absl::Status& StatusOf(const absl::StatusOr<T>& result) {
  return result.status();
}
}  // namespace

template <typename Op>
auto JobStore::Writing(Op&& op) -> decltype(op()) {
  std::lock_guard lock(mutex_);
  auto result = op();
  // Inside a transaction the whole transaction is retried instead (by its own Writing).
  if (transactionDepth_ == 0 && reclaim_ && absl::IsResourceExhausted(StatusOf(result)) &&
      reclaim_()) {
    result = op();
    if (restore_) restore_();
  }
  return result;
}

absl::Status JobStore::Exec(const char* sql) {
  std::lock_guard lock(mutex_);
  char* error = nullptr;
  if (const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, &error); rc != SQLITE_OK) {
    std::string message = error ? error : "unknown error";
    sqlite3_free(error);
    return SqliteStatus(rc, absl::StrCat("sqlite: ", message, " in ", sql));
  }
  return absl::OkStatus();
}

absl::Status JobStore::Transaction(const std::function<absl::Status()>& body) {
  return Writing([&] { return TransactionOnce(body); });
}

absl::Status JobStore::TransactionOnce(const std::function<absl::Status()>& body) {
  PB_RETURN_IF_ERROR(Exec("BEGIN IMMEDIATE"));
  ++transactionDepth_;
  absl::Status status = body();
  --transactionDepth_;
  if (status.ok()) {
    status = Exec("COMMIT");
    if (status.ok()) return status;
  }
  // SQLite may have rolled the transaction back itself (a full disk at COMMIT): then there is
  // nothing to roll back, and ROLLBACK would only log a spurious error.
  if (!sqlite3_get_autocommit(db_)) {
    absl::Status rollback = Exec("ROLLBACK");
    if (!rollback.ok())
      Logger("jobs")->error("rollback failed: {}", std::string(rollback.message()));
  }
  return status;
}

absl::Status JobStore::Insert(const v1::BakeJob& record, const v1::JobSpec& spec) {
  return Writing([&]() -> absl::Status {
    Statement s(db_, "INSERT INTO jobs(name, request_id, state, record, spec) VALUES(?,?,?,?,?)");
    PB_RETURN_IF_ERROR(s.status());
    s.BindText(1, record.name());
    if (record.request_id().empty())
      s.BindNull(2);
    else
      s.BindText(2, record.request_id());
    s.Bind(3, int64_t(record.state()));
    v1::BakeJob stripped = record;
    stripped.clear_job();
    s.Bind(4, stripped.SerializeAsString());
    s.Bind(5, spec.SerializeAsString());
    return s.Step().status();
  });
}

absl::Status JobStore::Update(const v1::BakeJob& record) {
  return Writing([&]() -> absl::Status {
    Statement s(db_, "UPDATE jobs SET state = ?, record = ? WHERE name = ?");
    PB_RETURN_IF_ERROR(s.status());
    s.Bind(1, int64_t(record.state()));
    v1::BakeJob stripped = record;
    stripped.clear_job();
    s.Bind(2, stripped.SerializeAsString());
    s.BindText(3, record.name());
    PB_RETURN_IF_ERROR(s.Step().status());
    if (sqlite3_changes(db_) == 0)
      return absl::NotFoundError(absl::StrCat(record.name(), ": no such job"));
    return absl::OkStatus();
  });
}

absl::StatusOr<std::optional<StoredJob>> JobStore::Get(const std::string& name) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT seq, record FROM jobs WHERE name = ?");
  PB_RETURN_IF_ERROR(s.status());
  s.BindText(1, name);
  PB_ASSIGN_OR_RETURN(bool row, s.Step());
  if (!row) return std::optional<StoredJob>();
  PB_ASSIGN_OR_RETURN(StoredJob job, RowToJob(s.Int(0), s.Blob(1)));
  return std::optional<StoredJob>(std::move(job));
}

absl::StatusOr<std::optional<v1::JobSpec>> JobStore::GetSpec(const std::string& name) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT spec FROM jobs WHERE name = ?");
  PB_RETURN_IF_ERROR(s.status());
  s.BindText(1, name);
  PB_ASSIGN_OR_RETURN(bool row, s.Step());
  if (!row) return std::optional<v1::JobSpec>();
  v1::JobSpec spec;
  if (!spec.ParseFromString(s.Blob(0)))
    return absl::DataLossError(absl::StrCat(name, ": unreadable job spec"));
  return std::optional<v1::JobSpec>(std::move(spec));
}

absl::StatusOr<std::optional<StoredJob>> JobStore::FindByRequestId(const std::string& requestId) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT seq, record FROM jobs WHERE request_id = ?");
  PB_RETURN_IF_ERROR(s.status());
  s.BindText(1, requestId);
  PB_ASSIGN_OR_RETURN(bool row, s.Step());
  if (!row) return std::optional<StoredJob>();
  PB_ASSIGN_OR_RETURN(StoredJob job, RowToJob(s.Int(0), s.Blob(1)));
  return std::optional<StoredJob>(std::move(job));
}

absl::StatusOr<std::vector<StoredJob>> JobStore::List(int64_t afterSeq, int limit) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT seq, record FROM jobs WHERE seq > ? ORDER BY seq LIMIT ?");
  PB_RETURN_IF_ERROR(s.status());
  s.Bind(1, afterSeq);
  s.Bind(2, int64_t(limit));
  std::vector<StoredJob> jobs;
  while (true) {
    PB_ASSIGN_OR_RETURN(bool row, s.Step());
    if (!row) break;
    PB_ASSIGN_OR_RETURN(StoredJob job, RowToJob(s.Int(0), s.Blob(1)));
    jobs.push_back(std::move(job));
  }
  return jobs;
}

absl::StatusOr<std::vector<StoredJob>> JobStore::ListInState(v1::BakeJob::State state) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT seq, record FROM jobs WHERE state = ? ORDER BY seq");
  PB_RETURN_IF_ERROR(s.status());
  s.Bind(1, int64_t(state));
  std::vector<StoredJob> jobs;
  while (true) {
    PB_ASSIGN_OR_RETURN(bool row, s.Step());
    if (!row) break;
    PB_ASSIGN_OR_RETURN(StoredJob job, RowToJob(s.Int(0), s.Blob(1)));
    jobs.push_back(std::move(job));
  }
  return jobs;
}

absl::StatusOr<int64_t> JobStore::CountInState(v1::BakeJob::State state) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT COUNT(*) FROM jobs WHERE state = ?");
  PB_RETURN_IF_ERROR(s.status());
  s.Bind(1, int64_t(state));
  PB_ASSIGN_OR_RETURN(bool row, s.Step());
  return row ? s.Int(0) : 0;
}

absl::StatusOr<bool> JobStore::Delete(const std::string& name) {
  return Writing([&]() -> absl::StatusOr<bool> {
    Statement s(db_, "DELETE FROM jobs WHERE name = ?");
    PB_RETURN_IF_ERROR(s.status());
    s.BindText(1, name);
    PB_RETURN_IF_ERROR(s.Step().status());
    return sqlite3_changes(db_) > 0;
  });
}

absl::Status JobStore::ForEachJob(
    const std::function<void(const v1::BakeJob& record, const v1::JobSpec& spec)>& visit) {
  // In pages, the store unlocked between them: specs may be megabytes each.
  constexpr int64_t kPage = 64;
  int64_t after = 0;
  while (true) {
    std::vector<std::pair<StoredJob, v1::JobSpec>> page;
    {
      std::lock_guard lock(mutex_);
      Statement s(db_, "SELECT seq, record, spec FROM jobs WHERE seq > ? ORDER BY seq LIMIT ?");
      PB_RETURN_IF_ERROR(s.status());
      s.Bind(1, after);
      s.Bind(2, kPage);
      while (true) {
        PB_ASSIGN_OR_RETURN(bool row, s.Step());
        if (!row) break;
        PB_ASSIGN_OR_RETURN(StoredJob job, RowToJob(s.Int(0), s.Blob(1)));
        v1::JobSpec spec;
        if (!spec.ParseFromString(s.Blob(2)))
          return absl::DataLossError(absl::StrCat(job.record.name(), ": unreadable job spec"));
        page.emplace_back(std::move(job), std::move(spec));
      }
    }
    for (const auto& [job, spec] : page) visit(job.record, spec);
    if (int64_t(page.size()) < kPage) return absl::OkStatus();
    after = page.back().first.seq;
  }
}

absl::StatusOr<std::vector<std::pair<std::string, v1::BakeJobResult>>> JobStore::ListCached() {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT job_digest, result FROM result_cache ORDER BY job_digest");
  PB_RETURN_IF_ERROR(s.status());
  std::vector<std::pair<std::string, v1::BakeJobResult>> entries;
  while (true) {
    PB_ASSIGN_OR_RETURN(bool row, s.Step());
    if (!row) return entries;
    std::string jobDigest = s.Blob(0);
    v1::BakeJobResult result;
    if (!result.ParseFromString(s.Blob(1)))
      return absl::DataLossError(absl::StrCat("result cache ", jobDigest, ": unreadable entry"));
    entries.emplace_back(std::move(jobDigest), std::move(result));
  }
}

absl::StatusOr<std::optional<v1::BakeJobResult>> JobStore::GetCached(const std::string& jobDigest) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT result FROM result_cache WHERE job_digest = ?");
  PB_RETURN_IF_ERROR(s.status());
  s.BindText(1, jobDigest);
  PB_ASSIGN_OR_RETURN(bool row, s.Step());
  if (!row) return std::optional<v1::BakeJobResult>();
  v1::BakeJobResult result;
  if (!result.ParseFromString(s.Blob(0)))
    return absl::DataLossError(absl::StrCat("result cache ", jobDigest, ": unreadable entry"));
  return std::optional<v1::BakeJobResult>(std::move(result));
}

absl::Status JobStore::PutCached(const std::string& jobDigest, const v1::BakeJobResult& result) {
  return Writing([&]() -> absl::Status {
    Statement s(db_, "INSERT OR REPLACE INTO result_cache(job_digest, result) VALUES(?, ?)");
    PB_RETURN_IF_ERROR(s.status());
    s.BindText(1, jobDigest);
    s.Bind(2, result.SerializeAsString());
    return s.Step().status();
  });
}

absl::Status JobStore::DeleteCached(const std::string& jobDigest) {
  return Writing([&]() -> absl::Status {
    Statement s(db_, "DELETE FROM result_cache WHERE job_digest = ?");
    PB_RETURN_IF_ERROR(s.status());
    s.BindText(1, jobDigest);
    return s.Step().status();
  });
}

absl::StatusOr<std::optional<std::string>> JobStore::GetClusterRun(const std::string& name) {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT run FROM cluster_runs WHERE name = ?");
  PB_RETURN_IF_ERROR(s.status());
  s.BindText(1, name);
  PB_ASSIGN_OR_RETURN(bool row, s.Step());
  if (!row) return std::optional<std::string>();
  return std::optional<std::string>(s.Blob(0));
}

absl::Status JobStore::PutClusterRun(const std::string& name, const std::string& run) {
  return Writing([&]() -> absl::Status {
    Statement s(db_, "INSERT OR REPLACE INTO cluster_runs(name, run) VALUES(?, ?)");
    PB_RETURN_IF_ERROR(s.status());
    s.BindText(1, name);
    s.Bind(2, run);
    return s.Step().status();
  });
}

absl::Status JobStore::DeleteClusterRun(const std::string& name) {
  return Writing([&]() -> absl::Status {
    Statement s(db_, "DELETE FROM cluster_runs WHERE name = ?");
    PB_RETURN_IF_ERROR(s.status());
    s.BindText(1, name);
    return s.Step().status();
  });
}

absl::StatusOr<std::vector<std::string>> JobStore::ListClusterRuns() {
  std::lock_guard lock(mutex_);
  Statement s(db_, "SELECT name FROM cluster_runs ORDER BY name");
  PB_RETURN_IF_ERROR(s.status());
  std::vector<std::string> names;
  for (;;) {
    PB_ASSIGN_OR_RETURN(bool row, s.Step());
    if (!row) return names;
    names.push_back(s.Blob(0));
  }
}

}  // namespace probebake::server
