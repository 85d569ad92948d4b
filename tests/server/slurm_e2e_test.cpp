// The Slurm backend end to end (docs/cluster.md) on a real one-node Slurm cluster on loopback
// (scripts/slurm-cluster.sh, started here and stopped at the end): probebake-server --backend
// slurm bakes the demo (fewer samples per probe) in 4 shards bit-identically to a local bake; a
// shard killed mid-bake is submitted again and the result is still identical; a cancel leaves no
// array in squeue; a server killed with SIGKILL mid-array and restarted finishes the job with the
// one array it submitted. And the farm-side path without the server (integrations/slurm/submit.sh:
// an array and a merge job after it). Skipped, saying why, without Slurm's daemons or root.
#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <thread>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "runtime/shard_progress.h"
#include "subprocess.h"
#include "temp_dir.h"
#include "test_server.h"
#include "volume_compare.h"

namespace probebake::testing {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using std::chrono::steady_clock;

const std::string kCli = PROBEBAKE_CLI;
const std::string kServer = PROBEBAKE_SERVER;
const std::filesystem::path kSource = PROBEBAKE_SOURCE_DIR;
constexpr int kShards = 4;
// The demo (tests/data/demo) at 512 instead of 1024 samples per probe: a shard bakes for about a
// second on one of this machine's two cores, long enough to be killed mid-bake.
constexpr int kSamples = 512;

// The full path of `tool` in $PATH ("" when absent).
std::string Which(const std::string& tool) {
  const char* path = std::getenv("PATH");
  for (absl::string_view dir : absl::StrSplit(path ? path : "", ':', absl::SkipEmpty())) {
    const std::filesystem::path candidate = std::filesystem::path(std::string(dir)) / tool;
    if (access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  for (const char* dir : {"/usr/sbin", "/sbin"}) {
    const std::filesystem::path candidate = std::filesystem::path(dir) / tool;
    if (access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

// SLURM_CONF of the test cluster, for the Slurm clients.
std::string gSlurmConf;

std::map<std::string, std::string> Env() {
  return {{"SLURM_CONF", gSlurmConf}};
}

// A Slurm command's output (the test fails when it fails).
std::string Slurm(std::vector<std::string> argv) {
  argv[0] = Which(argv[0]);
  const RunResult r = testing::Run(argv, Env(), seconds(60));
  EXPECT_EQ(r.exitCode, 0) << argv[0] << ": " << r.err;
  return r.out;
}

// The one-node cluster every test of the suite shares, and the local bake they compare with.
class SlurmCluster : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    skip_.clear();
    if (geteuid() != 0) {
      skip_ = "not root: slurmd starts jobs as their users, so the test cluster needs root";
      return;
    }
    for (const char* tool : {"munged", "slurmctld", "slurmd", "sbatch", "squeue", "scancel"}) {
      if (Which(tool).empty()) {
        skip_ = absl::StrCat(tool, " not installed (Debian: apt-get install slurm-wlm munge)");
        return;
      }
    }
    dir_ = new TempDir();
    gSlurmConf = (dir_->path() / "cluster" / "slurm.conf").string();
    const RunResult started =
        testing::Run({"/bin/bash", (kSource / "scripts" / "slurm-cluster.sh").string(), "start",
                      (dir_->path() / "cluster").string()},
                     {}, seconds(60));
    started_ = started.exitCode == 0;
    startLog_ = started.out + started.err;
    std::printf("%s", startLog_.c_str());

    // The job, and what a local bake of it gives.
    const std::filesystem::path demo = kSource / "tests" / "data" / "demo";
    for (const char* asset : {"boxes.obj", "sky.exr"})
      std::filesystem::copy_file(demo / asset, dir_->path() / asset);
    std::string json = ReadFile(demo / "demo.json");
    const std::string from = "\"samplesPerProbe\": 1024";
    const size_t at = json.find(from);
    if (at != std::string::npos)
      json.replace(at, from.size(), absl::StrCat("\"samplesPerProbe\": ", kSamples));
    std::ofstream(dir_->path() / "demo.json") << json;
    const auto start = steady_clock::now();
    local_ = testing::Run({kCli, "bake", Job(), "-o", LocalVolume(), "--threads", "2"}, {},
                          seconds(300));
    std::printf("local bake of the demo at %d samples per probe: %.2f s\n", kSamples,
                SecondsSince(start));
  }

  static void TearDownTestSuite() {
    if (!dir_) return;
    testing::Run({"/bin/bash", (kSource / "scripts" / "slurm-cluster.sh").string(), "stop",
                  (dir_->path() / "cluster").string()},
                 {}, seconds(60));
    delete dir_;
    dir_ = nullptr;
  }

  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_;
    ASSERT_TRUE(started_) << startLog_;
    ASSERT_EQ(local_.exitCode, 0) << local_.err;
  }

  static std::string Job() { return (dir_->path() / "demo.json").string(); }
  static std::string LocalVolume() { return (dir_->path() / "local.vdb").string(); }

  static std::string Cli(std::vector<std::string> args, milliseconds timeout = seconds(300)) {
    args.insert(args.begin(), kCli);
    const RunResult r = testing::Run(args, {}, timeout);
    EXPECT_NE(r.exitCode, -100) << "timed out: " << args[1];
    return r.exitCode == 0 ? r.out : "exit " + std::to_string(r.exitCode) + ": " + r.out + r.err;
  }

  static inline std::string skip_;
  static inline TempDir* dir_ = nullptr;
  static inline std::string startLog_;
  static inline bool started_ = false;
  static inline RunResult local_;
};

// probebake-server --backend slurm on `data` (the job store) and `shared` (the shared folder).
class SlurmServer {
 public:
  SlurmServer(const std::filesystem::path& dir, const std::map<std::string, std::string>& env)
      : dir_(dir) {
    const std::filesystem::path portFile = dir / absl::StrCat("port", ++starts_);
    std::filesystem::remove(portFile);
    process_ = std::make_unique<Subprocess>(
        std::vector<std::string>{
            kServer, "--listen", "127.0.0.1:0", "--data-dir", (dir / "data").string(),
            "--port-file", portFile.string(), "--threads", "1", "--backend", "slurm",
            "--slurm-shared-dir", (dir / "shared").string(), "--slurm-shards",
            std::to_string(kShards), "--slurm-poll-interval", "0.25", "--slurm-probebake", kCli},
        dir / "server.log", env);
    port_ = WaitForPortFile(portFile, seconds(30)).value_or(0);
  }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  Subprocess& process() { return *process_; }
  std::string log() const { return ReadFile(dir_ / "server.log"); }
  bool up() const { return port_ > 0; }

 private:
  static inline int starts_ = 0;
  std::filesystem::path dir_;
  std::unique_ptr<Subprocess> process_;
  int port_ = 0;
};

std::string JobName(const std::string& submitOut) {
  const size_t at = submitOut.find("bakeJobs/");
  return at == std::string::npos ? "" : submitOut.substr(at, 9 + 16);
}

// The progress of the first shard of job `id` found baking under `shared`, within `timeout`.
std::optional<runtime::ShardProgress> WaitForBakingShard(const std::filesystem::path& shared,
                                                         const std::string& id,
                                                         milliseconds timeout) {
  const auto deadline = steady_clock::now() + timeout;
  while (steady_clock::now() < deadline) {
    for (int i = 0; i < kShards; ++i) {
      const std::filesystem::path file =
          shared / id / "progress" / absl::StrCat("shard-", i, ".json");
      std::error_code ec;
      if (!std::filesystem::exists(file, ec)) continue;
      absl::StatusOr<runtime::ShardProgress> p = runtime::ParseShardProgress(ReadFile(file));
      if (p.ok() && p->stage == "baking") return *p;
    }
    std::this_thread::sleep_for(milliseconds(10));
  }
  return std::nullopt;
}

// squeue's lines "<job name>|<task>|<state>" of every task of job `id`'s submissions, any state.
std::vector<std::string> TasksOf(const std::string& squeueOut, const std::string& id) {
  std::vector<std::string> lines;
  for (absl::string_view line : absl::StrSplit(squeueOut, '\n', absl::SkipWhitespace()))
    if (line.find("probebake-" + id) != absl::string_view::npos) lines.emplace_back(line);
  std::sort(lines.begin(), lines.end());
  return lines;
}

std::string AllTasks(const std::string& id) {
  return absl::StrJoin(TasksOf(Slurm({"squeue", "-h", "-r", "--states=all", "-o", "%j|%K|%T"}), id),
                       "\n");
}

// AllTasks of a job baked by its first array alone, each shard run once.
std::string OneArrayEachShardOnce(const std::string& id) {
  std::string expected;
  for (int i = 0; i < kShards; ++i)
    absl::StrAppend(&expected, i ? "\n" : "", "probebake-", id, "-0|", i, "|COMPLETED");
  return expected;
}

TEST_F(SlurmCluster, FourShardsBakeBitIdenticallyToALocalBake) {
  TempDir dir;
  SlurmServer server(dir.path(), Env());
  ASSERT_TRUE(server.up()) << server.log();
  const std::filesystem::path out = dir.path() / "slurm.vdb";
  const auto start = steady_clock::now();
  const std::string submitted =
      Cli({"submit", Job(), "--server", server.address(), "-o", out.string()});
  ASSERT_NE(JobName(submitted), "") << submitted << server.log();
  std::printf("submit -o through Slurm, %d shards: %.2f s\n", kShards, SecondsSince(start));
  ExpectSameVolume(LocalVolume(), out);
  const std::string id = JobName(submitted).substr(9);
  EXPECT_EQ(AllTasks(id), OneArrayEachShardOnce(id));
  // Its shared folder is gone with the job's end.
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "shared" / id)) << server.log();
  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(20)), 0);
}

TEST_F(SlurmCluster, AShardKilledMidBakeIsRetriedAndTheResultIsTheSame) {
  TempDir dir;
  SlurmServer server(dir.path(), Env());
  ASSERT_TRUE(server.up()) << server.log();
  const std::string submitted = Cli({"submit", Job(), "--server", server.address()});
  const std::string name = JobName(submitted);
  ASSERT_NE(name, "") << submitted;
  const std::string id = name.substr(9);
  const std::optional<runtime::ShardProgress> victim =
      WaitForBakingShard(dir.path() / "shared", id, seconds(120));
  ASSERT_TRUE(victim) << server.log();
  ASSERT_EQ(kill(pid_t(victim->pid), SIGKILL), 0);
  const std::filesystem::path out = dir.path() / "slurm.vdb";
  const std::string watched = Cli({"watch", name, "--server", server.address()});
  EXPECT_EQ(watched.rfind("exit", 0), std::string::npos) << watched << server.log();
  EXPECT_EQ(Cli({"fetch", name, "--server", server.address(), "-o", out.string()}).rfind("exit", 0),
            std::string::npos);
  ExpectSameVolume(LocalVolume(), out);
  // The killed task failed, and a second submission baked its shard.
  const std::string tasks = AllTasks(id);
  EXPECT_NE(tasks.find(absl::StrCat("probebake-", id, "-0|", victim->shard, "|FAILED")),
            std::string::npos)
      << tasks;
  EXPECT_NE(tasks.find(absl::StrCat("probebake-", id, "-1|", victim->shard, "|COMPLETED")),
            std::string::npos)
      << tasks;
  EXPECT_NE(server.log().find(absl::StrCat("shard ", victim->shard)), std::string::npos);
  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(20)), 0);
}

TEST_F(SlurmCluster, CancelLeavesNoArrayInSqueue) {
  TempDir dir;
  SlurmServer server(dir.path(), Env());
  ASSERT_TRUE(server.up()) << server.log();
  const std::string name = JobName(Cli({"submit", Job(), "--server", server.address()}));
  ASSERT_NE(name, "");
  const std::string id = name.substr(9);
  ASSERT_TRUE(WaitForBakingShard(dir.path() / "shared", id, seconds(120))) << server.log();
  const auto start = steady_clock::now();
  const std::string cancelled = Cli({"cancel", name, "--server", server.address()});
  std::printf("cancel with shards running (scancel until squeue shows none): %.2f s\n",
              SecondsSince(start));
  EXPECT_NE(cancelled.find("CANCELLED"), std::string::npos) << cancelled << server.log();
  // Nothing of it pending, running or completing.
  EXPECT_EQ(TasksOf(Slurm({"squeue", "-h", "-r", "-o", "%j|%K|%T"}), id),
            std::vector<std::string>());
  EXPECT_NE(AllTasks(id).find("CANCELLED"), std::string::npos) << AllTasks(id);
  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(20)), 0);
}

TEST_F(SlurmCluster, AServerKilledMidArrayFinishesTheJobOnceAfterItsRestart) {
  TempDir dir;
  std::string name, id;
  {
    SlurmServer server(dir.path(), Env());
    ASSERT_TRUE(server.up()) << server.log();
    name = JobName(Cli({"submit", Job(), "--server", server.address()}));
    ASSERT_NE(name, "");
    id = name.substr(9);
    ASSERT_TRUE(WaitForBakingShard(dir.path() / "shared", id, seconds(120))) << server.log();
    server.process().Signal(SIGKILL);
    EXPECT_EQ(server.process().Wait(seconds(10)), -SIGKILL);
  }
  std::this_thread::sleep_for(seconds(1));
  SlurmServer restarted(dir.path(), Env());
  ASSERT_TRUE(restarted.up()) << restarted.log();
  const std::string watched = Cli({"watch", name, "--server", restarted.address()});
  EXPECT_EQ(watched.rfind("exit", 0), std::string::npos) << watched << restarted.log();
  const std::filesystem::path out = dir.path() / "slurm.vdb";
  EXPECT_EQ(
      Cli({"fetch", name, "--server", restarted.address(), "-o", out.string()}).rfind("exit", 0),
      std::string::npos);
  ExpectSameVolume(LocalVolume(), out);
  EXPECT_NE(restarted.log().find("re-attached"), std::string::npos) << restarted.log();
  // The one array of the first run: nothing was submitted again.
  EXPECT_EQ(AllTasks(id), OneArrayEachShardOnce(id));
  // One job, succeeded, listed once.
  const std::string listed = Cli({"list", "--server", restarted.address()});
  EXPECT_EQ(listed.find(name), listed.rfind(name)) << listed;
  EXPECT_NE(listed.find("SUCCEEDED"), std::string::npos) << listed;
  restarted.process().Signal(SIGTERM);
  EXPECT_EQ(restarted.process().Wait(seconds(20)), 0);
}

TEST_F(SlurmCluster, TheFarmSideScriptsBakeAndMergeWithoutTheServer) {
  TempDir dir;
  std::map<std::string, std::string> env = Env();
  env["PROBEBAKE"] = kCli;
  const RunResult submitted =
      testing::Run({"/bin/bash", (kSource / "integrations" / "slurm" / "submit.sh").string(), Job(),
                    "3", (dir.path() / "out").string()},
                   env, seconds(60));
  ASSERT_EQ(submitted.exitCode, 0) << submitted.err;
  const std::vector<std::string> words = absl::StrSplit(submitted.out, ' ');
  ASSERT_GE(words.size(), 6u) << submitted.out;
  const std::string merge = std::string(absl::StripSuffix(words[5], ":"));
  std::string state;
  const auto deadline = steady_clock::now() + seconds(240);
  while (steady_clock::now() < deadline) {
    state = Slurm({"squeue", "-h", "--states=all", "-j", merge, "-o", "%T"});
    if (state.find("COMPLETED") != std::string::npos || state.find("FAIL") != std::string::npos ||
        state.find("CANCELLED") != std::string::npos)
      break;
    std::this_thread::sleep_for(milliseconds(200));
  }
  ASSERT_NE(state.find("COMPLETED"), std::string::npos)
      << state << ReadFile(dir.path() / "out" / "logs" / "merge.log");
  ExpectSameVolume(LocalVolume(), dir.path() / "out" / "result.vdb");
}

TEST_F(SlurmCluster, SubmitToStartLatency) {
  // Per task of an array of trivial tasks on an idle cluster: from just before sbatch to the
  // task's first line (docs/cluster.md). Two tasks at a time fit this node's two CPUs.
  TempDir dir;
  const std::filesystem::path script = dir.path() / "stamp.sh";
  std::ofstream(script) << "#!/bin/sh\ndate +%s.%N > \"" << dir.path().string()
                        << "/start-$SLURM_ARRAY_TASK_ID\"\n";
  std::vector<double> latencies;
  for (int round = 0; round < 5; ++round) {
    const double submit =
        std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    Slurm({"sbatch", "--parsable", "--array=0-1", "--job-name=probebake-latency",
           "--output=/dev/null", script.string()});
    for (int task = 0; task < 2; ++task) {
      const std::filesystem::path stamp = dir.path() / absl::StrCat("start-", task);
      const auto deadline = steady_clock::now() + seconds(60);
      while (steady_clock::now() < deadline && ReadFile(stamp).empty())
        std::this_thread::sleep_for(milliseconds(20));
      double started = 0;
      ASSERT_TRUE(absl::SimpleAtod(absl::StripAsciiWhitespace(ReadFile(stamp)), &started));
      latencies.push_back(started - submit);
      std::filesystem::remove(stamp);
    }
    std::this_thread::sleep_for(milliseconds(500));  // both tasks gone from the node
  }
  std::sort(latencies.begin(), latencies.end());
  std::printf(
      "submit-to-start latency per task, %zu tasks: min %.2f s, median %.2f s, max %.2f s\n",
      latencies.size(), latencies.front(), latencies[latencies.size() / 2], latencies.back());
}

}  // namespace
}  // namespace probebake::testing
