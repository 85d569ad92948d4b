// Content digests (docs/service.md): lowercase hex SHA-256, as in the Remote Execution API. Blobs,
// scene and job digests all use this one function.
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include "probebake/v1/job.pb.h"

namespace probebake {

// Incremental SHA-256 (OpenSSL), for bytes that arrive in pieces (uploads, files read in blocks).
// The one SHA-256 of probebake: Sha256Hex below and the runtime's Sha256OfFile use it.
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void Update(std::string_view bytes);
  // 64 lowercase hex characters: the digest of everything given. The object is spent afterwards.
  std::string FinalHex();

 private:
  struct Context;
  std::unique_ptr<Context> context_;
};

// SHA-256 of `bytes` as 64 lowercase hex characters.
std::string Sha256Hex(std::string_view bytes);

// The Digest of `bytes`: {hash: Sha256Hex(bytes), sizeBytes: bytes.size()}.
v1::Digest DigestOf(std::string_view bytes);

// True when `hash` is 64 lowercase hex characters (the only form a Digest.hash may take).
bool IsSha256Hex(std::string_view hash);

}  // namespace probebake
