// stb_image behind a small interface (private to core/src/job): the only translation unit that
// compiles stb_image, and it compiles it static. Libraries this one links (assimp's draco) export
// their own copies of stb_image's stbi_* symbols, so a call to a shared stbi_* function could run
// another version's decoder; static functions are ours alone. libstb is not linked.
//
// Decodes from memory only (STBI_NO_STDIO): PNG, JPEG, TGA, BMP (8 bits per channel; 16-bit PNG
// is reduced to 8) and Radiance .hdr (32-bit float). Thread safe (stb's failure reason is thread
// local).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace probebake::job_internal {

struct StbImageInfo {
  int width = 0, height = 0;
  int channels = 0;       // in the file: 1 grey, 2 grey + alpha, 3 RGB, 4 RGBA
  bool radiance = false;  // a Radiance .hdr file (float), else 8 bits per channel
};

// The header of `bytes`: false, with stb's reason in `error`, when no enabled format reads it.
// Reads no pixels (check the size before decoding).
bool StbImageHeader(std::string_view bytes, StbImageInfo* info, std::string* error);

// Radiance .hdr pixels as linear float RGB, row 0 the image's top; false with `error` on failure.
bool StbDecodeRadiance(std::string_view bytes, std::vector<float>* rgb, std::string* error);

// 8-bit pixels as RGBA (grey copied to R, G and B; alpha 255 when the file has none), row 0 the
// image's top, the file's values unchanged (no colour-space conversion); false with `error` on
// failure, and for Radiance files.
bool StbDecodeRgba8(std::string_view bytes, std::vector<uint8_t>* rgba, std::string* error);

}  // namespace probebake::job_internal
