// errno as an absl::Status: the one mapping for every file operation in probebake (the volume
// writer, the server's stores, the CLI).
//
// Only the codes a caller acts on are told apart: RESOURCE_EXHAUSTED (the disk or a size limit is
// full: free space and try again; the server keeps a bake's volume in memory and retries) and
// NOT_FOUND (no such file or folder). Every other errno is INTERNAL. absl::ErrnoToStatusCode is not
// used because its other codes would blame the caller of an RPC for the server's own file: EACCES
// on the server's data folder is not the client's PERMISSION_DENIED (which the CLI reports as a
// failed login), nor EIO a retryable UNAVAILABLE.
#pragma once

#include <string_view>

#include "absl/status/status.h"

namespace probebake {

// "<path>: <what>: <strerror(errorNumber)>" with the code above. `what` says what failed
// ("open", "cannot rename <temp> to it").
absl::Status IoError(int errorNumber, std::string_view path, std::string_view what);

}  // namespace probebake
