// Error reporting: absl::Status / absl::StatusOr throughout, with helpers for the one message shape
// users see for bad input: "<field path>: <reason>", e.g.
// "scene.lights[2].rect.edge1: zero length".
//
// Pitfall: Debian 12's abseil has its own absl::string_view (not std::string_view), so
// Status::message() needs std::string(...) before it meets std::string_view or fmt.
#pragma once

#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace probebake {

// INVALID_ARGUMENT "<path>: <reason>".
inline absl::Status FieldError(std::string_view path, std::string_view reason) {
  std::string message(path);
  message += ": ";
  message += reason;
  return absl::InvalidArgumentError(message);
}

}  // namespace probebake

// Returns the status of `expr` from the enclosing function when it is not OK.
#define PB_RETURN_IF_ERROR(expr)                 \
  do {                                           \
    ::absl::Status pb_status_ = (expr);          \
    if (!pb_status_.ok()) [[unlikely]]           \
      return pb_status_;                         \
  } while (false)

#define PB_CONCAT_INNER_(a, b) a##b
#define PB_CONCAT_(a, b) PB_CONCAT_INNER_(a, b)
#define PB_ASSIGN_OR_RETURN_IMPL_(var, lhs, expr) \
  auto var = (expr);                              \
  if (!var.ok()) [[unlikely]]                     \
    return std::move(var).status();               \
  lhs = *std::move(var)
// `lhs = *expr` when expr (an absl::StatusOr) is OK, else returns its status.
#define PB_ASSIGN_OR_RETURN(lhs, expr) \
  PB_ASSIGN_OR_RETURN_IMPL_(PB_CONCAT_(pb_statusor_, __LINE__), lhs, expr)
