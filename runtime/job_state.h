// Job states and sizes the server and the CLI agree on.
//
// The state is the wire enum v1::BakeJob::State itself (service.pb.h, generated message code from
// probebake_proto: libprotobuf, no gRPC): a C++ mirror of it would be a second list to keep in
// step with service.proto.
#pragma once

#include <cstdint>

#include "probebake/v1/service.pb.h"

namespace probebake::runtime {

// SUCCEEDED, FAILED and CANCELLED: the job will not change any more.
inline bool IsFinal(v1::BakeJob::State state) {
  return state == v1::BakeJob::SUCCEEDED || state == v1::BakeJob::FAILED ||
         state == v1::BakeJob::CANCELLED;
}

// Bytes of ServerCapabilities.max_message_bytes a CreateBakeJob's job leaves for the rest of its
// FULL view (name, state, times, progress, result, error): the server refuses larger jobs, and
// the CLI checks before uploading.
inline constexpr int64_t kJobRecordReserve = 65536;

}  // namespace probebake::runtime
