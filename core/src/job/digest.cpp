#include "probebake/job/digest.h"

#include <openssl/evp.h>

#include "probebake/base/check.h"

namespace probebake {

// Failures of the EVP calls mean allocation failure or a broken OpenSSL: a bug, not user input.
struct Sha256::Context {
  EVP_MD_CTX* md = nullptr;
};

Sha256::Sha256() : context_(std::make_unique<Context>()) {
  context_->md = EVP_MD_CTX_new();
  PB_CHECK(context_->md != nullptr && EVP_DigestInit_ex(context_->md, EVP_sha256(), nullptr) == 1);
}

Sha256::~Sha256() {
  EVP_MD_CTX_free(context_->md);
}

void Sha256::Update(std::string_view bytes) {
  PB_CHECK(EVP_DigestUpdate(context_->md, bytes.data(), bytes.size()) == 1);
}

std::string Sha256::FinalHex() {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  PB_CHECK(EVP_DigestFinal_ex(context_->md, md, &length) == 1);
  PB_CHECK_EQ(length, 32u);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex(2 * length, '0');
  for (unsigned int i = 0; i < length; ++i) {
    hex[2 * i] = kHex[md[i] >> 4];
    hex[2 * i + 1] = kHex[md[i] & 15];
  }
  return hex;
}

std::string Sha256Hex(std::string_view bytes) {
  Sha256 hash;
  hash.Update(bytes);
  return hash.FinalHex();
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
