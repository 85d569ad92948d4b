#include "probebake/job/job_json.h"

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <system_error>
#include <type_traits>
#include <vector>

#include "errors.h"
#include "json_nesting.h"
#include "probebake/base/utf8.h"
#include "text.h"

namespace probebake {
namespace {

using google::protobuf::Descriptor;
using google::protobuf::EnumDescriptor;
using google::protobuf::FieldDescriptor;
using google::protobuf::OneofDescriptor;
using google::protobuf::Value;
using job_internal::ErrorList;
using job_internal::Index;
using job_internal::Member;
using job_internal::Num;
using job_internal::Quoted;

// ---- Locating what protobuf's JSON parser rejected ----
// protobuf's JSON parser says what is wrong but neither in which field nor at which line (it
// quotes a few characters around the error), and some of what it rejects is a number, not syntax:
// a literal beyond the range of a double (1e999) or a bare NaN or Infinity. This scanner runs only
// once protobuf has rejected the text. It follows the grammar protobuf 3.21's parser accepts
// (single-quoted strings, bare keys, trailing commas, numbers such as "1." and "-.5", any escape),
// so it stops where protobuf stopped, and it keeps the JSON path of the value it is in. protobuf
// remains the authority on what is valid; this only says where.
struct JsonFault {
  enum class Kind { kNotFound, kSyntax, kNonFinite };
  Kind kind = Kind::kNotFound;
  size_t offset = 0;  // byte offset of the offending token or character
  // The value being read (or the object or array whose punctuation is wrong); empty at the root.
  std::string path;
  std::string token;      // kNonFinite: the number or word as written
  bool overflow = false;  // kNonFinite: a numeral beyond the range of a double (not NaN etc.)
};

class FaultLocator {
 public:
  explicit FaultLocator(std::string_view text) : s_(text) {}

  JsonFault Find() {
    // protobuf parses the well-formed UTF-8 prefix only: its error is at the end of it, if not
    // before.
    const size_t size = s_.size();
    s_ = s_.substr(0, ValidUtf8PrefixLength(s_));
    SkipSpace();
    if (Value("", 0)) {
      SkipSpace();
      if (i_ != s_.size() || s_.size() < size) Syntax("");
    }
    // Running out of a cut-off prefix (in a string or array left open there) is the cut.
    if (fault_.kind == JsonFault::Kind::kSyntax && ranOut_ && s_.size() < size)
      fault_.offset = s_.size();
    return fault_;
  }

 private:
  // Deeper than protobuf's own limit (100 nested objects): past it, give up rather than recurse.
  static constexpr int kMaxDepth = 512;

  static bool IsSpace(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r';
  }
  static bool IsLetter(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == '$';
  }
  static bool IsAlphanumeric(char c) { return IsLetter(c) || (c >= '0' && c <= '9'); }
  // The words other JSON writers use for non-finite doubles (JavaScript's, Python's, C's).
  static bool IsNonFiniteWord(std::string_view word) {
    if (!word.empty() && (word[0] == '-' || word[0] == '+')) word.remove_prefix(1);
    std::string lower(word);
    for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    return lower == "nan" || lower == "inf" || lower == "infinity";
  }

  bool SyntaxAt(const std::string& path, size_t offset) {
    fault_ = {JsonFault::Kind::kSyntax, offset, path, "", false};
    ranOut_ = i_ >= s_.size();
    return false;
  }
  bool Syntax(const std::string& path) { return SyntaxAt(path, i_); }
  bool NonFinite(const std::string& path, size_t start, size_t end, bool overflow) {
    fault_ = {JsonFault::Kind::kNonFinite, start, path, std::string(s_.substr(start, end - start)),
              overflow};
    return false;
  }
  bool GiveUp() {
    fault_ = {};
    return false;
  }

  void SkipSpace() {
    while (i_ < s_.size() && IsSpace(s_[i_])) ++i_;
  }
  bool StartsWith(std::string_view word) const { return s_.substr(i_, word.size()) == word; }
  size_t WordEnd(size_t from) const {
    size_t end = from;
    while (end < s_.size() && IsAlphanumeric(s_[end])) ++end;
    return end;
  }

  // At a quote: past the closing one (either quote character, any escape, as protobuf reads).
  bool String() {
    const char quote = s_[i_++];
    while (i_ < s_.size()) {
      if (s_[i_] == '\\') {
        if (i_ + 1 >= s_.size()) return false;
        if (s_[i_ + 1] == 'u') {
          for (size_t k = 2; k < 6; ++k)
            if (i_ + k >= s_.size() || !std::isxdigit(static_cast<unsigned char>(s_[i_ + k])))
              return false;
          i_ += 6;
        } else {
          i_ += 2;
        }
        continue;
      }
      if (s_[i_++] == quote) return true;
    }
    return false;
  }

  // At '-' or a digit. protobuf takes the run of characters that may be part of a number and
  // converts it whole; a run that converts to an infinity is out of the range of a double.
  bool Number(const std::string& path) {
    const size_t start = i_;
    if (s_[i_] == '-' && i_ + 1 < s_.size() && IsLetter(s_[i_ + 1])) {
      const size_t end = WordEnd(i_ + 1);
      if (IsNonFiniteWord(s_.substr(start, end - start))) return NonFinite(path, start, end, false);
      return Syntax(path);
    }
    size_t end = i_;
    bool floating = false;
    for (; end < s_.size(); ++end) {
      const char c = s_[end];
      if (c >= '0' && c <= '9') continue;
      if (c == '.' || c == 'e' || c == 'E') {
        floating = true;
        continue;
      }
      if (c == '+' || c == '-' || c == 'x') continue;
      break;
    }
    const std::string number(s_.substr(start, end - start));
    const bool negative = number[0] == '-';
    if (!floating && number.size() >= (negative ? 3u : 2u) && number[negative ? 1 : 0] == '0')
      return Syntax(path);  // octal or hex
    char* parsedEnd = nullptr;
    const double x = std::strtod(number.c_str(), &parsedEnd);
    if (parsedEnd != number.c_str() + number.size()) return Syntax(path);
    if (!std::isfinite(x)) return NonFinite(path, start, end, true);
    i_ = end;
    return true;
  }

  bool Value(const std::string& path, int depth) {
    if (depth > kMaxDepth) return GiveUp();
    if (i_ >= s_.size()) return Syntax(path);
    const char c = s_[i_];
    if (c == '{') return Object(path, depth + 1);
    if (c == '[') return Array(path, depth + 1);
    if (c == '"' || c == '\'') {
      const size_t start = i_;
      if (String()) return true;
      return SyntaxAt(path, start);  // at the opening quote
    }
    if (c == '-' || (c >= '0' && c <= '9')) return Number(path);
    for (std::string_view keyword : {"true", "false", "null"}) {
      if (StartsWith(keyword)) {
        i_ += keyword.size();
        return true;
      }
    }
    const size_t end = WordEnd(i_);
    if (end > i_ && IsNonFiniteWord(s_.substr(i_, end - i_)))
      return NonFinite(path, i_, end, false);
    return Syntax(path);
  }

  bool Object(const std::string& path, int depth) {
    ++i_;  // '{'
    while (true) {
      SkipSpace();
      if (i_ >= s_.size()) return Syntax(path);
      if (s_[i_] == '}') {  // also after a trailing comma, as protobuf allows
        ++i_;
        return true;
      }
      const size_t start = i_;
      std::string key;
      if (s_[i_] == '"' || s_[i_] == '\'') {
        if (!String()) return SyntaxAt(path, start);
        key = s_.substr(start + 1, i_ - start - 2);
      } else if (IsLetter(s_[i_])) {
        i_ = WordEnd(i_);
        key = s_.substr(start, i_ - start);
      } else {
        return Syntax(path);
      }
      const std::string member = Member(path, key);
      SkipSpace();
      if (i_ >= s_.size() || s_[i_] != ':') return Syntax(member);
      ++i_;
      SkipSpace();
      if (!Value(member, depth)) return false;
      SkipSpace();
      if (i_ < s_.size() && s_[i_] == ',') {
        ++i_;
        continue;
      }
      if (i_ < s_.size() && s_[i_] == '}') {
        ++i_;
        return true;
      }
      return Syntax(path);
    }
  }

  bool Array(const std::string& path, int depth) {
    ++i_;  // '['
    for (int64_t index = 0;; ++index) {
      SkipSpace();
      if (i_ >= s_.size()) return Syntax(path);
      if (s_[i_] == ']') {  // also after a trailing comma, as protobuf allows
        ++i_;
        return true;
      }
      if (!Value(Index(path, index), depth)) return false;
      SkipSpace();
      if (i_ < s_.size() && s_[i_] == ',') {
        ++i_;
        continue;
      }
      if (i_ < s_.size() && s_[i_] == ']') {
        ++i_;
        return true;
      }
      return Syntax(path);
    }
  }

  std::string_view s_;
  size_t i_ = 0;
  JsonFault fault_;
  bool ranOut_ = false;  // the syntax fault is the end of the text (of its UTF-8 prefix)
};

// "line L, column C" of byte `offset`; columns count characters (UTF-8 sequences), from 1.
std::string LineAndColumn(std::string_view text, size_t offset) {
  size_t line = 1, column = 1;
  for (size_t k = 0; k < offset && k < text.size(); ++k) {
    if (text[k] == '\n') {
      ++line;
      column = 1;
    } else if ((static_cast<unsigned char>(text[k]) & 0xC0) != 0x80) {
      ++column;
    }
  }
  return "line " + Num(line) + ", column " + Num(column);
}

// The message for text protobuf's JSON parser rejected with `protobufMessage`: the field path and
// the line and column when the scanner finds them.
std::string InvalidJsonMessage(std::string_view text, std::string_view protobufMessage) {
  // protobuf's first line is the reason; the rest quotes the text around the error.
  const std::string reason(protobufMessage.substr(0, protobufMessage.find('\n')));
  const JsonFault fault = FaultLocator(text).Find();
  const std::string where = LineAndColumn(text, fault.offset);
  switch (fault.kind) {
    case JsonFault::Kind::kNonFinite:
      return (fault.path.empty() ? std::string("job") : fault.path) + ": " + fault.token +
             " is not a finite number (" +
             (fault.overflow ? "beyond the range of a double" : "numbers must be finite") +
             "), at " + where;
    case JsonFault::Kind::kSyntax:
      return (fault.path.empty() ? "" : fault.path + ": ") + "invalid JSON at " + where + ": " +
             reason;
    case JsonFault::Kind::kNotFound:
      break;
  }
  return "invalid JSON: " + reason;
}

// ---- The typed walk ----

std::string KindName(const Value& v) {
  switch (v.kind_case()) {
    case Value::kNullValue:
      return "null";
    case Value::kNumberValue:
      return "a number";
    case Value::kStringValue:
      return "a string";
    case Value::kBoolValue:
      return "a boolean";
    case Value::kStructValue:
      return "an object";
    case Value::kListValue:
      return "an array";
    case Value::KIND_NOT_SET:
      break;
  }
  return "nothing";
}

std::string Describe(const Value& v) {
  if (v.kind_case() == Value::kNumberValue) return Num(v.number_value());
  if (v.kind_case() == Value::kStringValue) return "the string " + Quoted(v.string_value());
  return KindName(v);
}

size_t EditDistance(std::string_view a, std::string_view b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      const bool same = std::tolower(static_cast<unsigned char>(a[i - 1])) ==
                        std::tolower(static_cast<unsigned char>(b[j - 1]));
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (same ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

std::string UnknownFieldReason(const Descriptor* type, std::string_view key) {
  std::string best;
  size_t bestDistance = std::max<size_t>(2, key.size() / 3) + 1;
  std::string names;
  for (int i = 0; i < type->field_count(); ++i) {
    const std::string& name = type->field(i)->json_name();
    names += (i ? ", " : "") + name;
    const size_t d = EditDistance(key, name);
    if (d < bestDistance) {
      bestDistance = d;
      best = name;
    }
  }
  if (!best.empty()) return "unknown field (did you mean " + Quoted(best) + "?)";
  return "unknown field (expected one of " + names + ")";
}

std::string EnumNames(const EnumDescriptor* type) {
  std::string names;
  for (int i = 0; i < type->value_count(); ++i) {
    const std::string& name = type->value(i)->name();
    if (name.size() >= 12 && name.ends_with("_UNSPECIFIED")) continue;
    if (!names.empty()) names += ", ";
    names += name;
  }
  return names;
}

// The field named `key` in JSON (lowerCamelCase) or in the .proto (snake_case), as protobuf's
// JSON parser accepts both.
const FieldDescriptor* FindField(const Descriptor* type, const std::string& key) {
  for (int i = 0; i < type->field_count(); ++i) {
    const FieldDescriptor* field = type->field(i);
    if (field->json_name() == key || field->name() == key) return field;
  }
  return nullptr;
}

class JsonChecker {
 public:
  explicit JsonChecker(ErrorList* errors) : errors_(errors) {}

  void Message(const Value& value, const Descriptor* type, const std::string& path) {
    const std::string& typeName = type->full_name();
    if (typeName == "google.protobuf.Value") return;  // any JSON value (checked by the validator)
    if (value.kind_case() != Value::kStructValue) {
      errors_->Add(path.empty() ? "job" : path, "expected an object, got " + KindName(value));
      return;
    }
    const auto& fields = value.struct_value().fields();
    std::vector<std::string> keys;
    keys.reserve(fields.size());
    for (const auto& [key, unused] : fields) keys.push_back(key);
    std::sort(keys.begin(), keys.end());

    std::map<const OneofDescriptor*, std::string> oneofSeen;
    std::map<const FieldDescriptor*, std::string> fieldSeen;
    for (const std::string& key : keys) {
      const Value& child = fields.at(key);
      const std::string childPath = Member(path, key);
      const FieldDescriptor* field = FindField(type, key);
      if (field == nullptr) {
        errors_->Add(childPath, UnknownFieldReason(type, key));
        continue;
      }
      if (const auto [it, inserted] = fieldSeen.emplace(field, key); !inserted) {
        errors_->Add(childPath, "given twice (also as " + Quoted(it->second) + ")");
        continue;
      }
      if (child.kind_case() == Value::kNullValue) continue;  // null: the field is absent
      if (const OneofDescriptor* oneof = field->real_containing_oneof()) {
        const auto [it, inserted] = oneofSeen.emplace(oneof, key);
        if (!inserted) {
          std::string names;
          for (int i = 0; i < oneof->field_count(); ++i)
            names += (i ? ", " : "") + oneof->field(i)->json_name();
          errors_->Add(childPath, "only one of " + names + " may be set (" + Quoted(it->second) +
                                      " is set too)");
          continue;
        }
      }
      if (field->is_repeated()) {
        if (child.kind_case() != Value::kListValue) {
          errors_->Add(childPath, "expected an array, got " + KindName(child));
          continue;
        }
        const auto& items = child.list_value().values();
        for (int i = 0; i < items.size(); ++i) {
          if (items[i].kind_case() == Value::kNullValue) {
            errors_->Add(Index(childPath, i), "null is not allowed in an array");
            continue;
          }
          Single(items[i], field, Index(childPath, i));
        }
      } else {
        Single(child, field, childPath);
      }
    }
  }

 private:
  void Single(const Value& v, const FieldDescriptor* field, const std::string& path) {
    switch (field->cpp_type()) {
      case FieldDescriptor::CPPTYPE_MESSAGE:
        Message(v, field->message_type(), path);
        return;
      case FieldDescriptor::CPPTYPE_DOUBLE:
      case FieldDescriptor::CPPTYPE_FLOAT:
        Real(v, path);
        return;
      case FieldDescriptor::CPPTYPE_INT32:
        Integer<int32_t>(v, path);
        return;
      case FieldDescriptor::CPPTYPE_INT64:
        Integer<int64_t>(v, path);
        return;
      case FieldDescriptor::CPPTYPE_UINT32:
        Integer<uint32_t>(v, path);
        return;
      case FieldDescriptor::CPPTYPE_UINT64:
        Integer<uint64_t>(v, path);
        return;
      case FieldDescriptor::CPPTYPE_BOOL:
        if (v.kind_case() != Value::kBoolValue)
          errors_->Add(path, "expected true or false, got " + Describe(v));
        return;
      case FieldDescriptor::CPPTYPE_STRING:
        if (v.kind_case() != Value::kStringValue)
          errors_->Add(path, "expected a string, got " + Describe(v));
        return;
      case FieldDescriptor::CPPTYPE_ENUM:
        Enum(v, field->enum_type(), path);
        return;
    }
  }

  void Real(const Value& v, const std::string& path) {
    if (v.kind_case() == Value::kNumberValue) return;  // always finite: JSON has no NaN literal
    if (v.kind_case() != Value::kStringValue) {
      errors_->Add(path, "expected a number, got " + Describe(v));
      return;
    }
    const std::string& s = v.string_value();
    if (s == "NaN" || s == "Infinity" || s == "-Infinity") {
      errors_->Add(path, Quoted(s) + " is not allowed (numbers must be finite)");
      return;
    }
    double x = 0;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), x);
    if (r.ptr != s.data() + s.size() ||
        (r.ec != std::errc() && r.ec != std::errc::result_out_of_range)) {
      errors_->Add(path, "expected a number, got " + Describe(v));
    } else if (r.ec == std::errc::result_out_of_range &&
               !std::isfinite(std::strtod(s.c_str(), nullptr))) {
      // from_chars leaves x alone when out of range; strtod tells overflow from underflow.
      errors_->Add(path, Quoted(s) + " is out of the range of a double (numbers must be finite)");
    } else if (!std::isfinite(x)) {
      errors_->Add(path, Quoted(s) + " is not allowed (numbers must be finite)");
    }
  }

  template <typename T>
  void Integer(const Value& v, const std::string& path) {
    constexpr double kLo = double(std::numeric_limits<T>::min());
    // The largest 64-bit values are not doubles; 2^63 and 2^64 pass here and protobuf's own
    // parser, which reads the text exactly, has the last word.
    constexpr double kHi = double(std::numeric_limits<T>::max());
    const std::string range =
        "[" + Num(std::numeric_limits<T>::min()) + ", " + Num(std::numeric_limits<T>::max()) + "]";
    if (v.kind_case() == Value::kNumberValue) {
      const double x = v.number_value();
      if (std::floor(x) != x) {
        errors_->Add(path, "expected an integer, got " + Num(x));
      } else if (x < kLo || x > kHi) {
        errors_->Add(path, Num(x) + " is out of range " + range);
      }
      return;
    }
    if (v.kind_case() == Value::kStringValue) {
      T x{};
      const std::string& s = v.string_value();
      const auto r = std::from_chars(s.data(), s.data() + s.size(), x);
      const bool negativeUnsigned =
          std::is_unsigned_v<T> && s.size() > 1 && s[0] == '-' &&
          std::all_of(s.begin() + 1, s.end(), [](char c) { return c >= '0' && c <= '9'; });
      if (negativeUnsigned ||
          (r.ec == std::errc::result_out_of_range && r.ptr == s.data() + s.size())) {
        errors_->Add(path, s + " is out of range " + range);
      } else if (r.ec != std::errc() || r.ptr != s.data() + s.size()) {
        errors_->Add(path, "expected an integer, got " + Describe(v));
      }
      return;
    }
    errors_->Add(path, "expected an integer, got " + Describe(v));
  }

  void Enum(const Value& v, const EnumDescriptor* type, const std::string& path) {
    if (v.kind_case() == Value::kStringValue) {
      if (type->FindValueByName(v.string_value()) == nullptr) {
        errors_->Add(path, "unknown value " + Quoted(v.string_value()) + " (expected one of " +
                               EnumNames(type) + ")");
      }
      return;
    }
    if (v.kind_case() == Value::kNumberValue) {
      const double x = v.number_value();
      if (std::floor(x) != x || std::abs(x) > 1e9 || type->FindValueByNumber(int(x)) == nullptr) {
        errors_->Add(path,
                     "unknown value " + Num(x) + " (expected one of " + EnumNames(type) + ")");
      }
      return;
    }
    errors_->Add(path, "expected one of " + EnumNames(type) + ", got " + Describe(v));
  }

  ErrorList* errors_;
};

// protobuf's "(settings.sh_order): invalid value ..." as "settings.shOrder: invalid value ...".
std::string ProtobufErrorMessage(const std::string& message) {
  const size_t close = message.find("): ");
  if (message.empty() || message[0] != '(' || close == std::string::npos) {
    return "invalid job: " + message;
  }
  std::string path;
  bool upper = false;
  for (size_t i = 1; i < close; ++i) {
    if (message[i] == '_') {
      upper = true;
    } else {
      path += upper ? char(std::toupper(static_cast<unsigned char>(message[i]))) : message[i];
      upper = false;
    }
  }
  return path + message.substr(close + 1);
}

google::protobuf::StringPiece Piece(std::string_view s) {
  return google::protobuf::StringPiece(s.data(), s.size());
}

}  // namespace

absl::StatusOr<v1::JobSpec> ParseJobJson(std::string_view json) {
  if (json.starts_with("\xEF\xBB\xBF")) json.remove_prefix(3);
  // A job nests 5 levels deep; protobuf's parser slows quadratically with depth.
  constexpr int kMaxNesting = 32;
  if (job_internal::JsonNestsDeeperThan(json, kMaxNesting)) {
    return absl::InvalidArgumentError("invalid JSON: arrays and objects nest deeper than " +
                                      std::to_string(kMaxNesting) + " levels");
  }
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;

  Value root;
  const auto syntax = google::protobuf::util::JsonStringToMessage(Piece(json), &root, options);
  if (!syntax.ok()) {
    return absl::InvalidArgumentError(InvalidJsonMessage(json, std::string(syntax.message())));
  }
  ErrorList errors;
  JsonChecker(&errors).Message(root, v1::JobSpec::descriptor(), "");
  if (!errors.ok()) return errors.ToStatus();

  v1::JobSpec job;
  const auto parsed = google::protobuf::util::JsonStringToMessage(Piece(json), &job, options);
  if (!parsed.ok()) {
    // Rare after the walk above (e.g. a uint64 of exactly 2^64, which a double cannot tell from
    // 2^64 - 1); protobuf's message names the field by its .proto path.
    return absl::InvalidArgumentError(ProtobufErrorMessage(std::string(parsed.message())));
  }
  return job;
}

absl::StatusOr<v1::JobSpec> ReadJobFile(const std::string& path) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (ec) return absl::InvalidArgumentError(path + ": cannot read: " + ec.message());
  if (!std::filesystem::is_regular_file(status)) {
    return absl::InvalidArgumentError(path + ": cannot read: not a regular file");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return absl::InvalidArgumentError(path + ": cannot read: " + std::strerror(errno));
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return absl::InvalidArgumentError(path + ": cannot read: read error");
  absl::StatusOr<v1::JobSpec> job = ParseJobJson(text.str());
  if (!job.ok()) return job_internal::PrefixLines(job.status(), path);
  return job;
}

}  // namespace probebake
