#include "probebake/base/io_error.h"

#include <cerrno>
#include <cstring>
#include <string>

namespace probebake {

absl::Status IoError(int errorNumber, std::string_view path, std::string_view what) {
  std::string message(path);
  message += ": ";
  message += what;
  message += ": ";
  message += std::strerror(errorNumber);
  if (errorNumber == ENOSPC || errorNumber == EDQUOT || errorNumber == EFBIG)
    return absl::ResourceExhaustedError(message);
  if (errorNumber == ENOENT) return absl::NotFoundError(message);
  return absl::InternalError(message);
}

}  // namespace probebake
