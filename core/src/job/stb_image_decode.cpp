#include "stb_image_decode.h"

#include <climits>
#include <memory>

// Warnings of stb_image's own code, which we do not edit.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wimplicit-fallthrough"
#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#define STBI_NO_STDIO
#define STBI_ONLY_PNG
#define STBI_ONLY_JPEG
#define STBI_ONLY_TGA
#define STBI_ONLY_BMP
#define STBI_ONLY_HDR
#include "stb_image.h"
#pragma GCC diagnostic pop

namespace probebake::job_internal {
namespace {

const stbi_uc* Data(std::string_view bytes) {
  return reinterpret_cast<const stbi_uc*>(bytes.data());
}

bool TooLarge(std::string_view bytes, std::string* error) {
  if (bytes.size() <= size_t(INT_MAX)) return false;
  *error = "the file is too large";
  return true;
}

std::string Reason() {
  const char* reason = stbi_failure_reason();
  return reason != nullptr ? reason : "unknown error";
}

}  // namespace

bool StbImageHeader(std::string_view bytes, StbImageInfo* info, std::string* error) {
  if (TooLarge(bytes, error)) return false;
  if (!stbi_info_from_memory(Data(bytes), int(bytes.size()), &info->width, &info->height,
                             &info->channels)) {
    *error = Reason();
    return false;
  }
  info->radiance = stbi_is_hdr_from_memory(Data(bytes), int(bytes.size())) != 0;
  return true;
}

bool StbDecodeRadiance(std::string_view bytes, std::vector<float>* rgb, std::string* error) {
  if (TooLarge(bytes, error)) return false;
  if (!stbi_is_hdr_from_memory(Data(bytes), int(bytes.size()))) {
    *error = "not a Radiance HDR file";
    return false;
  }
  int width = 0, height = 0, channels = 0;
  std::unique_ptr<float, void (*)(void*)> pixels(
      stbi_loadf_from_memory(Data(bytes), int(bytes.size()), &width, &height, &channels, 3),
      stbi_image_free);
  if (!pixels) {
    *error = Reason();
    return false;
  }
  rgb->assign(pixels.get(), pixels.get() + size_t(width) * size_t(height) * 3);
  return true;
}

bool StbDecodeRgba8(std::string_view bytes, std::vector<uint8_t>* rgba, std::string* error) {
  if (TooLarge(bytes, error)) return false;
  if (stbi_is_hdr_from_memory(Data(bytes), int(bytes.size()))) {
    *error = "a Radiance HDR file, not an 8-bit image";
    return false;
  }
  int width = 0, height = 0, channels = 0;
  std::unique_ptr<stbi_uc, void (*)(void*)> pixels(
      stbi_load_from_memory(Data(bytes), int(bytes.size()), &width, &height, &channels, 4),
      stbi_image_free);
  if (!pixels) {
    *error = Reason();
    return false;
  }
  rgba->assign(pixels.get(), pixels.get() + size_t(width) * size_t(height) * 4);
  return true;
}

}  // namespace probebake::job_internal
