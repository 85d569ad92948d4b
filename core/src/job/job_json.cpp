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

// ---- Locating a syntax error ----
// protobuf's JSON parser says what is wrong but not where (it quotes a few characters around the
// error). This scanner finds the byte offset of the first syntax error so the message can give a
// line and column. It only checks the grammar; protobuf's parser remains the authority.
class SyntaxScanner {
 public:
  explicit SyntaxScanner(std::string_view text) : s_(text) {}

  // Offset of the first syntax error, or npos when the text is well-formed JSON.
  size_t FirstError() {
    SkipSpace();
    if (!ScanValue(0)) return i_;
    SkipSpace();
    return i_ == s_.size() ? std::string_view::npos : i_;
  }

 private:
  static constexpr int kMaxDepth = 512;

  void SkipSpace() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\n' || s_[i_] == '\r'))
      ++i_;
  }
  bool Literal(std::string_view word) {
    if (s_.substr(i_, word.size()) != word) return false;
    i_ += word.size();
    return true;
  }
  bool ScanString() {
    ++i_;  // opening quote
    while (i_ < s_.size()) {
      const unsigned char c = s_[i_];
      if (c == '"') {
        ++i_;
        return true;
      }
      if (c < 0x20) return false;
      if (c == '\\') {
        if (++i_ >= s_.size()) return false;
        if (s_[i_] == 'u') {
          for (int k = 0; k < 4; ++k)
            if (++i_ >= s_.size() || !std::isxdigit(static_cast<unsigned char>(s_[i_])))
              return false;
        } else if (!std::strchr("\"\\/bfnrt", s_[i_])) {
          return false;
        }
      }
      ++i_;
    }
    return false;
  }
  bool Digits() {
    const size_t start = i_;
    while (i_ < s_.size() && s_[i_] >= '0' && s_[i_] <= '9') ++i_;
    return i_ > start;
  }
  bool ScanNumber() {
    if (s_[i_] == '-') ++i_;
    if (!Digits()) return false;
    if (i_ < s_.size() && s_[i_] == '.') {
      ++i_;
      if (!Digits()) return false;
    }
    if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
      ++i_;
      if (i_ < s_.size() && (s_[i_] == '+' || s_[i_] == '-')) ++i_;
      if (!Digits()) return false;
    }
    return true;
  }
  bool ScanValue(int depth) {
    if (i_ >= s_.size() || depth > kMaxDepth) return false;
    switch (s_[i_]) {
      case '{': {
        ++i_;
        SkipSpace();
        if (i_ < s_.size() && s_[i_] == '}') return ++i_, true;
        while (true) {
          SkipSpace();
          if (i_ >= s_.size() || s_[i_] != '"' || !ScanString()) return false;
          SkipSpace();
          if (i_ >= s_.size() || s_[i_] != ':') return false;
          ++i_;
          SkipSpace();
          if (!ScanValue(depth + 1)) return false;
          SkipSpace();
          if (i_ < s_.size() && s_[i_] == ',') {
            ++i_;
            continue;
          }
          if (i_ < s_.size() && s_[i_] == '}') return ++i_, true;
          return false;
        }
      }
      case '[': {
        ++i_;
        SkipSpace();
        if (i_ < s_.size() && s_[i_] == ']') return ++i_, true;
        while (true) {
          SkipSpace();
          if (!ScanValue(depth + 1)) return false;
          SkipSpace();
          if (i_ < s_.size() && s_[i_] == ',') {
            ++i_;
            continue;
          }
          if (i_ < s_.size() && s_[i_] == ']') return ++i_, true;
          return false;
        }
      }
      case '"':
        return ScanString();
      case 't':
        return Literal("true");
      case 'f':
        return Literal("false");
      case 'n':
        return Literal("null");
      default:
        return ScanNumber();
    }
  }

  std::string_view s_;
  size_t i_ = 0;
};

std::string InvalidJsonMessage(std::string_view text, std::string_view protobufMessage) {
  // protobuf's first line is the reason; the rest quotes the text around the error.
  std::string reason(protobufMessage.substr(0, protobufMessage.find('\n')));
  const size_t offset = SyntaxScanner(text).FirstError();
  if (offset == std::string_view::npos) return "invalid JSON: " + reason;
  size_t line = 1, column = 1;
  for (size_t k = 0; k < offset && k < text.size(); ++k) {
    if (text[k] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return "invalid JSON at line " + Num(line) + ", column " + Num(column) + ": " + reason;
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
