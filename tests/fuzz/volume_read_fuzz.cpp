// Probe volume files (.vdb) through the reader `probebake inspect`, `merge` and the server use.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <new>
#include <string>

#include "probebake/base/log.h"
#include "probebake/volume/vdb_io.h"

// OpenVDB sizes its buffers from the file; a corrupt size asks for terabytes. Without a sanitizer
// that allocation fails and throws std::bad_alloc, which the reader reports as a bad file
// (`probebake inspect` on such a file: "OpenVDB: RuntimeError: ..."); AddressSanitizer's own
// operator new aborts instead. These replacements restore the production behaviour (malloc, which
// ASan makes return null under allocator_may_return_null=1, then bad_alloc) so fuzzing goes on.
void* operator new(size_t size) {
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t size) {
  return operator new(size);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, size_t) noexcept {
  std::free(p);
}
void* operator new(size_t size, std::align_val_t align) {
  const size_t a = size_t(align);
  if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t size, std::align_val_t align) {
  return operator new(size, align);
}
void operator delete(void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete(void* p, size_t, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, size_t, std::align_val_t) noexcept {
  std::free(p);
}

// Memory from ASan's allocator may reach these deletes (and the reverse): not a mismatch here.
extern "C" const char* __asan_default_options() {
  return "alloc_dealloc_mismatch=0:allocator_may_return_null=1";
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = (probebake::SetLogLevel(spdlog::level::off), true);
  (void)quiet;
  static const std::string path = "/tmp/probebake-fuzz-volume-" + std::to_string(getpid()) + ".vdb";
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  (void)probebake::ReadProbeVolume(path);
  return 0;
}
