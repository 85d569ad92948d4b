// Just enough JSON for the volume module: writing numbers and strings, parsing the stats object
// back, and checking that a metadata string is JSON before embedding it. Private to the module.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace probebake::volume_internal {

struct JsonValue {
  enum class Kind { kNull, kBool, kNumber, kString, kArray, kObject };
  Kind kind = Kind::kNull;
  bool boolean = false;
  std::string text;              // kNumber: the literal as written; kString: the decoded string
  std::vector<JsonValue> items;  // kArray
  std::vector<std::pair<std::string, JsonValue>> members;  // kObject, in order

  // The member named `key` of an object, or null.
  const JsonValue* Find(std::string_view key) const;
};

// Parses one JSON value (RFC 8259) filling the whole of `text` (surrounding whitespace allowed).
// nullopt when it is not valid JSON.
std::optional<JsonValue> ParseJson(std::string_view text);

// `value` as an int64 when it is an integer literal in range, else nullopt.
std::optional<int64_t> JsonInt64(const JsonValue& value);
// `value` as a double (exactly rounded) when it is a number, else nullopt.
std::optional<double> JsonDouble(const JsonValue& value);

// A JSON string literal (with quotes) for `s`.
std::string JsonQuote(std::string_view s);
// The shortest decimal that reads back as exactly `x`; "null" for NaN and infinities, which JSON
// cannot express.
std::string JsonNumber(double x);

}  // namespace probebake::volume_internal
