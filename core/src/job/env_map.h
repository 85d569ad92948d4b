// OpenEXR lat-long environment maps (private to core/src/job).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "probebake/scene/scene.h"

namespace probebake::job_internal {

// Decodes the OpenEXR file `bytes` as 32-bit float RGB (channels R, G, B; or Y alone, copied to
// all three) over its data window; width, height, data window origin and rgb are filled, the rest
// of EnvironmentMap is left to the caller. INVALID_ARGUMENT "<fieldPath>: ..." when the file cannot
// be read, has neither RGB nor Y, has subsampled channels, has more than `maxPixels` pixels
// (0: no limit), or holds a negative or non-finite value. `name` is the file's name for messages.
absl::StatusOr<EnvironmentMap> DecodeEnvironmentMap(std::string_view bytes, const std::string& name,
                                                    const std::string& fieldPath,
                                                    int64_t maxPixels);

}  // namespace probebake::job_internal
