// Job states and sizes shared by the server and the client.
#pragma once

#include <cstdint>

#include "probebake/v1/service.pb.h"

namespace probebake::server {

// SUCCEEDED, FAILED and CANCELLED: the job will not change any more.
inline bool IsFinal(v1::BakeJob::State state) {
  return state == v1::BakeJob::SUCCEEDED || state == v1::BakeJob::FAILED ||
         state == v1::BakeJob::CANCELLED;
}

// Bytes of ServerCapabilities.max_message_bytes a CreateBakeJob's job leaves for the rest of its
// FULL view (name, state, times, progress, result, error): the server refuses larger jobs, and
// the CLI checks before uploading.
inline constexpr int64_t kJobRecordReserve = 65536;

}  // namespace probebake::server
