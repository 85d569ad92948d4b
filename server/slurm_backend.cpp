#include "server/slurm_backend.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <thread>

#include <google/protobuf/util/json_util.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_replace.h"
#include "probebake/base/check.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/job.h"
#include "probebake/volume/vdb_io.h"
#include "probebake/volume/volume_merge.h"
#include "runtime/files.h"
#include "runtime/job_state.h"
#include "runtime/shard_plan.h"
#include "runtime/shard_progress.h"
#include "server/blob_store.h"
#include "server/cluster_run.pb.h"
#include "server/job_store.h"
#include "server/slurm_commands.h"

namespace probebake::server {
namespace {

using Clock = std::chrono::steady_clock;

// How long a cancelled run waits for squeue to show none of its arrays (Slurm's KillWait, 30 s by
// default, is the longest a task takes to die after scancel's SIGTERM).
constexpr std::chrono::seconds kCancelWait{90};
// What a failed shard's error quotes of its log.
constexpr size_t kLogTailLines = 12;
constexpr size_t kLogTailBytes = 2000;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// `text` in single quotes for sh.
std::string ShellQuote(const std::string& text) {
  return "'" + absl::StrReplaceAll(text, {{"'", "'\\''"}}) + "'";
}

// The last lines of the file at `path` ("" when it cannot be read).
std::string Tail(const std::filesystem::path& path) {
  absl::StatusOr<std::string> text = runtime::ReadWholeFile(path);
  if (!text.ok()) return "";
  std::string t = *text;
  if (t.size() > kLogTailBytes) t = t.substr(t.size() - kLogTailBytes);
  size_t at = t.size(), lines = 0;
  while (at > 0 && lines <= kLogTailLines) {
    at = t.rfind('\n', at - 1);
    if (at == std::string::npos) return t;
    ++lines;
  }
  return t.substr(at + 1);
}

// Where one shard is.
enum class ShardState { kUnsubmitted, kLive, kDone, kFailed };

class SlurmRunner {
 public:
  SlurmRunner(BackendContext context, SlurmConfig config, SlurmCommands commands)
      : blobs_(context.blobs),
        store_(context.store),
        config_(std::move(config)),
        slurm_(std::move(commands)) {}

  absl::StatusOr<ProbeVolume> Bake(const BakeRun& run, const BakeJob& job,
                                   const BakeOptions& options);
  // Cancels what is left of job `name`'s arrays, removes its folder and its run. Best effort:
  // failures are logged.
  void Release(const std::string& name);
  // Releases the runs of jobs that ended or were deleted while the server was down.
  void ReleaseEnded();

 private:
  // One run being followed by Bake.
  struct Run {
    std::string jobName;
    std::string id;  // the job's id: its folder's and its arrays' names
    std::filesystem::path folder;
    ClusterRun record;
    runtime::ShardPlan plan;
    const BakeOptions* options = nullptr;
    Clock::time_point start;
    // Per shard: since when its task has ended (or was forgotten) without a part.
    std::vector<std::optional<Clock::time_point>> missingSince;
    std::vector<runtime::ShardProgress> progress;
    std::vector<bool> failedNow;  // failed this poll, whatever Slurm says (an unreadable part)
  };

  std::filesystem::path PartPath(const Run& r, int shard) const {
    return r.folder / "parts" / absl::StrCat("part-", shard, ".vdb");
  }
  std::filesystem::path ProgressPath(const Run& r, int shard) const {
    return r.folder / "progress" / absl::StrCat("shard-", shard, ".json");
  }
  std::filesystem::path LogPath(const Run& r, int shard) const {
    return r.folder / "logs" / absl::StrCat("shard-", shard, ".log");
  }

  absl::StatusOr<std::optional<ClusterRun>> LoadRecord(const std::string& name) const;
  absl::Status Save(const Run& r) const;
  // The plan of `job` in config_'s shard count (`shards` > 0: that many).
  absl::StatusOr<runtime::ShardPlan> Plan(const BakeJob& job, int shards, int threads) const;
  // A new run: the folder filled, the record stored.
  absl::Status Start(Run& r, const v1::JobSpec& spec, const BakeJob& job);
  absl::Status WriteFolder(const Run& r, const v1::JobSpec& spec, const BakeJob& job) const;
  // A submission made just before a crash, its id unknown: adopted when slurmctld knows its name,
  // forgotten otherwise (its shards are then submitted again).
  absl::Status AdoptPending(Run& r) const;
  // Submits `shards` as one array (stored before and after sbatch).
  absl::Status Submit(Run& r, const std::vector<int>& shards) const;
  // Every shard's state from squeue's tasks and the part files: how many tasks are pending and
  // running, the pending tasks' first reason, and how each shard that failed ended (lastEnd).
  std::vector<ShardState> Survey(Run& r,
                                 const std::map<std::pair<std::string, int>, SlurmTask>& tasks,
                                 int* pending, int* running, std::string* pendingReason,
                                 std::vector<std::string>* lastEnd) const;
  void ReportProgress(Run& r, const std::vector<ShardState>& states) const;
  // The job's error once shard `shard` has failed every attempt.
  absl::Status ShardFailed(const Run& r, int shard, const std::string& lastEnd) const;
  // scancel every array of the run and wait until squeue shows none.
  absl::Status CancelArrays(const Run& r) const;
  // The parts merged; an unreadable part is removed and its shard marked failed (*retry).
  absl::StatusOr<ProbeVolume> Merge(Run& r, const BakeJob& job, bool* retry) const;
  // Sleeps one poll interval, or less when the job is cancelled.
  void Pause(const Run& r) const;

  const BlobStore* blobs_;
  JobStore* store_;
  const SlurmConfig config_;
  const SlurmCommands slurm_;
};

absl::StatusOr<std::optional<ClusterRun>> SlurmRunner::LoadRecord(const std::string& name) const {
  PB_ASSIGN_OR_RETURN(std::optional<std::string> bytes, store_->GetClusterRun(name));
  if (!bytes) return std::optional<ClusterRun>();
  ClusterRun record;
  if (!record.ParseFromString(*bytes))
    return absl::DataLossError(absl::StrCat(name, ": unreadable cluster run in the job store"));
  return std::optional<ClusterRun>(std::move(record));
}

absl::Status SlurmRunner::Save(const Run& r) const {
  return store_->PutClusterRun(r.jobName, r.record.SerializeAsString());
}

absl::StatusOr<runtime::ShardPlan> SlurmRunner::Plan(const BakeJob& job, int shards,
                                                     int threads) const {
  PB_ASSIGN_OR_RETURN(const runtime::WorkEstimate estimate, runtime::EstimateWork(job, threads));
  const int64_t points = job.grid.ProbeCount();
  if (shards <= 0) {
    if (config_.shards > 0) {
      shards = config_.shards;
    } else {
      PB_ASSIGN_OR_RETURN(const runtime::ShardPlan whole,
                          runtime::PlanShards(job.grid, estimate, 1));
      shards = int(std::clamp<int64_t>(
          (whole.expectedProbes + config_.probesPerShard - 1) / config_.probesPerShard, 1,
          int64_t(1) << 20));
    }
    shards = int(std::min<int64_t>(shards, points));
  }
  return runtime::PlanShards(job.grid, estimate, shards);
}

absl::Status SlurmRunner::WriteFolder(const Run& r, const v1::JobSpec& spec,
                                      const BakeJob& job) const {
  std::error_code ec;
  std::filesystem::remove_all(r.folder, ec);
  for (const char* sub : {"blobs", "parts", "progress", "logs"}) {
    std::filesystem::create_directories(r.folder / sub, ec);
    if (ec)
      return absl::FailedPreconditionError(absl::StrCat(
          "--slurm-shared-dir: cannot create ", (r.folder / sub).string(), ": ", ec.message()));
  }
  std::string json;
  if (!google::protobuf::util::MessageToJsonString(spec, &json).ok())
    return absl::InternalError("the job's spec does not print as JSON");
  PB_RETURN_IF_ERROR(runtime::WriteFileAtomic(r.folder / "job.json", json));
  for (const BlobReference& ref : ListBlobReferences(spec)) {
    const v1::Digest& digest = ref.digest;
    PB_ASSIGN_OR_RETURN(std::string bytes, blobs_->ReadAll(digest));
    PB_RETURN_IF_ERROR(runtime::WriteFileAtomic(r.folder / "blobs" / digest.hash(), bytes));
  }
  // Task I of the array bakes shard I; its threads are the CPUs Slurm gave it.
  const std::string script = absl::StrCat(
      "#!/bin/sh\n"
      "# Shard $SLURM_ARRAY_TASK_ID of ",
      r.record.shard_count(), " of probebake job ", r.jobName,
      ", written by probebake-server (docs/cluster.md).\n"
      "exec ",
      ShellQuote(config_.probebake.string()),
      " bake job.json --blob-dir blobs --shard \"$SLURM_ARRAY_TASK_ID/", r.record.shard_count(),
      "\" \\\n"
      "  -o \"parts/part-$SLURM_ARRAY_TASK_ID.vdb\" "
      "--progress-file \"progress/shard-$SLURM_ARRAY_TASK_ID.json\" \\\n"
      "  --expect-job-digest ",
      job.jobDigest, " --threads \"${SLURM_CPUS_PER_TASK:-${SLURM_CPUS_ON_NODE:-0}}\"\n");
  PB_RETURN_IF_ERROR(runtime::WriteFileAtomic(r.folder / "shard.sh", script));
  std::filesystem::permissions(r.folder / "shard.sh", std::filesystem::perms::owner_exec,
                               std::filesystem::perm_options::add, ec);
  return absl::OkStatus();
}

absl::Status SlurmRunner::Start(Run& r, const v1::JobSpec& spec, const BakeJob& job) {
  r.record = ClusterRun();
  r.record.set_job_digest(job.jobDigest);
  r.record.set_shard_count(int(r.plan.shards.size()));
  r.record.mutable_attempts()->Resize(r.record.shard_count(), 0);
  PB_RETURN_IF_ERROR(WriteFolder(r, spec, job));
  PB_RETURN_IF_ERROR(Save(r));
  Logger("slurm")->info("{}: {} shards ({} probes expected, imbalance {:.3f}) in {}", r.jobName,
                        r.plan.shards.size(), r.plan.expectedProbes, r.plan.Imbalance(),
                        r.folder.string());
  return absl::OkStatus();
}

absl::Status SlurmRunner::AdoptPending(Run& r) const {
  if (r.record.submissions_size() == 0) return absl::OkStatus();
  ClusterSubmission* last = r.record.mutable_submissions(r.record.submissions_size() - 1);
  if (!last->slurm_job_id().empty()) return absl::OkStatus();
  PB_ASSIGN_OR_RETURN(std::optional<std::string> id, slurm_.FindByName(last->name()));
  if (id) {
    last->set_slurm_job_id(*id);
    Logger("slurm")->info("{}: adopted array {} ({}), submitted before the restart", r.jobName, *id,
                          last->name());
  } else {
    for (int shard : last->shards()) r.record.set_attempts(shard, r.record.attempts(shard) - 1);
    Logger("slurm")->info("{}: submission {} never reached Slurm; its shards go again", r.jobName,
                          last->name());
    r.record.mutable_submissions()->RemoveLast();
  }
  return Save(r);
}

absl::Status SlurmRunner::Submit(Run& r, const std::vector<int>& shards) const {
  ClusterSubmission* sub = r.record.add_submissions();
  sub->set_name(absl::StrCat("probebake-", r.id, "-", r.record.submissions_size() - 1));
  for (int shard : shards) {
    sub->add_shards(shard);
    r.record.set_attempts(shard, r.record.attempts(shard) + 1);
    std::error_code ec;
    std::filesystem::remove(ProgressPath(r, shard), ec);  // an earlier attempt's
  }
  // Stored first: a crash from here on leaves its name for AdoptPending.
  PB_RETURN_IF_ERROR(Save(r));
  SbatchRequest request;
  request.script = r.folder / "shard.sh";
  request.workDir = r.folder;
  request.jobName = sub->name();
  request.tasks = shards;
  request.outputPattern = r.folder / "logs" / "shard-%a.log";
  request.partition = config_.partition;
  request.cpusPerTask = config_.cpusPerTask;
  request.extraArgs = config_.sbatchArgs;
  absl::StatusOr<std::string> id = slurm_.Submit(request);
  if (!id.ok()) {
    for (int shard : shards) r.record.set_attempts(shard, r.record.attempts(shard) - 1);
    r.record.mutable_submissions()->RemoveLast();
    PB_RETURN_IF_ERROR(Save(r));
    return id.status();
  }
  sub->set_slurm_job_id(*id);
  PB_RETURN_IF_ERROR(Save(r));
  Logger("slurm")->info("{}: array {} ({}): shards {}", r.jobName, *id, sub->name(),
                        absl::StrJoin(shards, ","));
  return absl::OkStatus();
}

std::vector<ShardState> SlurmRunner::Survey(
    Run& r, const std::map<std::pair<std::string, int>, SlurmTask>& tasks, int* pending,
    int* running, std::string* pendingReason, std::vector<std::string>* lastEnd) const {
  const int n = r.record.shard_count();
  // The latest submission of each shard.
  std::vector<const ClusterSubmission*> latest(size_t(n), nullptr);
  for (const ClusterSubmission& sub : r.record.submissions())
    for (int shard : sub.shards()) latest[size_t(shard)] = &sub;
  std::vector<ShardState> states(size_t(n), ShardState::kUnsubmitted);
  *pending = *running = 0;
  const auto grace = std::chrono::duration<double>(config_.missingPartGraceSeconds);
  for (int i = 0; i < n; ++i) {
    ShardState& state = states[size_t(i)];
    std::error_code ec;
    if (r.failedNow[size_t(i)]) {
      r.failedNow[size_t(i)] = false;
      state = ShardState::kFailed;
      (*lastEnd)[size_t(i)] = "its part could not be read";
      continue;
    }
    if (std::filesystem::exists(PartPath(r, i), ec)) {
      state = ShardState::kDone;
      r.missingSince[size_t(i)].reset();
      continue;
    }
    const ClusterSubmission* sub = latest[size_t(i)];
    if (!sub) continue;
    auto task = tasks.find({sub->slurm_job_id(), i});
    if (task != tasks.end() && !IsEndedSlurmState(task->second.state)) {
      state = ShardState::kLive;
      r.missingSince[size_t(i)].reset();
      if (task->second.state == "PENDING") {
        ++*pending;
        if (pendingReason->empty()) *pendingReason = task->second.reason;
      } else {
        ++*running;
      }
      continue;
    }
    const std::string where = absl::StrCat("Slurm job ", sub->slurm_job_id(), "_", i);
    if (task != tasks.end() && task->second.state != "COMPLETED") {
      state = ShardState::kFailed;
      (*lastEnd)[size_t(i)] =
          absl::StrCat(where, " ended ", task->second.state, " (", task->second.reason, ")");
      continue;
    }
    // COMPLETED, or forgotten by slurmctld, and no part (yet: the shared folder may show it late).
    if (!r.missingSince[size_t(i)]) r.missingSince[size_t(i)] = Clock::now();
    state = ShardState::kLive;
    if (Clock::now() - *r.missingSince[size_t(i)] >= grace) {
      state = ShardState::kFailed;
      (*lastEnd)[size_t(i)] =
          absl::StrCat(where, task != tasks.end() ? " COMPLETED" : " is no longer known to Slurm",
                       " but wrote no part in ", config_.missingPartGraceSeconds, " s");
    }
  }
  return states;
}

void SlurmRunner::ReportProgress(Run& r, const std::vector<ShardState>& states) const {
  BakeProgress total;
  for (size_t i = 0; i < states.size(); ++i) {
    runtime::ShardProgress& p = r.progress[i];
    if (p.stage != "done") {
      absl::StatusOr<std::string> text = runtime::ReadWholeFile(ProgressPath(r, int(i)));
      if (text.ok()) {
        absl::StatusOr<runtime::ShardProgress> read = runtime::ParseShardProgress(*text);
        if (read.ok()) p = *read;
      }
    }
    const int64_t shardTotal = p.probesTotal > 0 ? p.probesTotal : r.plan.shards[i].expectedProbes;
    total.probesTotal += shardTotal;
    total.probesDone += states[i] == ShardState::kDone ? shardTotal : p.probesDone;
    total.samples += p.samples;
    total.rays += p.rays;
  }
  total.elapsedSeconds = SecondsSince(r.start);
  if (total.probesDone > 0 && total.probesDone < total.probesTotal)
    total.etaSeconds = total.elapsedSeconds * double(total.probesTotal - total.probesDone) /
                       double(total.probesDone);
  if (r.options->progress) r.options->progress(total);
}

absl::Status SlurmRunner::ShardFailed(const Run& r, int shard, const std::string& lastEnd) const {
  std::string tail = Tail(LogPath(r, shard));
  return absl::AbortedError(absl::StrCat(
      "shard ", shard, " of ", r.record.shard_count(), " failed ", r.record.attempts(shard),
      " time(s) (1 + --slurm-retries ", config_.retries, "); the last: ", lastEnd, "; its log ",
      LogPath(r, shard).string(), tail.empty() ? " is empty" : " ends:\n" + tail));
}

absl::Status SlurmRunner::CancelArrays(const Run& r) const {
  std::vector<std::string> ids, names;
  for (const ClusterSubmission& sub : r.record.submissions()) {
    names.push_back(sub.name());
    if (!sub.slurm_job_id().empty()) ids.push_back(sub.slurm_job_id());
  }
  if (names.empty()) return absl::OkStatus();
  PB_RETURN_IF_ERROR(slurm_.Cancel(ids));
  const auto deadline = Clock::now() + kCancelWait;
  while (Clock::now() < deadline) {
    absl::StatusOr<bool> active = slurm_.AnyActive(names);
    if (active.ok() && !*active) return absl::OkStatus();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  return absl::DeadlineExceededError(absl::StrCat("scancel ", absl::StrJoin(ids, " "),
                                                  ": tasks still listed after ",
                                                  kCancelWait.count(), " s"));
}

absl::StatusOr<ProbeVolume> SlurmRunner::Merge(Run& r, const BakeJob& job, bool* retry) const {
  *retry = false;
  const auto start = Clock::now();
  std::vector<VolumePart> parts;
  for (int i = 0; i < r.record.shard_count(); ++i) {
    const std::string path = PartPath(r, i).string();
    absl::StatusOr<ProbeVolumeFile> file = ReadProbeVolume(path);
    if (!file.ok()) {
      // A part damaged on its way (a node that died mid-rename on a file system that does not
      // keep that atomic): baked again.
      Logger("slurm")->warn("{}: {}; shard {} is baked again", r.jobName,
                            std::string(file.status().message()), i);
      std::error_code ec;
      std::filesystem::remove(path, ec);
      r.failedNow[size_t(i)] = true;
      *retry = true;
      continue;
    }
    const ProbeGrid expected = runtime::ShardGrid(job.grid, r.plan.shards[size_t(i)]);
    const ProbeGrid& got = file->volume.grid;
    if (got.counts[0] != expected.counts[0] || got.counts[1] != expected.counts[1] ||
        got.counts[2] != expected.counts[2] || !(got.origin == expected.origin))
      return absl::InternalError(absl::StrCat(path, ": not the sub-grid the plan gives shard ", i,
                                              ": the shards planned another split"));
    if (file->meta.sceneDigest != job.sceneDigest || file->meta.settingsJson != job.settingsJson)
      return absl::InternalError(
          absl::StrCat(path, ": baked from another scene or settings than the job's"));
    parts.push_back({path, std::move(*file)});
  }
  if (*retry) return absl::UnavailableError("parts to bake again");
  PB_ASSIGN_OR_RETURN(ProbeVolumeFile merged, MergeProbeVolumes(std::move(parts)));
  for (int a = 0; a < 3; ++a) {
    if (merged.volume.grid.counts[a] != job.grid.counts[a])
      return absl::InternalError("the parts do not cover the job's grid");
  }
  Logger("slurm")->info("{}: {} parts merged ({} probes) in {:.3f} s", r.jobName,
                        r.record.shard_count(), merged.volume.stats.probes, SecondsSince(start));
  return std::move(merged.volume);
}

void SlurmRunner::Pause(const Run& r) const {
  const auto until = Clock::now() + std::chrono::duration<double>(config_.pollSeconds);
  while (Clock::now() < until && !r.options->cancel->load())
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

absl::StatusOr<ProbeVolume> SlurmRunner::Bake(const BakeRun& bakeRun, const BakeJob& job,
                                              const BakeOptions& options) {
  PB_CHECK(options.cancel != nullptr);
  PB_CHECK(bakeRun.spec != nullptr);
  Run r;
  r.jobName = bakeRun.jobName;
  r.id = bakeRun.jobName.substr(bakeRun.jobName.find('/') + 1);
  r.folder = config_.sharedDir / r.id;
  r.options = &options;
  r.start = Clock::now();
  auto log = Logger("slurm");

  PB_ASSIGN_OR_RETURN(std::optional<ClusterRun> stored, LoadRecord(r.jobName));
  if (stored && stored->job_digest() != job.jobDigest) {
    // The baker changed while the job ran (the server was upgraded): what its shards baked is
    // not this job's.
    log->warn("{}: its run baked job digest {}, the job is now {}: starting over", r.jobName,
              stored->job_digest(), job.jobDigest);
    r.record = *stored;
    if (absl::Status cancelled = CancelArrays(r); !cancelled.ok())
      log->warn("{}: {}", r.jobName, std::string(cancelled.message()));
    stored.reset();
  }
  if (stored) {
    r.record = std::move(*stored);
    PB_ASSIGN_OR_RETURN(r.plan, Plan(job, r.record.shard_count(), options.threads));
    log->info("{}: re-attached to its {} submission(s) ({} shards)", r.jobName,
              r.record.submissions_size(), r.record.shard_count());
    PB_RETURN_IF_ERROR(AdoptPending(r));
  } else {
    PB_ASSIGN_OR_RETURN(r.plan, Plan(job, 0, options.threads));
    PB_RETURN_IF_ERROR(Start(r, *bakeRun.spec, job));
  }
  const int n = r.record.shard_count();
  r.missingSince.assign(size_t(n), std::nullopt);
  r.progress.assign(size_t(n), {});
  r.failedNow.assign(size_t(n), false);

  std::vector<std::string> lastEnd(static_cast<size_t>(n));
  bool slurmDown = false;
  for (;;) {
    if (options.cancel->load()) {
      if (!bakeRun.cancelledByClient()) {
        log->info(
            "{}: the server stops; its arrays keep running and are followed again after "
            "the restart",
            r.jobName);
        return absl::CancelledError("the server is shutting down");
      }
      if (absl::Status cancelled = CancelArrays(r); !cancelled.ok())
        log->warn("{}: {}", r.jobName, std::string(cancelled.message()));
      else
        log->info("{}: cancelled; no array of it is left in squeue", r.jobName);
      return absl::CancelledError("cancelled by CancelBakeJob");
    }
    std::vector<std::string> names;
    for (const ClusterSubmission& sub : r.record.submissions()) names.push_back(sub.name());
    absl::StatusOr<std::map<std::pair<std::string, int>, SlurmTask>> tasks = slurm_.Tasks(names);
    if (!tasks.ok()) {
      // slurmctld restarting or unreachable: the tasks go on; wait for it.
      if (!slurmDown) log->warn("{}: {}", r.jobName, std::string(tasks.status().message()));
      slurmDown = true;
      bakeRun.setWaiting(absl::StrCat("Slurm does not answer: ", tasks.status().message()));
      Pause(r);
      continue;
    }
    slurmDown = false;
    int pending = 0, running = 0;
    std::string pendingReason;
    const std::vector<ShardState> states =
        Survey(r, *tasks, &pending, &running, &pendingReason, &lastEnd);
    std::vector<int> toSubmit;
    int done = 0;
    for (int i = 0; i < n; ++i) {
      switch (states[size_t(i)]) {
        case ShardState::kDone:
          ++done;
          break;
        case ShardState::kUnsubmitted:
          toSubmit.push_back(i);
          break;
        case ShardState::kFailed:
          if (r.record.attempts(i) >= 1 + config_.retries) {
            const absl::Status failed = ShardFailed(r, i, lastEnd[size_t(i)]);
            if (absl::Status cancelled = CancelArrays(r); !cancelled.ok())
              log->warn("{}: {}", r.jobName, std::string(cancelled.message()));
            return failed;
          }
          log->warn("{}: shard {}: {}; submitted again (attempt {} of {})", r.jobName, i,
                    lastEnd[size_t(i)], r.record.attempts(i) + 1, 1 + config_.retries);
          toSubmit.push_back(i);
          break;
        case ShardState::kLive:
          break;
      }
    }
    if (!toSubmit.empty()) {
      if (absl::Status submitted = Submit(r, toSubmit); !submitted.ok()) {
        if (!absl::IsUnavailable(submitted)) return submitted;
        bakeRun.setWaiting(absl::StrCat("sbatch failed, retrying: ", submitted.message()));
        Pause(r);
        continue;
      }
      for (int i : toSubmit) r.missingSince[size_t(i)].reset();
    }
    ReportProgress(r, states);
    if (running == 0 && pending > 0)
      bakeRun.setWaiting(absl::StrCat(pending, " shard(s) pending in Slurm (", pendingReason, ")"));
    else
      bakeRun.setWaiting("");
    if (done == n) {
      bool retry = false;
      absl::StatusOr<ProbeVolume> merged = Merge(r, job, &retry);
      if (!retry) return merged;
      continue;
    }
    Pause(r);
  }
}

void SlurmRunner::Release(const std::string& name) {
  auto log = Logger("slurm");
  absl::StatusOr<std::optional<ClusterRun>> record = LoadRecord(name);
  if (!record.ok()) {
    log->warn("{}: {}", name, std::string(record.status().message()));
    return;
  }
  if (!*record) return;
  Run r;
  r.jobName = name;
  r.id = name.substr(name.find('/') + 1);
  r.folder = config_.sharedDir / r.id;
  r.record = std::move(**record);
  std::vector<std::string> names;
  for (const ClusterSubmission& sub : r.record.submissions()) names.push_back(sub.name());
  absl::StatusOr<bool> active = slurm_.AnyActive(names);
  if (!active.ok() || *active) {
    if (absl::Status cancelled = CancelArrays(r); !cancelled.ok())
      log->warn("{}: {}", name, std::string(cancelled.message()));
  }
  std::error_code ec;
  std::filesystem::remove_all(r.folder, ec);
  if (ec) log->warn("{}: cannot remove {}: {}", name, r.folder.string(), ec.message());
  if (absl::Status deleted = store_->DeleteClusterRun(name); !deleted.ok())
    log->warn("{}: {}", name, std::string(deleted.message()));
}

void SlurmRunner::ReleaseEnded() {
  absl::StatusOr<std::vector<std::string>> names = store_->ListClusterRuns();
  if (!names.ok()) {
    Logger("slurm")->warn("cluster runs: {}", std::string(names.status().message()));
    return;
  }
  for (const std::string& name : *names) {
    absl::StatusOr<std::optional<StoredJob>> job = store_->Get(name);
    if (!job.ok()) continue;
    if (!*job || runtime::IsFinal((*job)->record.state())) {
      Logger("slurm")->info("{}: the job ended while the server was down; its run is removed",
                            name);
      Release(name);
    }
  }
}

}  // namespace

absl::StatusOr<BakeBackend> SlurmBackend(const BackendContext& context, const SlurmConfig& config) {
  if (config.sharedDir.empty() || !config.sharedDir.is_absolute())
    return FieldError("--slurm-shared-dir",
                      "an absolute path is required (the same on every node)");
  std::error_code ec;
  std::filesystem::create_directories(config.sharedDir, ec);
  if (ec || !std::filesystem::is_directory(config.sharedDir))
    return FieldError("--slurm-shared-dir",
                      absl::StrCat(config.sharedDir.string(), " is not a folder we can use: ",
                                   ec ? ec.message() : "not a folder"));
  if (config.shards <= 0 && config.probesPerShard <= 0)
    return FieldError("--slurm-shards", "give a shard count or --slurm-probes-per-shard");
  if (config.retries < 0) return FieldError("--slurm-retries", "must be >= 0");
  if (!(config.pollSeconds > 0)) return FieldError("--slurm-poll-interval", "must be > 0");
  if (access(config.probebake.c_str(), X_OK) != 0)
    return FieldError("--slurm-probebake",
                      absl::StrCat(config.probebake.string(), " is not an executable"));
  PB_ASSIGN_OR_RETURN(SlurmCommands commands, SlurmCommands::Find(config.binDir));
  auto runner = std::make_shared<SlurmRunner>(context, config, std::move(commands));
  runner->ReleaseEnded();

  BakeBackend backend = ProductionBackend(context.blobs, context.limits);
  backend.bake = [runner](const BakeRun& run, const BakeJob& job, const BakeOptions& options) {
    return runner->Bake(run, job, options);
  };
  backend.release = [runner](const std::string& name) { runner->Release(name); };
  return backend;
}

}  // namespace probebake::server
