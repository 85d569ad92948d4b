#include "server/slurm_commands.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>

#include "absl/strings/ascii.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "runtime/subprocess.h"

namespace probebake::server {
namespace {

// slurmctld answers in well under a second; a minute means it is gone.
constexpr std::chrono::seconds kCommandTimeout{60};

absl::StatusOr<std::string> FindTool(const std::filesystem::path& binDir, const std::string& name) {
  std::vector<std::string> dirs;
  if (!binDir.empty()) {
    dirs.push_back(binDir.string());
  } else if (const char* path = std::getenv("PATH")) {
    dirs = absl::StrSplit(path, ':', absl::SkipEmpty());
  }
  for (const std::string& dir : dirs) {
    const std::filesystem::path candidate = std::filesystem::path(dir) / name;
    if (access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return absl::NotFoundError(
      absl::StrCat(name, " not found ", binDir.empty() ? "in $PATH" : "in " + binDir.string(),
                   " (the Slurm backend needs sbatch, squeue and scancel: Debian's slurm-client)"));
}

std::string Names(const std::vector<std::string>& names) {
  return absl::StrJoin(names, ",");
}

}  // namespace

bool IsEndedSlurmState(const std::string& state) {
  for (const char* ended : {"COMPLETED", "FAILED", "CANCELLED", "TIMEOUT", "NODE_FAIL",
                            "OUT_OF_MEMORY", "PREEMPTED", "BOOT_FAIL", "DEADLINE", "REVOKED"}) {
    if (state == ended) return true;
  }
  return false;
}

absl::StatusOr<SlurmCommands> SlurmCommands::Find(const std::filesystem::path& binDir) {
  SlurmCommands commands;
  absl::StatusOr<std::string> sbatch = FindTool(binDir, "sbatch");
  if (!sbatch.ok()) return sbatch.status();
  absl::StatusOr<std::string> squeue = FindTool(binDir, "squeue");
  if (!squeue.ok()) return squeue.status();
  absl::StatusOr<std::string> scancel = FindTool(binDir, "scancel");
  if (!scancel.ok()) return scancel.status();
  commands.sbatch_ = *sbatch;
  commands.squeue_ = *squeue;
  commands.scancel_ = *scancel;
  return commands;
}

absl::StatusOr<std::string> SlurmCommands::Run(std::vector<std::string> argv) const {
  const std::string shown = absl::StrJoin(argv, " ");
  absl::StatusOr<runtime::ChildExit> exit =
      runtime::RunChild(std::move(argv), kCommandTimeout, "slurm", /*stderrToOut=*/true);
  if (!exit.ok()) return absl::UnavailableError(std::string(exit.status().message()));
  if (exit->timedOut)
    return absl::UnavailableError(
        absl::StrCat(shown, ": no answer in ", kCommandTimeout.count(), " s"));
  if (!WIFEXITED(exit->waitStatus) || WEXITSTATUS(exit->waitStatus) != 0)
    return absl::UnavailableError(absl::StrCat(shown, ": ", absl::StripAsciiWhitespace(exit->out)));
  return exit->out;
}

absl::StatusOr<std::string> SlurmCommands::Submit(const SbatchRequest& r) const {
  std::vector<std::string> argv = {sbatch_,
                                   "--parsable",
                                   "--job-name=" + r.jobName,
                                   "--array=" + absl::StrJoin(r.tasks, ","),
                                   "--chdir=" + r.workDir.string(),
                                   "--output=" + r.outputPattern.string(),
                                   "--open-mode=append"};
  if (!r.partition.empty()) argv.push_back("--partition=" + r.partition);
  if (r.cpusPerTask > 0) argv.push_back(absl::StrCat("--cpus-per-task=", r.cpusPerTask));
  argv.insert(argv.end(), r.extraArgs.begin(), r.extraArgs.end());
  argv.push_back(r.script.string());
  absl::StatusOr<std::string> out = Run(std::move(argv));
  if (!out.ok()) return out.status();
  // "<job id>" or "<job id>;<cluster>", possibly after warnings on stderr: the last line.
  std::vector<absl::string_view> lines =
      absl::StrSplit(absl::StripAsciiWhitespace(*out), '\n', absl::SkipWhitespace());
  const std::string id(
      lines.empty() ? ""
                    : absl::StripAsciiWhitespace(lines.back().substr(0, lines.back().find(';'))));
  int64_t number = 0;
  if (!absl::SimpleAtoi(id, &number))
    return absl::UnavailableError(absl::StrCat("sbatch printed no job id: ", *out));
  return id;
}

absl::StatusOr<std::map<std::pair<std::string, int>, SlurmTask>> SlurmCommands::Tasks(
    const std::vector<std::string>& names) const {
  std::map<std::pair<std::string, int>, SlurmTask> tasks;
  if (names.empty()) return tasks;
  absl::StatusOr<std::string> out =
      Run({squeue_, "-h", "-r", "--states=all", "--name=" + Names(names), "-o", "%F|%K|%T|%r"});
  if (!out.ok()) return out.status();
  for (absl::string_view line : absl::StrSplit(*out, '\n', absl::SkipWhitespace())) {
    std::vector<std::string> f = absl::StrSplit(absl::StripAsciiWhitespace(line), '|');
    int task = 0;
    if (f.size() != 4 || !absl::SimpleAtoi(f[1], &task)) continue;  // not a task line
    tasks[{f[0], task}] = {f[2], f[3]};
  }
  return tasks;
}

absl::StatusOr<std::optional<std::string>> SlurmCommands::FindByName(
    const std::string& name) const {
  absl::StatusOr<std::string> out =
      Run({squeue_, "-h", "--states=all", "--name=" + name, "-o", "%F"});
  if (!out.ok()) return out.status();
  for (absl::string_view line : absl::StrSplit(*out, '\n', absl::SkipWhitespace())) {
    int64_t id = 0;
    if (absl::SimpleAtoi(absl::StripAsciiWhitespace(line), &id))
      return std::optional<std::string>(std::string(absl::StripAsciiWhitespace(line)));
  }
  return std::optional<std::string>();
}

absl::StatusOr<bool> SlurmCommands::AnyActive(const std::vector<std::string>& names) const {
  if (names.empty()) return false;
  absl::StatusOr<std::string> out = Run({squeue_, "-h", "--name=" + Names(names), "-o", "%F"});
  if (!out.ok()) return out.status();
  return !absl::StripAsciiWhitespace(*out).empty();
}

absl::Status SlurmCommands::Cancel(const std::vector<std::string>& ids) const {
  if (ids.empty()) return absl::OkStatus();
  std::vector<std::string> argv = {scancel_};
  argv.insert(argv.end(), ids.begin(), ids.end());
  return Run(std::move(argv)).status();
}

}  // namespace probebake::server
