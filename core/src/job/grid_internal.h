// Grid arithmetic shared by validation (probe-count limits) and ResolveGrid, so both agree on the
// counts a spacing gives (private to core/src/job).
#pragma once

#include <google/protobuf/struct.pb.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "probebake/v1/job.pb.h"

namespace probebake::job_internal {

// Whether the job gives a spacing (null counts as absent, as in proto3 JSON).
inline bool HasSpacing(const v1::Grid& grid) {
  return grid.has_spacing() && grid.spacing().kind_case() != google::protobuf::Value::kNullValue &&
         grid.spacing().kind_case() != google::protobuf::Value::KIND_NOT_SET;
}

// Probes on the axis from lo to hi >= lo with probes `spacing` > 0 apart, as a double so that
// absurd grids can be compared with the limits before anything is cast: floor(q + tol) + 1 with
// q = (hi - lo) / spacing. The tolerance keeps an extent that is a whole number of spacings up to
// rounding from losing its last probe. lo and hi carry up to half an ulp each of their decimal
// value, which (hi - lo) / spacing scales to eps |coordinate| / spacing: 0.22 / 0.01 from
// 200000.14 is 21.999999997. The quotient's own rounding adds eps q; tol is 8x the sum, at least
// 1e-9 (8 / 0.1 at the origin). A probe it adds lies past hi by no more than that rounding.
inline double ProbesOnAxis(double lo, double hi, double spacing) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  const double q = (hi - lo) / spacing;
  const double rounding = kEps * (std::max(std::abs(lo), std::abs(hi)) / spacing + q);
  return std::floor(q + std::max(1e-9, 8 * rounding)) + 1;
}

}  // namespace probebake::job_internal
