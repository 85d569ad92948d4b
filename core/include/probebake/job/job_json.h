// Reading job files (docs/job-format.md): the proto3 JSON form of probebake.v1.JobSpec.
//
// The text is first parsed as plain JSON and walked alongside the JobSpec descriptor, so every
// unknown field, wrong type, bad enum name and non-finite number is reported with its JSON path
// (lowerCamelCase names, array indices), e.g.
//   scene.lights[2].rect.edgeOne: unknown field (did you mean "edge1"?)
//   grid.counts[1]: expected an integer, got 2.5
//   settings.window: unknown value "HANN" (expected one of NONE, HANNING, LANCZOS, AUTO)
//   scene.materials[0].albedo[2]: "NaN" is not allowed (numbers must be finite)
// Only then is it handed to protobuf's JSON parser (ignore_unknown_fields = false).
//
// Accepted beyond plain lowerCamelCase JSON, as proto3 JSON does: the .proto field names
// (snake_case), numbers written as strings ("1.5"), 64-bit integers as strings (the form
// MessageToJsonString writes), enum values by number when the number is defined, and null for an
// absent field. Stricter than protobuf: a repeated field must be a JSON array, a bool a JSON
// boolean, and an enum number must name a defined value.
//
// Errors are INVALID_ARGUMENT; when several fields are wrong the message holds one
// "<field path>: <reason>" line per error (at most 50), in document order of the descriptor walk
// (keys sorted within an object). Text protobuf's JSON parser rejects gives one line, with the
// field path and the line and column when they can be found (JSON paths here are the keys as
// written):
//   scene.materials[1].albedo[1]: 1e999 is not a finite number (beyond the range of a double),
//     at line 5, column 41
//   grid.min[0]: NaN is not a finite number (numbers must be finite), at line 2, column 20
//   grid.min: invalid JSON at line 2, column 22: Expected , or ] after array value.
// (the first two on one line each); a bare NaN, Infinity or -Infinity, and any numeral beyond the
// range of a double, are reported as non-finite numbers.
//
// Parsing does not validate values (ranges, lengths, references): see ValidateJobSpec
// (probebake/job/validate.h).
#pragma once

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "probebake/v1/job.pb.h"

namespace probebake {

// Parses a job from its JSON text (UTF-8; a leading byte-order mark is skipped).
absl::StatusOr<v1::JobSpec> ParseJobJson(std::string_view json);

// Reads and parses the job file at `path`. Every error line starts with "<path>: ", so a message
// names the file and the field: "jobs/room.json: settings.shOrder: expected an integer, got 2.5".
// An unreadable file is INVALID_ARGUMENT too ("<path>: cannot read: No such file or directory").
absl::StatusOr<v1::JobSpec> ReadJobFile(const std::string& path);

}  // namespace probebake
