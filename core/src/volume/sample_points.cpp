#include "probebake/volume/sample_points.h"

#include <cmath>

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace probebake {
namespace {

using google::protobuf::ListValue;
using google::protobuf::Value;

absl::Status PointError(size_t i, const std::string& field, const std::string& reason) {
  return absl::InvalidArgumentError(
      absl::StrCat("points[", i, "]", field.empty() ? "" : ".", field, ": ", reason));
}

// A [x, y, z] of finite numbers.
absl::Status ReadVec3(const Value& v, size_t i, const std::string& field, Vec3d* out) {
  if (v.kind_case() != Value::kListValue || v.list_value().values_size() != 3)
    return PointError(i, field, "must be an array of 3 numbers");
  for (int a = 0; a < 3; ++a) {
    const Value& x = v.list_value().values(a);
    if (x.kind_case() != Value::kNumberValue || !std::isfinite(x.number_value()))
      return PointError(i, field, "must be an array of 3 finite numbers");
    (*out)[a] = x.number_value();
  }
  return absl::OkStatus();
}

// "%.9g": a float's value exactly, a double's to 9 digits.
std::string Triple(const Vec3d& v) {
  return absl::StrFormat("[%.9g, %.9g, %.9g]", v.x, v.y, v.z);
}

}  // namespace

absl::StatusOr<std::vector<SamplePoint>> ParseSamplePoints(std::string_view json) {
  ListValue list;
  google::protobuf::util::JsonParseOptions options;
  const auto parsed = google::protobuf::util::JsonStringToMessage(
      google::protobuf::StringPiece(json.data(), json.size()), &list, options);
  if (!parsed.ok())
    return absl::InvalidArgumentError(
        absl::StrCat("points: not a JSON array of objects (", std::string(parsed.message()), ")"));
  std::vector<SamplePoint> points;
  points.reserve(size_t(list.values_size()));
  for (int k = 0; k < list.values_size(); ++k) {
    const size_t i = size_t(k);
    const Value& v = list.values(k);
    if (v.kind_case() != Value::kStructValue)
      return PointError(i, "",
                        "must be an object {\"position\": [x, y, z], \"normal\": [x, y, z]}");
    const auto& fields = v.struct_value().fields();
    for (const auto& [key, value] : fields) {
      (void)value;
      if (key != "position" && key != "normal") return PointError(i, key, "unknown field");
    }
    SamplePoint p;
    for (const char* name : {"position", "normal"}) {
      auto it = fields.find(name);
      if (it == fields.end()) return PointError(i, name, "missing");
      PB_RETURN_IF_ERROR(ReadVec3(it->second, i, name, name[0] == 'p' ? &p.position : &p.normal));
    }
    const double len2 = LengthSquared(p.normal);
    if (!(len2 > 0) || !std::isfinite(len2)) return PointError(i, "normal", "must be non-zero");
    points.push_back(p);
  }
  return points;
}

std::string SampleJson(const SamplePoint& point, const ProbeSample& sample) {
  std::string sh;
  for (size_t i = 0; i < sample.radianceSh.size(); ++i)
    absl::StrAppend(&sh, i ? ", " : "", Triple(sample.radianceSh[i]));
  return absl::StrCat("{\"position\": ", Triple(point.position),
                      ", \"normal\": ", Triple(point.normal),
                      ", \"irradiance\": ", Triple(sample.irradiance), ", \"radianceSh\": [", sh,
                      "], \"probes\": ", sample.probes, "}");
}

}  // namespace probebake
