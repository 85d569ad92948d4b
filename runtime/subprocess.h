// Running a child process to completion with a time limit, its stdout captured: how the CLI and
// the server keep work that may crash or hang (importing a client's assets) out of their own
// process.
#pragma once

#include <chrono>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace probebake::runtime {

// How a child ended.
struct ChildExit {
  std::string out;        // everything it wrote to stdout (until the time limit, if killed)
  bool timedOut = false;  // ran past the limit and was killed with SIGKILL
  int waitStatus = 0;     // waitpid's status: WIFEXITED / WEXITSTATUS, WIFSIGNALED / WTERMSIG
};

// Runs `argv` (argv[0] a path, not searched in $PATH) with stdin from /dev/null, stdout piped
// back, stderr inherited (or piped back with stdout when `stderrToOut`), and no signal blocked (the
// server blocks SIGTERM and SIGINT in every thread for its sigwait; the child must not inherit
// that). Waits for it to close stdout and exit, killing it once `timeout` has passed. Errors:
// INTERNAL "<what>: cannot run <argv[0]>:
// ..." when the child could not be started; `what` names the caller's purpose.
absl::StatusOr<ChildExit> RunChild(std::vector<std::string> argv, std::chrono::seconds timeout,
                                   const std::string& what, bool stderrToOut = false);

}  // namespace probebake::runtime
