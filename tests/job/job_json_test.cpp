// ParseJobJson / ReadJobFile: proto3 JSON with every error named by its JSON path.
#include "probebake/job/job_json.h"

#include <gtest/gtest.h>

#include <chrono>

#include <cmath>

#include "job/test_util.h"

namespace probebake {
namespace {

using testing::DataDir;
using testing::HasFieldError;
using testing::Patched;
using testing::ReadText;

std::string Example() {
  return ReadText(DataDir() + "/example.json");
}

TEST(ParseJobJson, ExampleParses) {
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(Example());
  ASSERT_TRUE(job.ok()) << job.status();
  ASSERT_EQ(job->scene().materials_size(), 2);
  EXPECT_EQ(job->scene().materials(1).name(), "lamp");
  ASSERT_EQ(job->scene().lights_size(), 6);
  EXPECT_EQ(job->scene().lights(1).spot().outer_angle_deg(), 30);
  EXPECT_EQ(job->scene().lights(2).directional().angular_diameter_deg(), 0.53);
  EXPECT_EQ(job->grid().placement(), v1::Grid::OUTSIDE_GEOMETRY);
  ASSERT_EQ(job->grid().counts_size(), 3);
  EXPECT_EQ(job->grid().counts(2), 4);
  EXPECT_EQ(job->settings().samples_per_probe(), 1024);
  EXPECT_TRUE(job->settings().has_target_rel_error());
  EXPECT_TRUE(job->settings().irradiance());
  EXPECT_EQ(job->settings().window(), v1::BakeSettings::NONE);
}

TEST(ParseJobJson, DeepNestingIsRefusedBeforeParsing) {
  // protobuf's JSON parser slows quadratically with depth: 20000 levels in `spacing` (a
  // google.protobuf.Value) took 29 s to be refused. Brackets inside strings do not count.
  auto spacing = [](int levels) {
    return R"({"grid": {"min": [0, 0, 0], "max": [1, 1, 1], "spacing": )" +
           std::string(size_t(levels), '[') + std::string(size_t(levels), ']') + "}}";
  };
  const auto start = std::chrono::steady_clock::now();
  const absl::Status deep = ParseJobJson(spacing(200000)).status();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_EQ(deep.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(deep.message(), "invalid JSON: arrays and objects nest deeper than 32 levels");
  // The job's own two levels plus 30: at the limit, parsed (and refused for what it says).
  EXPECT_EQ(ParseJobJson(spacing(30)).status().message().find("nest deeper"), std::string::npos);
  EXPECT_NE(ParseJobJson(spacing(31)).status().message().find("nest deeper"), std::string::npos);
  const std::string quoted =
      R"({"scene": {"materials": [{"name": ")" + std::string(100, '[') +
      R"(\""}]}, "grid": {"min": [0, 0, 0], "max": [1, 1, 1], "counts": [1, 1, 1]}})";
  EXPECT_TRUE(ParseJobJson(quoted).ok()) << ParseJobJson(quoted).status();
}

TEST(ParseJobJson, UnknownFieldsAtEveryDepth) {
  const std::string base = Example();
  EXPECT_TRUE(
      HasFieldError(ParseJobJson(Patched(base, "extra", "1")).status(), "extra", "unknown field"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "scene.fog", "{}")).status(), "scene.fog",
                            "unknown field"));
  EXPECT_TRUE(
      HasFieldError(ParseJobJson(Patched(base, "scene.materials[1].albedoo", "[0, 0, 0]")).status(),
                    "scene.materials[1].albedoo", "did you mean \"albedo\""));
  EXPECT_TRUE(HasFieldError(
      ParseJobJson(Patched(base, "scene.lights[3].rect.edgeOne", "[1, 0, 0]")).status(),
      "scene.lights[3].rect.edgeOne", "unknown field"));
  EXPECT_TRUE(
      HasFieldError(ParseJobJson(Patched(base, "scene.environment.uniform.scale", "2")).status(),
                    "scene.environment.uniform.scale", "unknown field"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "settings.shorder", "2")).status(),
                            "settings.shorder", "did you mean \"shOrder\""));
}

TEST(ParseJobJson, ReportsEveryErrorOneLineEach) {
  std::string json = Patched(Example(), "grid.bogus", "1");
  json = Patched(json, "scene.lights[0].point.position[1]", "\"NaN\"");
  json = Patched(json, "settings.window", "\"HANN\"");
  const absl::Status s = ParseJobJson(json).status();
  EXPECT_TRUE(HasFieldError(s, "grid.bogus", "unknown field"));
  EXPECT_TRUE(HasFieldError(s, "scene.lights[0].point.position[1]", "\"NaN\" is not allowed"));
  EXPECT_TRUE(HasFieldError(s, "settings.window", "unknown value \"HANN\""));
  EXPECT_EQ(std::count(s.message().begin(), s.message().end(), '\n'), 2) << s.message();
}

TEST(ParseJobJson, NonFiniteStringsAreRejectedWithThePath) {
  const std::string base = Example();
  EXPECT_TRUE(HasFieldError(
      ParseJobJson(Patched(base, "scene.lights[0].point.position[1]", "\"NaN\"")).status(),
      "scene.lights[0].point.position[1]", "\"NaN\" is not allowed"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "scene.medium.g", "\"Infinity\"")).status(),
                            "scene.medium.g", "\"Infinity\" is not allowed"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "grid.min[0]", "\"-Infinity\"")).status(),
                            "grid.min[0]", "\"-Infinity\" is not allowed"));
  EXPECT_TRUE(HasFieldError(
      ParseJobJson(Patched(base, "scene.materials[0].albedo[2]", "\"1e999\"")).status(),
      "scene.materials[0].albedo[2]", "out of the range of a double"));
}

TEST(ParseJobJson, WrongTypesNameTheField) {
  const std::string base = Example();
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "settings.shOrder", "2.5")).status(),
                            "settings.shOrder", "expected an integer, got 2.5"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "settings.shOrder", "\"two\"")).status(),
                            "settings.shOrder", "expected an integer"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "grid.counts[1]", "-3e10")).status(),
                            "grid.counts[1]", "out of range"));
  EXPECT_TRUE(
      HasFieldError(ParseJobJson(Patched(base, "scene.meshes[1].indices[0]", "-1")).status(),
                    "scene.meshes[1].indices[0]", "out of range"));
  EXPECT_TRUE(
      HasFieldError(ParseJobJson(Patched(base, "scene.lights[4].disk.radius", "\"big\"")).status(),
                    "scene.lights[4].disk.radius", "expected a number, got the string \"big\""));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "scene.meshes[0].name", "3")).status(),
                            "scene.meshes[0].name", "expected a string"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "settings.irradiance", "\"yes\"")).status(),
                            "settings.irradiance", "expected true or false"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "grid.min", "0")).status(), "grid.min",
                            "expected an array"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "scene.medium", "[1]")).status(),
                            "scene.medium", "expected an object"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "grid.max[2]", "null")).status(),
                            "grid.max[2]", "null is not allowed"));
}

TEST(ParseJobJson, IntegerEdges) {
  const std::string base = Example();
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "settings.seed", "\"-1\"")).status(),
                            "settings.seed", "-1 is out of range [0, 18446744073709551615]"));
  // 2^64 is a double equal to (double)UINT64_MAX, so only protobuf's exact parse catches it; its
  // message is still given with the JSON path.
  const std::string json = std::string(R"({"grid": {"min": [0, 0, 0], "max": [0, 0, 0],
      "counts": [1, 1, 1]}, "settings": {"seed": 18446744073709551616}})");
  EXPECT_TRUE(HasFieldError(ParseJobJson(json).status(), "settings.seed", "invalid value"));
  const absl::StatusOr<v1::JobSpec> exact = ParseJobJson(Patched(base, "settings.maxDepth", "4.0"));
  ASSERT_TRUE(exact.ok()) << exact.status();
  EXPECT_EQ(exact->settings().max_depth(), 4);
}

TEST(ParseJobJson, BadEnumNames) {
  const std::string base = Example();
  EXPECT_TRUE(HasFieldError(
      ParseJobJson(Patched(base, "grid.placement", "\"EVERYWHERE\"")).status(), "grid.placement",
      "unknown value \"EVERYWHERE\" (expected one of ALL, OUTSIDE_GEOMETRY, "
      "NEAR_SURFACES)"));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "settings.window", "\"none\"")).status(),
                            "settings.window", "unknown value \"none\""));
  EXPECT_TRUE(HasFieldError(ParseJobJson(Patched(base, "settings.window", "9")).status(),
                            "settings.window", "unknown value 9"));
  // A defined number is proto3 JSON.
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(Patched(base, "settings.window", "2"));
  ASSERT_TRUE(job.ok()) << job.status();
  EXPECT_EQ(job->settings().window(), v1::BakeSettings::HANNING);
}

TEST(ParseJobJson, TwoKindsOfOneLight) {
  const std::string json =
      Patched(Example(), "scene.lights[0].sphere", R"({"center": [0, 0, 1], "radius": 1})");
  EXPECT_TRUE(HasFieldError(ParseJobJson(json).status(), "scene.lights[0].sphere",
                            "only one of point, spot, directional, rect, disk, sphere"));
}

TEST(ParseJobJson, SameFieldUnderBothNames) {
  const std::string json = Patched(Example(), "settings.sh_order", "3");
  EXPECT_TRUE(HasFieldError(ParseJobJson(json).status(), "settings.shOrder", "given twice") ||
              HasFieldError(ParseJobJson(json).status(), "settings.sh_order", "given twice"));
}

TEST(ParseJobJson, ProtoJsonFormsAreAccepted) {
  std::string json = Patched(Example(), "settings.samplesPerProbe", "\"4096\"");  // int64 string
  json = Patched(json, "settings.seed", "\"18446744073709551615\"");
  json = Patched(json, "settings", R"({"sh_order": 3, "seed": "18446744073709551615",
                                        "targetRelError": "0.25", "window": "NONE"})");
  json = Patched(json, "scene.medium", "null");
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  ASSERT_TRUE(job.ok()) << job.status();
  EXPECT_EQ(job->settings().sh_order(), 3);
  EXPECT_EQ(job->settings().seed(), 18446744073709551615ull);
  EXPECT_EQ(job->settings().target_rel_error(), 0.25);
  EXPECT_FALSE(job->scene().has_medium());
}

TEST(ParseJobJson, ByteOrderMarkIsSkipped) {
  EXPECT_TRUE(ParseJobJson("\xEF\xBB\xBF" + Example()).ok());
}

TEST(ParseJobJson, SyntaxErrorsGiveLineAndColumn) {
  const absl::Status s = ParseJobJson("{\n  \"grid\": {\"min\": [1 2]}\n}").status();
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(s.message()).find("invalid JSON at line 2, column 22: "), std::string::npos)
      << s.message();
  EXPECT_EQ(std::string(s.message()).find('\n'), std::string::npos) << s.message();
  const absl::Status empty = ParseJobJson("").status();
  EXPECT_EQ(empty.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(empty.message()).find("invalid JSON"), std::string::npos);
  // NaN as a bare literal is not JSON.
  EXPECT_EQ(ParseJobJson(R"({"grid": {"min": [NaN, 0, 0]}})").status().code(),
            absl::StatusCode::kInvalidArgument);
}

// Text protobuf's JSON parser rejects: a numeral beyond the range of a double, or a bare NaN or
// Infinity, is named by its field path, with its line and column.
TEST(ParseJobJson, NonFiniteNumeralsAndLiteralsNameTheFieldAndLine) {
  auto parse = [](const std::string& value) {
    return ParseJobJson(
               "{\n"
               "  \"scene\": {\n"
               "    \"materials\": [\n"
               "      {\"name\": \"white\", \"albedo\": [0.8, 0.8, 0.8]},\n"
               "      {\"name\": \"lamp\", \"albedo\": [0.5, " +
               value +
               ", 0.5]}\n"
               "    ]\n"
               "  }\n"
               "}\n")
        .status();
  };
  const std::string path = "scene.materials[1].albedo[1]";
  const std::string at = ", at line 5, column 40";
  for (const std::string value : {"1e999", "-1e999", "1.5E+400"}) {
    const absl::Status s = parse(value);
    EXPECT_TRUE(HasFieldError(
        s, path, value + " is not a finite number (beyond the range of a double)" + at))
        << value;
    EXPECT_EQ(std::string(s.message()).find('\n'), std::string::npos) << s.message();
  }
  for (const std::string value : {"NaN", "Infinity", "-Infinity", "nan", "-inf"}) {
    EXPECT_TRUE(HasFieldError(parse(value), path,
                              value + " is not a finite number (numbers must be finite)" + at))
        << value;
  }
  // A 400-digit integer overflows a double too; "1e-999" (underflow to 0) is a finite number.
  EXPECT_TRUE(HasFieldError(
      ParseJobJson("{\"grid\": {\"counts\": [1, " + std::string(400, '9') + "]}}").status(),
      "grid.counts[1]", "is not a finite number"));
  std::string underflow = Example();
  const size_t g = underflow.find("\"g\": 0.3");
  ASSERT_NE(g, std::string::npos);
  underflow.replace(g, 8, "\"g\": 1e-999");
  EXPECT_TRUE(ParseJobJson(underflow).ok());
  // At the root, in an object value, and after protobuf's leniencies (bare keys, single quotes,
  // trailing commas), which the locator follows so it stops where protobuf stopped.
  EXPECT_TRUE(HasFieldError(ParseJobJson("NaN").status(), "job", "NaN is not a finite number"));
  EXPECT_TRUE(HasFieldError(ParseJobJson("{\"scene\": {\"medium\": {\"g\": -Infinity}}}").status(),
                            "scene.medium.g", "-Infinity is not a finite number"));
  EXPECT_TRUE(HasFieldError(
      ParseJobJson("{grid: {'min': [1, 2, 3,], max: [1e999, 0, 0]}}").status(), "grid.max[0]",
      "1e999 is not a finite number (beyond the range of a double), at line 1, column 34"));
  // A file: the file, then the field.
  testing::TempDir dir;
  const std::string file = dir.Write("nan.json", "{\"grid\": {\"min\": [0, NaN, 0]}}");
  EXPECT_TRUE(HasFieldError(ReadJobFile(file).status(), file + ": grid.min[1]",
                            "NaN is not a finite number (numbers must be finite), at line 1, "
                            "column 22"));
}

TEST(ParseJobJson, SyntaxErrorsNameTheEnclosingField) {
  EXPECT_TRUE(HasFieldError(ParseJobJson("{\n  \"grid\": {\"min\": [1 2]}\n}").status(), "grid.min",
                            "invalid JSON at line 2, column 22: "));
  EXPECT_TRUE(HasFieldError(ParseJobJson("{\"grid\": {\"min\": [1, 2, 3] \"max\": 1}}").status(),
                            "grid", "invalid JSON at line 1, column 28: "));
  EXPECT_TRUE(HasFieldError(ParseJobJson("{\"grid\": {\"min\" [1]}}").status(), "grid.min",
                            "invalid JSON at line 1, column 17: "));
  EXPECT_TRUE(HasFieldError(ParseJobJson("{\"grid\": {\"min\": [1, tru]}}").status(), "grid.min[1]",
                            "invalid JSON at line 1, column 22: "));
  // Bytes that are not UTF-8: where protobuf stopped reading.
  const absl::Status latin1 =
      ParseJobJson("{\"scene\": {\"materials\": [{\"name\": \"caf\xE9\"}]}}").status();
  EXPECT_TRUE(HasFieldError(latin1, "scene.materials[0].name", "invalid JSON at line 1, column 39"))
      << latin1;
  // Columns count characters, not bytes (the é is two bytes).
  EXPECT_TRUE(HasFieldError(
      ParseJobJson("{\"scene\": {\"materials\": [{\"name\": \"caf\xC3\xA9\", \"albedo\": [NaN]}]}}")
          .status(),
      "scene.materials[0].albedo[0]", "at line 1, column 54"));
  // A syntax error before such bytes is reported as such.
  EXPECT_TRUE(HasFieldError(
      ParseJobJson("{\"grid\": {\"min\": [1 2]}, \"scene\": {\"x\": \"caf\xE9\"}}").status(),
      "grid.min", "invalid JSON at line 1, column 21: "));
}

TEST(ParseJobJson, TopLevelMustBeAnObject) {
  EXPECT_TRUE(HasFieldError(ParseJobJson("[1, 2]").status(), "job", "expected an object"));
}

TEST(ReadJobFile, MessagesNameTheFile) {
  testing::TempDir dir;
  const std::string missing = dir.File("missing.json");
  const absl::Status s = ReadJobFile(missing).status();
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(s.message()).find(missing + ": cannot read"), std::string::npos) << s;

  const std::string bad = dir.Write("bad.json", Patched(Example(), "settings.shOrder", "2.5"));
  EXPECT_TRUE(
      HasFieldError(ReadJobFile(bad).status(), bad + ": settings.shOrder", "expected an integer"));

  EXPECT_TRUE(HasFieldError(ReadJobFile(dir.path()).status(), dir.path(), "not a regular file"));
  EXPECT_TRUE(ReadJobFile(DataDir() + "/example.json").ok());
}

}  // namespace
}  // namespace probebake
