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

// s with control characters as \xNN: a NUL or a newline in a name or path must not cut or break
// the message it is shown in. Other bytes, UTF-8 included, are kept.
inline std::string Escaped(std::string_view s) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c == 0x7f) {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    } else {
      out += ch;
    }
  }
  return out;
}

// "s", escaped as above.
inline std::string Quoted(std::string_view s) {
  std::string q = "\"";
  q += Escaped(s);
  q += '"';
  return q;
}

}  // namespace probebake::job_internal
