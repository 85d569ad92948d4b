// The progress file of a shard of a sharded bake (docs/cluster.md): `probebake bake --shard I/N
// --progress-file F` rewrites F (atomically, about once a second) with where the shard is, and
// probebake-server's cluster backend reads it to report the job's progress. One JSON object:
//   {"shard":2,"shards":4,"host":"node17","pid":1234,"stage":"baking","probesDone":10,
//    "probesTotal":288,"samples":10240,"rays":51234,"elapsedSeconds":3.5}
// stage: "planning" (the work pre-pass), "baking", "writing" (the part's volume file), "done".
#pragma once

#include <cstdint>
#include <string>

#include "absl/status/statusor.h"

namespace probebake::runtime {

struct ShardProgress {
  int shard = 0, shards = 1;
  std::string host;
  int64_t pid = 0;
  std::string stage = "planning";
  int64_t probesDone = 0;
  int64_t probesTotal = 0;  // 0 until the placement has run
  int64_t samples = 0;
  int64_t rays = 0;
  double elapsedSeconds = 0;
};

std::string ShardProgressJson(const ShardProgress& progress);
// INVALID_ARGUMENT when `json` is not such an object (a field missing or of the wrong type).
absl::StatusOr<ShardProgress> ParseShardProgress(const std::string& json);

}  // namespace probebake::runtime
