// Internal invariant checks (pbrt-style). PB_CHECK* are always on and print both operands on
// failure before aborting: they guard bugs, never user input (user input gets an absl::Status
// naming the field). PB_DCHECK* compile away in release builds and are for hot loops only.
#pragma once

#include <sstream>
#include <string>

namespace probebake::detail {

[[noreturn]] void CheckFailed(const char* file, int line, const std::string& message);

template <typename A, typename B>
[[noreturn]] void CheckOpFailed(const char* file, int line, const char* expr, const A& a,
                                const B& b) {
  std::ostringstream s;
  s.precision(17);
  s << "Check failed: " << expr << " (" << a << " vs. " << b << ")";
  CheckFailed(file, line, s.str());
}

}  // namespace probebake::detail

#define PB_CHECK(cond)                                                           \
  do {                                                                           \
    if (!(cond)) [[unlikely]]                                                    \
      ::probebake::detail::CheckFailed(__FILE__, __LINE__, "Check failed: " #cond); \
  } while (false)

#define PB_CHECK_OP(a, b, op)                                                                \
  do {                                                                                       \
    const auto& pb_a_ = (a);                                                                 \
    const auto& pb_b_ = (b);                                                                 \
    if (!(pb_a_ op pb_b_)) [[unlikely]]                                                      \
      ::probebake::detail::CheckOpFailed(__FILE__, __LINE__, #a " " #op " " #b, pb_a_, pb_b_); \
  } while (false)

#define PB_CHECK_EQ(a, b) PB_CHECK_OP(a, b, ==)
#define PB_CHECK_NE(a, b) PB_CHECK_OP(a, b, !=)
#define PB_CHECK_LT(a, b) PB_CHECK_OP(a, b, <)
#define PB_CHECK_LE(a, b) PB_CHECK_OP(a, b, <=)
#define PB_CHECK_GT(a, b) PB_CHECK_OP(a, b, >)
#define PB_CHECK_GE(a, b) PB_CHECK_OP(a, b, >=)

#ifdef NDEBUG
#define PB_DCHECK(cond) \
  do {                  \
  } while (false && (cond))
#define PB_DCHECK_OP(a, b, op) \
  do {                         \
  } while (false && ((a)op(b)))
#else
#define PB_DCHECK(cond) PB_CHECK(cond)
#define PB_DCHECK_OP(a, b, op) PB_CHECK_OP(a, b, op)
#endif
#define PB_DCHECK_EQ(a, b) PB_DCHECK_OP(a, b, ==)
#define PB_DCHECK_LT(a, b) PB_DCHECK_OP(a, b, <)
#define PB_DCHECK_LE(a, b) PB_DCHECK_OP(a, b, <=)
#define PB_DCHECK_GE(a, b) PB_DCHECK_OP(a, b, >=)
