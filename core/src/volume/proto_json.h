// JSON for the volume module through protobuf's own JSON mapping (google::protobuf::util) on the
// well-known google.protobuf.Value / Struct / ListValue: writing the stats metadata and the
// inspect report, parsing stats back, and telling whether a metadata string is JSON. Private to
// the module.
//
// Numbers are doubles (google.protobuf.Value has no integer kind): integers print exactly as
// long as their magnitude is below 2^53. Protobuf prints a finite double with %.15g, or %.17g
// when %.15g does not read back as the same double: integral values below 10^15 print as integer
// literals ("1124", "1099511627776"), others as e.g. "0.1", "12.345678901234567", "1e-07",
// "1e+15" (exact, in exponent form from 10^15 on).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <google/protobuf/message.h>
#include <google/protobuf/struct.pb.h>

namespace probebake::volume_internal {

// Magnitude from which an integer is not always exactly representable as a double: 2^53.
inline constexpr double kMaxExactJsonInteger = 9007199254740992.0;

// `message` as compact JSON (no whitespace) with every object's keys in ascending byte order, so
// the same value always gives the same text (protobuf's MessageToJsonString alone prints a
// Struct's keys in the order of its hash map, which varies from run to run).
std::string ToJson(const google::protobuf::Message& message);

// Parses `text` as one JSON value; nullopt when it is not JSON. Protobuf's parser also accepts
// single-quoted strings and a trailing comma; what ToJson prints of the result is always JSON.
// Pass ValidUtf8 text: strings in the result keep the bytes they were given.
std::optional<google::protobuf::Value> ParseJson(const std::string& text);

// A number, or null for NaN and infinities (JSON has no such numbers).
google::protobuf::Value NumberValue(double x);
// A number when |n| < 2^53 (exact as a double), else its decimal digits as a string, as
// protobuf's JSON mapping does for 64-bit integers.
google::protobuf::Value IntegerValue(int64_t n);
// `s` with every byte that is not part of a well-formed UTF-8 sequence replaced by U+FFFD
// (protobuf's string fields must be UTF-8: it would drop such bytes with an error log).
std::string ValidUtf8(std::string_view s);
// A string, made ValidUtf8.
google::protobuf::Value StringValue(std::string_view s);

// `value` as an int64 when it is an integral number of magnitude below 2^53, else nullopt.
std::optional<int64_t> ExactInteger(const google::protobuf::Value& value);

}  // namespace probebake::volume_internal
