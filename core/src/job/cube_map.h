// Cube-map environments (private to core/src/job). A cube map is held in OpenEXR's cube-face
// layout (Imf::CubeMap: one image N wide and 6N high, faces +X, -X, +Y, -Y, +Z, -Z from the top)
// and resampled into OpenEXR's lat-long layout, which the tracer importance-samples like any
// lat-long map (core/src/bake/environment_light.h).
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "absl/status/statusor.h"
#include "probebake/scene/scene.h"

namespace probebake::job_internal {

// Stacks six N x N face images (+X, -X, +Y, -Y, +Z, -Z, each oriented as that face of the
// cube-face layout) into one N x 6N image. INVALID_ARGUMENT "<fieldPaths[i]>: ..." when face i is
// not square or not the size of face 0.
absl::StatusOr<EnvironmentMap> StackCubeFaces(const std::array<EnvironmentMap, 6>& faces,
                                              const std::array<std::string, 6>& fieldPaths);

// The lat-long map (4N + 1 x 2N + 1 pixels, data window at the origin) of the N x 6N cube-face
// image `cube`: each pixel is the mean of the cube over kCubeSupersampling^2 directions spread
// evenly, in longitude and in sin(latitude), over the pixel's cell of the sphere (so equal solid
// angles), each read from the nearest cube pixel. A constant cube gives that constant exactly.
// INVALID_ARGUMENT "<fieldPath>: ..." when `cube` is not N x 6N or the lat-long map would hold
// more than `maxPixels` pixels (0: no limit). Deterministic; runs in parallel over rows.
inline constexpr int kCubeSupersampling = 4;
absl::StatusOr<EnvironmentMap> LatLongFromCube(const EnvironmentMap& cube,
                                               const std::string& fieldPath, int64_t maxPixels);

}  // namespace probebake::job_internal
