#include "probebake/job/digest.h"

#include <openssl/evp.h>

#include "probebake/base/check.h"

namespace probebake {

std::string Sha256Hex(std::string_view bytes) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  // EVP_Digest fails only on allocation failure or a broken OpenSSL: a bug, not user input.
  PB_CHECK(EVP_Digest(bytes.data(), bytes.size(), md, &length, EVP_sha256(), nullptr) == 1);
  PB_CHECK_EQ(length, 32u);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex(2 * length, '0');
  for (unsigned int i = 0; i < length; ++i) {
    hex[2 * i] = kHex[md[i] >> 4];
    hex[2 * i + 1] = kHex[md[i] & 15];
  }
  return hex;
}

v1::Digest DigestOf(std::string_view bytes) {
  v1::Digest digest;
  digest.set_hash(Sha256Hex(bytes));
  digest.set_size_bytes(int64_t(bytes.size()));
  return digest;
}

bool IsSha256Hex(std::string_view hash) {
  if (hash.size() != 64) return false;
  for (char c : hash)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
}

}  // namespace probebake
