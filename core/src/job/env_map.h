// Environment images: OpenEXR and Radiance .hdr files decoded to 32-bit float RGB (private to
// core/src/job).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "probebake/scene/scene.h"

namespace probebake::job_internal {

struct EnvironmentImage {
  // width, height, data window origin (0 for .hdr) and rgb; the rest is left to the caller.
  EnvironmentMap pixels;
  // An OpenEXR file whose `envmap` attribute says cube-face layout.
  bool cubeTagged = false;
};

// Decodes `bytes` as 32-bit float RGB, telling the format from the contents: OpenEXR (channels R,
// G, B; or Y alone, copied to all three; over its data window) or Radiance RGBE (.hdr, via
// stb_image; linear values, as the format stores). INVALID_ARGUMENT "<fieldPath>: ..." when the
// file is neither, cannot be read, has neither RGB nor Y, has subsampled channels, has more than
// `maxPixels` pixels (0: no limit), or holds a negative or non-finite value. `name` is the file's
// name for messages.
absl::StatusOr<EnvironmentImage> DecodeEnvironmentImage(std::string_view bytes,
                                                        const std::string& name,
                                                        const std::string& fieldPath,
                                                        int64_t maxPixels);

}  // namespace probebake::job_internal
