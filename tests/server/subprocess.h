// Child processes for end-to-end tests: servers started and killed by the test, and CLI runs with
// their exit code and output captured.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace probebake::testing {

class Subprocess {
 public:
  // Starts argv[0] with `argv`, stdout and stderr appended to `logFile`, and `env` added to
  // the environment.
  Subprocess(const std::vector<std::string>& argv, const std::filesystem::path& logFile,
             const std::map<std::string, std::string>& env = {});
  ~Subprocess();  // SIGKILL and reap when still running
  Subprocess(const Subprocess&) = delete;
  Subprocess& operator=(const Subprocess&) = delete;

  pid_t pid() const { return pid_; }
  bool started() const { return pid_ > 0; }
  void Signal(int signal) const;
  // The exit code, or -signal when killed; nullopt when it did not end within `timeout`.
  std::optional<int> Wait(std::chrono::milliseconds timeout);

 private:
  pid_t pid_ = -1;
  bool reaped_ = false;
};

struct RunResult {
  int exitCode = -1;  // -signal when killed, -100 on timeout
  std::string out, err;
};

// Runs a command to completion (killed after `timeout`).
RunResult Run(const std::vector<std::string>& argv,
              const std::map<std::string, std::string>& env = {},
              std::chrono::milliseconds timeout = std::chrono::seconds(60));

// The port a server wrote to `portFile` (--port-file), once it exists; nullopt after `timeout`.
std::optional<int> WaitForPortFile(const std::filesystem::path& portFile,
                                   std::chrono::milliseconds timeout);

std::string ReadFile(const std::filesystem::path& path);

}  // namespace probebake::testing
