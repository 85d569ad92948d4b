#include "png_io.h"

#include <png.h>

#include <cerrno>
#include <csetjmp>
#include <cstdio>

#include "probebake/base/atomic_file.h"
#include "probebake/base/check.h"
#include "probebake/base/io_error.h"

namespace probebake::volume_internal {
namespace {

// libpng reports errors by longjmp; everything touched after setjmp lives outside that frame.
struct PngWriteState {
  png_structp png = nullptr;
  png_infop info = nullptr;
  FILE* out = nullptr;
  std::string error;
};

void OnPngError(png_structp png, png_const_charp message) {
  auto* state = static_cast<PngWriteState*>(png_get_error_ptr(png));
  state->error = message;
  png_longjmp(png, 1);
}

void OnPngWarning(png_structp, png_const_charp) {}

// Returns false and sets state->error on failure. No C++ objects with destructors are created
// between setjmp and the end of this function.
bool EncodePng(PngWriteState* state, int width, int height, const uint8_t* rgb) {
  if (setjmp(png_jmpbuf(state->png))) return false;
  png_init_io(state->png, state->out);
  png_set_IHDR(state->png, state->info, png_uint_32(width), png_uint_32(height), 8,
               PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  // The pixels are sRGB-encoded.
  png_set_sRGB_gAMA_and_cHRM(state->png, state->info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(state->png, state->info);
  for (int y = 0; y < height; ++y) {
    png_write_row(state->png, rgb + size_t(y) * size_t(width) * 3);
  }
  png_write_end(state->png, state->info);
  return true;
}

}  // namespace

absl::Status WritePngRgb8(const std::string& path, int width, int height,
                          const std::vector<uint8_t>& rgb) {
  PB_CHECK(width > 0 && height > 0);
  PB_CHECK_EQ(rgb.size(), size_t(width) * size_t(height) * 3);
  PB_ASSIGN_OR_RETURN(AtomicFile file, AtomicFile::Create(path));
  PngWriteState state;
  state.out = std::fopen(file.tempPath().c_str(), "wb");
  if (state.out == nullptr) return IoError(errno, path, "cannot open " + file.tempPath());
  state.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &state, OnPngError, OnPngWarning);
  if (state.png != nullptr) state.info = png_create_info_struct(state.png);
  bool ok = state.png != nullptr && state.info != nullptr;
  if (!ok) state.error = "cannot initialise libpng";
  errno = 0;
  if (ok) ok = EncodePng(&state, width, height, rgb.data());
  png_destroy_write_struct(state.png ? &state.png : nullptr, state.info ? &state.info : nullptr);
  const bool flushed = std::fflush(state.out) == 0 && !std::ferror(state.out);
  const int writeErrno = errno;
  const bool closed = std::fclose(state.out) == 0;
  if (!flushed || !closed) {
    // libpng's own "Write Error" says less than errno (ENOSPC, EFBIG, ...).
    return IoError(writeErrno != 0 ? writeErrno : EIO, path, "writing the PNG failed");
  }
  if (!ok) return absl::InternalError(path + ": PNG encoding failed: " + state.error);
  return file.Commit();
}

}  // namespace probebake::volume_internal
