// Probe volume files (.vdb) through the reader `probebake inspect`, `merge` and the server use.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include "probebake/base/log.h"
#include "probebake/volume/vdb_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = (probebake::SetLogLevel(spdlog::level::off), true);
  (void)quiet;
  static const std::string path = "/tmp/probebake-fuzz-volume-" + std::to_string(getpid()) + ".vdb";
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  (void)probebake::ReadProbeVolume(path);
  return 0;
}
