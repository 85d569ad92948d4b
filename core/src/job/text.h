// Small text helpers for the job module's messages (private to core/src/job).
#pragma once

#include <charconv>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>

namespace probebake::job_internal {

// Shortest text that reads back as exactly `x` ("0.1", "1e+300", "nan", "inf").
inline std::string Num(double x) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}
template <typename T>
requires std::is_integral_v<T> std::string Num(T x) {
  return std::to_string(x);
}

// "path[i]"
inline std::string Index(std::string_view path, int64_t i) {
  std::string s(path);
  s += '[';
  s += std::to_string(i);
  s += ']';
  return s;
}

// "path.name" (just "name" at the root).
inline std::string Member(std::string_view path, std::string_view name) {
  std::string s(path);
  if (!s.empty()) s += '.';
  s += name;
  return s;
}

inline std::string Quoted(std::string_view s) {
  std::string q = "\"";
  q += s;
  q += '"';
  return q;
}

}  // namespace probebake::job_internal
