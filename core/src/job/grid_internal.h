// Grid arithmetic shared by validation (probe-count limits) and ResolveGrid, so both agree on the
// counts a spacing gives (private to core/src/job).
#pragma once

#include <google/protobuf/struct.pb.h>

#include <cmath>

#include "probebake/v1/job.pb.h"

namespace probebake::job_internal {

// Whether the job gives a spacing (null counts as absent, as in proto3 JSON).
inline bool HasSpacing(const v1::Grid& grid) {
  return grid.has_spacing() && grid.spacing().kind_case() != google::protobuf::Value::kNullValue &&
         grid.spacing().kind_case() != google::protobuf::Value::KIND_NOT_SET;
}

// Probes on an axis of length `extent` >= 0 with probes `spacing` > 0 apart, as a double so that
// absurd grids can be compared with the limits before anything is cast: floor(extent / spacing +
// 1e-9) + 1. The 1e-9 keeps an extent that is a whole number of spacings up to rounding (8 / 0.1)
// from losing its last probe.
inline double ProbesOnAxis(double extent, double spacing) {
  return std::floor(extent / spacing + 1e-9) + 1;
}

}  // namespace probebake::job_internal
