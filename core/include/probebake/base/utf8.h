// Well-formed UTF-8 (Unicode 15, Table 3-7): what protobuf requires of every string field, so
// text from files and metadata is checked against the same rule before it reaches a message.
#pragma once

#include <cstddef>
#include <string_view>

namespace probebake {

// Length in bytes (1 to 4) of the well-formed UTF-8 sequence at the start of `s`; 0 when `s` is
// empty or does not start with one (a stray continuation byte, an overlong form, a surrogate, a
// code point above U+10FFFF, or a sequence cut short).
size_t Utf8SequenceLength(std::string_view s);

// Length of the longest prefix of `s` that is well-formed UTF-8.
size_t ValidUtf8PrefixLength(std::string_view s);

}  // namespace probebake
