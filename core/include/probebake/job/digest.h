// Content digests (docs/service.md): lowercase hex SHA-256, as in the Remote Execution API. Blobs,
// scene and job digests all use this one function.
#pragma once

#include <string>
#include <string_view>

#include "probebake/v1/job.pb.h"

namespace probebake {

// SHA-256 of `bytes` as 64 lowercase hex characters.
std::string Sha256Hex(std::string_view bytes);

// The Digest of `bytes`: {hash: Sha256Hex(bytes), sizeBytes: bytes.size()}.
v1::Digest DigestOf(std::string_view bytes);

// True when `hash` is 64 lowercase hex characters (the only form a Digest.hash may take).
bool IsSha256Hex(std::string_view hash);

}  // namespace probebake
