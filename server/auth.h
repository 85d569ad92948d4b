// Bearer-token authentication (docs/service.md): with a token configured, every RPC but gRPC health
// checking must carry "authorization: Bearer <token>" metadata, else UNAUTHENTICATED.
//
// probebake's own handlers call TokenAuth::Check first thing. Services the gRPC library
// implements (server reflection) are covered by AuthInterceptorFactory, which cancels their
// unauthenticated calls: a server interceptor cannot choose the status, so those clients see
// CANCELLED rather than UNAUTHENTICATED.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <grpcpp/server_context.h>
#include <grpcpp/support/server_interceptor.h>

#include "absl/status/statusor.h"

namespace probebake::server {

class TokenAuth {
 public:
  // No token: every call is accepted (the loopback default).
  explicit TokenAuth(std::optional<std::string> token = std::nullopt) : token_(std::move(token)) {}

  // The token in `path`, surrounding whitespace removed. INVALID_ARGUMENT when the file cannot be
  // read or holds no token.
  static absl::StatusOr<std::string> ReadTokenFile(const std::filesystem::path& path);

  bool enabled() const { return token_.has_value(); }

  // OK, or UNAUTHENTICATED saying what is wrong (missing metadata, wrong scheme, wrong token).
  grpc::Status Check(const grpc::ServerContextBase& context) const;
  // The same check on a raw "authorization" value (nullptr: absent).
  grpc::Status CheckValue(const std::string* authorization) const;

 private:
  std::optional<std::string> token_;
};

// Cancels unauthenticated calls to every method outside grpc.health.v1 and probebake.v1.
class AuthInterceptorFactory : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  explicit AuthInterceptorFactory(std::shared_ptr<const TokenAuth> auth) : auth_(std::move(auth)) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override;

 private:
  std::shared_ptr<const TokenAuth> auth_;
};

}  // namespace probebake::server
