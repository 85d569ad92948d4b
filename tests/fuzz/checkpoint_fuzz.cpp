// Checkpoint files, read back when a server restarts a job.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

#include "probebake/base/log.h"
#include "server/checkpoint.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = (probebake::SetLogLevel(spdlog::level::off), true);
  (void)quiet;
  static const std::string path = "/tmp/probebake-fuzz-checkpoint-" + std::to_string(getpid());
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  (void)probebake::server::ReadCheckpointOfAnyJob(path);
  return 0;
}
