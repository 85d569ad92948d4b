// Job states shared by the server and the client.
#pragma once

#include "probebake/v1/service.pb.h"

namespace probebake::server {

// SUCCEEDED, FAILED and CANCELLED: the job will not change any more.
inline bool IsFinal(v1::BakeJob::State state) {
  return state == v1::BakeJob::SUCCEEDED || state == v1::BakeJob::FAILED ||
         state == v1::BakeJob::CANCELLED;
}

}  // namespace probebake::server
