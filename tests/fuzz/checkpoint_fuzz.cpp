// Checkpoint files, read back when a server restarts a job. The input is a checkpoint's body: the
// target appends its SHA-256 as the writer does, so that mutations reach the parser instead of
// stopping at the checksum (which a damaged file on disk would pass only by accident). Seed:
// the body of a real checkpoint of a partly baked demo corner (27 probes, order 1).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

#include "probebake/base/log.h"
#include "probebake/job/digest.h"
#include "server/checkpoint.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = (probebake::SetLogLevel(spdlog::level::off), true);
  (void)quiet;
  static const std::string path = "/tmp/probebake-fuzz-checkpoint-" + std::to_string(getpid());
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    out << probebake::Sha256Hex(std::string_view(reinterpret_cast<const char*>(data), size));
  }
  (void)probebake::server::ReadCheckpointOfAnyJob(path);
  return 0;
}
