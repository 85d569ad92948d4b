// How deeply a JSON text nests, found by a scan (private to core/src/job).
//
// JSON parsers recurse per level: 200000 nested arrays crashed assimp's glTF parser, and
// protobuf's JSON parser slows quadratically with depth (20000 levels of a job file's `spacing`,
// a google.protobuf.Value, took 29 s to be refused). Real job files and glTF files nest a few
// levels deep, so both are refused past a limit before any parser sees them.
#pragma once

#include <string_view>

namespace probebake::job_internal {

// True when `json` opens more than `levels` arrays or objects inside each other. Brackets inside
// strings (with their escapes) do not count; the text need not be valid JSON. O(size).
bool JsonNestsDeeperThan(std::string_view json, int levels);

}  // namespace probebake::job_internal
