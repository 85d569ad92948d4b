#include "server/auth.h"

#include <openssl/crypto.h>

#include <string_view>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "probebake/base/status.h"
#include "runtime/files.h"

namespace probebake::server {

absl::StatusOr<std::string> TokenAuth::ReadTokenFile(const std::filesystem::path& path) {
  absl::StatusOr<std::string> bytes = runtime::ReadWholeFile(path);
  if (!bytes.ok())
    return absl::InvalidArgumentError(
        absl::StrCat("--token-file ", path.string(), ": ", std::string(bytes.status().message())));
  std::string token(absl::StripAsciiWhitespace(*bytes));
  if (token.empty())
    return absl::InvalidArgumentError(absl::StrCat("--token-file ", path.string(), ": empty"));
  for (char c : token) {
    if (c < 0x21 || c > 0x7e)
      return absl::InvalidArgumentError(absl::StrCat(
          "--token-file ", path.string(), ": the token must be printable ASCII without spaces"));
  }
  return token;
}

grpc::Status TokenAuth::CheckValue(const std::string* authorization) const {
  if (!token_) return grpc::Status::OK;
  if (!authorization)
    return {grpc::StatusCode::UNAUTHENTICATED,
            "missing \"authorization: Bearer <token>\" metadata"};
  constexpr std::string_view kScheme = "bearer ";
  if (authorization->size() < kScheme.size() ||
      !absl::EqualsIgnoreCase(absl::string_view(*authorization).substr(0, kScheme.size()),
                              absl::string_view(kScheme.data(), kScheme.size())))
    return {grpc::StatusCode::UNAUTHENTICATED,
            "the authorization metadata must be \"Bearer <token>\""};
  std::string_view given = std::string_view(*authorization).substr(kScheme.size());
  // Constant time in the token's content, so the comparison does not leak a prefix.
  if (given.size() != token_->size() ||
      CRYPTO_memcmp(given.data(), token_->data(), given.size()) != 0)
    return {grpc::StatusCode::UNAUTHENTICATED, "invalid bearer token"};
  return grpc::Status::OK;
}

grpc::Status TokenAuth::Check(const grpc::ServerContextBase& context) const {
  if (!token_) return grpc::Status::OK;
  const auto& metadata = context.client_metadata();
  auto it = metadata.find("authorization");
  if (it == metadata.end()) return CheckValue(nullptr);
  std::string value(it->second.data(), it->second.size());
  return CheckValue(&value);
}

namespace {

class AuthInterceptor : public grpc::experimental::Interceptor {
 public:
  AuthInterceptor(grpc::experimental::ServerRpcInfo* info, std::shared_ptr<const TokenAuth> auth)
      : info_(info), auth_(std::move(auth)) {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(
            grpc::experimental::InterceptionHookPoints::POST_RECV_INITIAL_METADATA)) {
      const std::string* value = nullptr;
      std::string authorization;
      auto* metadata = methods->GetRecvInitialMetadata();
      auto it = metadata->find("authorization");
      if (it != metadata->end()) {
        authorization.assign(it->second.data(), it->second.size());
        value = &authorization;
      }
      if (!auth_->CheckValue(value).ok()) info_->server_context()->TryCancel();
    }
    methods->Proceed();
  }

 private:
  grpc::experimental::ServerRpcInfo* info_;
  std::shared_ptr<const TokenAuth> auth_;
};

}  // namespace

grpc::experimental::Interceptor* AuthInterceptorFactory::CreateServerInterceptor(
    grpc::experimental::ServerRpcInfo* info) {
  absl::string_view method = info->method();
  if (!auth_->enabled() || absl::StartsWith(method, "/grpc.health.v1.") ||
      absl::StartsWith(method, "/probebake.v1."))
    return nullptr;
  return new AuthInterceptor(info, auth_);
}

}  // namespace probebake::server
