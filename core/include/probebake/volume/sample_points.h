// The input and output of `probebake sample VOLUME --points FILE` (README, "Sampling a volume").
//
// Input: a JSON array of objects {"position": [x, y, z], "normal": [x, y, z]}, scene
// coordinates; the normal need not be unit length but must be finite and non-zero. No other keys.
// Output: per point one JSON object on a line, {"position": [...], "normal": [...] (as given),
// "irradiance": [r, g, b], "radianceSh": [[r, g, b] x (L+1)^2], "probes": n}
// (ProbeSampler, probe_sampler.h; SH in the volume's basis, docs/spherical-harmonics.md).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "probebake/base/status.h"
#include "probebake/math/vec3.h"
#include "probebake/volume/probe_sampler.h"

namespace probebake {

struct SamplePoint {
  Vec3d position;
  Vec3d normal;
};

// INVALID_ARGUMENT naming the field ("points[3].normal: ...") on bad input.
absl::StatusOr<std::vector<SamplePoint>> ParseSamplePoints(std::string_view json);

// One line of output (no newline).
std::string SampleJson(const SamplePoint& point, const ProbeSample& sample);

}  // namespace probebake
