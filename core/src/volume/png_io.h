// 8-bit RGB PNG output through libpng. Private to the volume module.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "probebake/base/status.h"

namespace probebake::volume_internal {

// Writes a width x height 8-bit RGB image (rows top to bottom, 3 bytes per pixel) to `path`,
// atomically (probebake/base/atomic_file.h). Errors name the path.
absl::Status WritePngRgb8(const std::string& path, int width, int height,
                          const std::vector<uint8_t>& rgb);

}  // namespace probebake::volume_internal
