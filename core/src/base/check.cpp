#include "probebake/base/check.h"

#include <cstdio>
#include <cstdlib>

namespace probebake::detail {

void CheckFailed(const char* file, int line, const std::string& message) {
  // Not through spdlog: the logger may be what failed, and this line must reach stderr.
  std::fprintf(stderr, "%s:%d: %s\n", file, line, message.c_str());
  std::fflush(stderr);
  std::abort();
}

}  // namespace probebake::detail
