#include "server/job_store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "probebake/base/status.h"
#include "temp_dir.h"

namespace probebake::server {
namespace {

using probebake::testing::TempDir;

v1::BakeJob Record(const std::string& name, const std::string& requestId,
                   v1::BakeJob::State state) {
  v1::BakeJob job;
  job.set_name(name);
  job.set_request_id(requestId);
  job.set_state(state);
  job.set_job_digest(std::string(64, 'a'));
  return job;
}

v1::JobSpec Spec(int counts) {
  v1::JobSpec spec;
  for (int a = 0; a < 3; ++a) spec.mutable_grid()->add_counts(counts);
  return spec;
}

TEST(JobStore, ABusyDatabaseIsUnavailableNotInternal) {
  // Another writer holds the database past the busy timeout (5 s): the store's error says to
  // retry (UNAVAILABLE) rather than that the server is broken (INTERNAL); reads still work.
  TempDir dir;
  auto path = dir.path() / "jobs.sqlite";
  auto store = JobStore::Open(path);
  ASSERT_TRUE(store.ok()) << store.status();
  ASSERT_TRUE((*store)->Insert(Record("bakeJobs/a", "", v1::BakeJob::QUEUED), Spec(3)).ok());
  sqlite3* other = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &other), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(other, "BEGIN IMMEDIATE", nullptr, nullptr, nullptr), SQLITE_OK);
  const absl::Status busy =
      (*store)->Insert(Record("bakeJobs/b", "", v1::BakeJob::QUEUED), Spec(3));
  EXPECT_EQ(busy.code(), absl::StatusCode::kUnavailable) << busy;
  EXPECT_TRUE((*store)->Get("bakeJobs/a").ok());
  sqlite3_exec(other, "ROLLBACK", nullptr, nullptr, nullptr);
  sqlite3_close(other);
  EXPECT_TRUE((*store)->Insert(Record("bakeJobs/b", "", v1::BakeJob::QUEUED), Spec(3)).ok());
}

// A spec that needs pages of its own (about 160 kB).
v1::JobSpec BigSpec() {
  v1::JobSpec spec = Spec(3);
  v1::Mesh* mesh = spec.mutable_scene()->add_meshes();
  for (int i = 0; i < 20000; ++i) mesh->add_positions(double(i));
  return spec;
}

TEST(JobStore, AWriteThatFindsTheDiskFullIsRetriedOnceSpaceIsFreed) {
  // The database may not grow (max_page_count, as a full disk): a write fails RESOURCE_EXHAUSTED
  // unless the reclaimer frees space, and then succeeds at its second try; a transaction is
  // retried whole.
  TempDir dir;
  auto store = JobStore::Open(dir.path() / "jobs.sqlite");
  ASSERT_TRUE(store.ok()) << store.status();
  JobStore& s = **store;
  ASSERT_TRUE(s.Insert(Record("bakeJobs/a", "", v1::BakeJob::QUEUED), Spec(3)).ok());
  ASSERT_TRUE(s.SetMaxPageCountForTesting(1).ok());  // no larger than it is now
  EXPECT_EQ(s.Insert(Record("bakeJobs/b", "", v1::BakeJob::QUEUED), BigSpec()).code(),
            absl::StatusCode::kResourceExhausted);

  int calls = 0, restores = 0;
  s.SetSpaceReclaimer(
      [&] {
        ++calls;
        return false;  // nothing to give back
      },
      [&] { ++restores; });
  EXPECT_EQ(s.Insert(Record("bakeJobs/b", "", v1::BakeJob::QUEUED), BigSpec()).code(),
            absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(restores, 0);  // nothing was lent

  calls = 0;
  s.SetSpaceReclaimer(
      [&] {
        ++calls;
        return s.SetMaxPageCountForTesting(1 << 30).ok();
      },
      [&] { ++restores; });
  EXPECT_TRUE(s.Insert(Record("bakeJobs/b", "", v1::BakeJob::QUEUED), BigSpec()).ok());
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(restores, 1);

  calls = 0;
  ASSERT_TRUE(s.SetMaxPageCountForTesting(1).ok());
  const absl::Status committed = s.Transaction([&]() -> absl::Status {
    PB_RETURN_IF_ERROR(s.Update(Record("bakeJobs/a", "", v1::BakeJob::RUNNING)));
    return s.Insert(Record("bakeJobs/c", "", v1::BakeJob::QUEUED), BigSpec());
  });
  EXPECT_TRUE(committed.ok()) << committed;
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(restores, 2);
  auto a = s.Get("bakeJobs/a");
  ASSERT_TRUE(a.ok() && a->has_value());
  EXPECT_EQ((*a)->record.state(), v1::BakeJob::RUNNING);
  auto c = s.GetSpec("bakeJobs/c");
  ASSERT_TRUE(c.ok() && c->has_value());
  EXPECT_EQ((*c)->scene().meshes(0).positions_size(), 20000);
}

TEST(JobStore, InsertGetUpdateDeleteSurviveReopen) {
  TempDir dir;
  auto path = dir.path() / "jobs.sqlite";
  {
    auto store = JobStore::Open(path);
    ASSERT_TRUE(store.ok()) << store.status();
    ASSERT_TRUE((*store)->Insert(Record("bakeJobs/a", "r1", v1::BakeJob::QUEUED), Spec(3)).ok());
    ASSERT_TRUE((*store)->Insert(Record("bakeJobs/b", "", v1::BakeJob::QUEUED), Spec(4)).ok());
    // Names and non-empty request ids are unique; empty ones are not.
    EXPECT_EQ((*store)->Insert(Record("bakeJobs/a", "", v1::BakeJob::QUEUED), Spec(1)).code(),
              absl::StatusCode::kAlreadyExists);
    EXPECT_EQ((*store)->Insert(Record("bakeJobs/c", "r1", v1::BakeJob::QUEUED), Spec(1)).code(),
              absl::StatusCode::kAlreadyExists);
    ASSERT_TRUE((*store)->Insert(Record("bakeJobs/d", "", v1::BakeJob::QUEUED), Spec(1)).ok());
    v1::BakeJob running = Record("bakeJobs/b", "", v1::BakeJob::RUNNING);
    running.set_attempts(1);
    ASSERT_TRUE((*store)->Update(running).ok());
    EXPECT_EQ((*store)->Update(Record("bakeJobs/zz", "", v1::BakeJob::RUNNING)).code(),
              absl::StatusCode::kNotFound);
    auto deleted = (*store)->Delete("bakeJobs/d");
    ASSERT_TRUE(deleted.ok());
    EXPECT_TRUE(*deleted);
    EXPECT_FALSE(*(*store)->Delete("bakeJobs/d"));
  }
  auto store = JobStore::Open(path);
  ASSERT_TRUE(store.ok());
  auto a = (*store)->FindByRequestId("r1");
  ASSERT_TRUE(a.ok() && a->has_value());
  EXPECT_EQ((*a)->record.name(), "bakeJobs/a");
  auto b = (*store)->Get("bakeJobs/b");
  ASSERT_TRUE(b.ok() && b->has_value());
  EXPECT_EQ((*b)->record.state(), v1::BakeJob::RUNNING);
  EXPECT_EQ((*b)->record.attempts(), 1);
  EXPECT_FALSE((*b)->record.has_job());  // the spec is stored apart
  auto spec = (*store)->GetSpec("bakeJobs/b");
  ASSERT_TRUE(spec.ok() && spec->has_value());
  EXPECT_EQ((*spec)->grid().counts(0), 4);
  EXPECT_FALSE((*store)->Get("bakeJobs/d")->has_value());
  EXPECT_EQ(*(*store)->CountInState(v1::BakeJob::QUEUED), 1);
  auto running = (*store)->ListInState(v1::BakeJob::RUNNING);
  ASSERT_EQ(running->size(), 1u);
  EXPECT_EQ((*running)[0].record.name(), "bakeJobs/b");
}

TEST(JobStore, ListPagesInInsertionOrder) {
  TempDir dir;
  auto store = *JobStore::Open(dir.path() / "jobs.sqlite");
  for (int i = 0; i < 7; ++i)
    ASSERT_TRUE(
        store->Insert(Record("bakeJobs/" + std::to_string(i), "", v1::BakeJob::QUEUED), Spec(1))
            .ok());
  std::vector<std::string> seen;
  int64_t after = 0;
  while (true) {
    auto page = store->List(after, 3);
    ASSERT_TRUE(page.ok());
    if (page->empty()) break;
    for (const StoredJob& job : *page) seen.push_back(job.record.name());
    after = page->back().seq;
  }
  ASSERT_EQ(seen.size(), 7u);
  for (int i = 0; i < 7; ++i) EXPECT_EQ(seen[size_t(i)], "bakeJobs/" + std::to_string(i));
}

TEST(JobStore, ClusterRunsSurviveReopenUntilDeleted) {
  // The Slurm backend's record of a job's arrays (slurm_backend.h) must outlive a restart, or a
  // restarted server would submit the job's shards a second time.
  TempDir dir;
  auto path = dir.path() / "jobs.sqlite";
  {
    auto store = JobStore::Open(path);
    ASSERT_TRUE(store.ok()) << store.status();
    ASSERT_TRUE((*store)->PutClusterRun("bakeJobs/b", std::string("run\0b", 5)).ok());
    ASSERT_TRUE((*store)->PutClusterRun("bakeJobs/a", "first").ok());
    ASSERT_TRUE((*store)->PutClusterRun("bakeJobs/a", "second").ok());  // replaced
  }
  auto store = JobStore::Open(path);
  ASSERT_TRUE(store.ok()) << store.status();
  auto a = (*store)->GetClusterRun("bakeJobs/a");
  ASSERT_TRUE(a.ok() && a->has_value());
  EXPECT_EQ(**a, "second");
  auto b = (*store)->GetClusterRun("bakeJobs/b");
  ASSERT_TRUE(b.ok() && b->has_value());
  EXPECT_EQ(**b, std::string("run\0b", 5));
  auto names = (*store)->ListClusterRuns();
  ASSERT_TRUE(names.ok());
  EXPECT_EQ(*names, (std::vector<std::string>{"bakeJobs/a", "bakeJobs/b"}));
  ASSERT_TRUE((*store)->DeleteClusterRun("bakeJobs/a").ok());
  ASSERT_TRUE((*store)->DeleteClusterRun("bakeJobs/none").ok());
  auto gone = (*store)->GetClusterRun("bakeJobs/a");
  ASSERT_TRUE(gone.ok());
  EXPECT_FALSE(gone->has_value());
}

TEST(JobStore, ResultCacheAndTransactions) {
  TempDir dir;
  auto store = *JobStore::Open(dir.path() / "jobs.sqlite");
  std::string key(64, 'b');
  EXPECT_FALSE(store->GetCached(key)->has_value());
  v1::BakeJobResult result;
  result.mutable_volume()->set_hash(std::string(64, 'c'));
  result.mutable_volume()->set_size_bytes(42);
  result.set_source_job("bakeJobs/x");
  ASSERT_TRUE(store->PutCached(key, result).ok());
  auto cached = store->GetCached(key);
  ASSERT_TRUE(cached.ok() && cached->has_value());
  EXPECT_EQ((*cached)->volume().size_bytes(), 42);
  // A failed transaction leaves nothing behind.
  absl::Status failed = store->Transaction([&]() -> absl::Status {
    EXPECT_TRUE(store->DeleteCached(key).ok());
    EXPECT_TRUE(store->Insert(Record("bakeJobs/t", "", v1::BakeJob::QUEUED), Spec(1)).ok());
    return absl::InternalError("abort");
  });
  EXPECT_FALSE(failed.ok());
  EXPECT_TRUE(store->GetCached(key)->has_value());
  EXPECT_FALSE(store->Get("bakeJobs/t")->has_value());
}

}  // namespace
}  // namespace probebake::server
