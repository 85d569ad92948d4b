#include "proto_json.h"

#include <cmath>
#include <memory>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/type_resolver.h>
#include <google/protobuf/util/type_resolver_util.h>

#include "probebake/base/check.h"
#include "probebake/base/utf8.h"

namespace probebake::volume_internal {

namespace pb = google::protobuf;

namespace {

constexpr const char* kTypeUrlPrefix = "type.googleapis.com";

// Resolves the generated well-known types; thread safe, lives for the process.
pb::util::TypeResolver* GeneratedTypeResolver() {
  static pb::util::TypeResolver* const resolver = pb::util::NewTypeResolverForDescriptorPool(
      kTypeUrlPrefix, pb::DescriptorPool::generated_pool());
  return resolver;
}

}  // namespace

std::string ToJson(const pb::Message& message) {
  // Deterministic serialization writes map entries (a Struct's fields) sorted by key, and the
  // binary-to-JSON converter keeps the order it reads.
  std::string binary;
  {
    pb::io::StringOutputStream stream(&binary);
    pb::io::CodedOutputStream coded(&stream);
    coded.SetSerializationDeterministic(true);
    PB_CHECK(message.SerializeToCodedStream(&coded));
  }
  std::string json;
  const auto status = pb::util::BinaryToJsonString(
      GeneratedTypeResolver(),
      std::string(kTypeUrlPrefix) + "/" + message.GetDescriptor()->full_name(), binary, &json);
  // Only a bug can make this fail: every message here is a well-known type with valid UTF-8.
  if (!status.ok()) {
    detail::CheckFailed(__FILE__, __LINE__, "protobuf JSON printing failed: " + status.ToString());
  }
  return json;
}

std::optional<pb::Value> ParseJson(const std::string& text) {
  pb::Value value;
  if (!pb::util::JsonStringToMessage(text, &value).ok()) return std::nullopt;
  // An empty or all-blank text parses as a Value without a kind; it is not JSON.
  if (value.kind_case() == pb::Value::KIND_NOT_SET) return std::nullopt;
  return value;
}

pb::Value NumberValue(double x) {
  pb::Value value;
  if (std::isfinite(x)) {
    value.set_number_value(x);
  } else {
    value.set_null_value(pb::NULL_VALUE);
  }
  return value;
}

pb::Value IntegerValue(int64_t n) {
  pb::Value value;
  if (std::abs(double(n)) < kMaxExactJsonInteger) {
    value.set_number_value(double(n));
  } else {
    value.set_string_value(std::to_string(n));
  }
  return value;
}

std::string ValidUtf8(std::string_view s) {
  std::string valid;
  valid.reserve(s.size());
  while (!s.empty()) {
    const size_t n = Utf8SequenceLength(s);
    if (n == 0) {
      valid += "\xEF\xBF\xBD";  // U+FFFD REPLACEMENT CHARACTER
      s.remove_prefix(1);
    } else {
      valid.append(s.substr(0, n));
      s.remove_prefix(n);
    }
  }
  return valid;
}

pb::Value StringValue(std::string_view s) {
  pb::Value value;
  value.set_string_value(ValidUtf8(s));
  return value;
}

std::optional<int64_t> ExactInteger(const pb::Value& value) {
  if (value.kind_case() != pb::Value::kNumberValue) return std::nullopt;
  const double x = value.number_value();
  if (!(std::abs(x) < kMaxExactJsonInteger) || std::trunc(x) != x) return std::nullopt;
  return int64_t(x);
}

}  // namespace probebake::volume_internal
