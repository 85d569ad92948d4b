#include "runtime/shard_progress.h"

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace probebake::runtime {
namespace {

using google::protobuf::Struct;
using google::protobuf::Value;

// `text` as a JSON string literal (host names and stages: printable ASCII in practice).
std::string Quote(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\')
      absl::StrAppend(&out, "\\", std::string(1, c));
    else if (static_cast<unsigned char>(c) < 0x20)
      absl::StrAppendFormat(&out, "\\u%04x", int(c));
    else
      out += c;
  }
  return out + "\"";
}

absl::Status Missing(const char* key, const char* type) {
  return absl::InvalidArgumentError(
      absl::StrCat("shard progress: ", key, ": missing or not a ", type));
}

absl::StatusOr<double> Number(const Struct& s, const char* key) {
  auto it = s.fields().find(key);
  if (it == s.fields().end() || it->second.kind_case() != Value::kNumberValue)
    return Missing(key, "number");
  return it->second.number_value();
}

absl::StatusOr<std::string> Text(const Struct& s, const char* key) {
  auto it = s.fields().find(key);
  if (it == s.fields().end() || it->second.kind_case() != Value::kStringValue)
    return Missing(key, "string");
  return it->second.string_value();
}

}  // namespace

std::string ShardProgressJson(const ShardProgress& p) {
  return absl::StrFormat(
      "{\"shard\":%d,\"shards\":%d,\"host\":%s,\"pid\":%d,\"stage\":%s,\"probesDone\":%d,"
      "\"probesTotal\":%d,\"samples\":%d,\"rays\":%d,\"elapsedSeconds\":%.3f}\n",
      p.shard, p.shards, Quote(p.host), p.pid, Quote(p.stage), p.probesDone, p.probesTotal,
      p.samples, p.rays, p.elapsedSeconds);
}

absl::StatusOr<ShardProgress> ParseShardProgress(const std::string& json) {
  Struct s;
  if (!google::protobuf::util::JsonStringToMessage(json, &s).ok())
    return absl::InvalidArgumentError("shard progress: not a JSON object");
  ShardProgress p;
  // Counts travel as JSON numbers (doubles): exact below 2^53, far beyond any real count.
  auto count = [&](const char* key, int64_t* to) -> absl::Status {
    absl::StatusOr<double> v = Number(s, key);
    if (!v.ok()) return v.status();
    *to = int64_t(*v);
    return absl::OkStatus();
  };
  int64_t shard = 0, shards = 0;
  for (auto [key, to] : {std::pair{"shard", &shard},
                         {"shards", &shards},
                         {"pid", &p.pid},
                         {"probesDone", &p.probesDone},
                         {"probesTotal", &p.probesTotal},
                         {"samples", &p.samples},
                         {"rays", &p.rays}}) {
    if (absl::Status got = count(key, to); !got.ok()) return got;
  }
  p.shard = int(shard);
  p.shards = int(shards);
  absl::StatusOr<double> elapsed = Number(s, "elapsedSeconds");
  if (!elapsed.ok()) return elapsed.status();
  p.elapsedSeconds = *elapsed;
  absl::StatusOr<std::string> host = Text(s, "host"), stage = Text(s, "stage");
  if (!host.ok()) return host.status();
  if (!stage.ok()) return stage.status();
  p.host = *host;
  p.stage = *stage;
  return p;
}

}  // namespace probebake::runtime
