// Helpers shared by the engine export and viewer tests: plausible synthetic volumes, running the
// CLI and node, JSON read back through protobuf's JSON mapping.
#pragma once

#include <string>
#include <vector>

#include "google/protobuf/struct.pb.h"
#include "probebake/bake/probe_volume.h"
#include "probebake/math/vec3.h"

namespace probebake::testing {

// A 3 x 4 x 5 grid (tests/volume/test_volumes.h's structure: some probes inactive, some invalid)
// whose radiance is that of a plausible sky: a constant ambient plus a Henyey-Greenstein lobe
// (g = 0.6) of random direction and colour per probe, projected to L2 exactly (positive radiance,
// irradiance dominated by the ambient term, so relative comparisons of E are well conditioned).
ProbeVolume PlausibleVolume(uint64_t seed);

// Runs `command` through the shell; returns its exit status (-1 if it could not run) and puts
// stdout into *out when out is non-null (stderr goes to the test's stderr).
int RunCommand(const std::string& command, std::string* out = nullptr);

// Whether `program` is on PATH.
bool HaveProgram(const std::string& program);

// The whole file; fails the test (and returns "") when it cannot be read.
std::string ReadFileText(const std::string& path);

// Parses JSON into a Struct; fails the test on a parse error.
google::protobuf::Struct ParseJson(const std::string& text);

// A JSON list of numbers [a, b, c] as a Vec3d; fails the test on another shape.
Vec3d ToVec3(const google::protobuf::Value& value);

}  // namespace probebake::testing
