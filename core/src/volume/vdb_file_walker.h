// Reading an OpenVDB file field by field, every read checked against the bytes the file holds;
// the walks in vdb_file_walk.cpp and vdb_tree_walk.cpp share it.
#pragma once

#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>

namespace probebake::volume_internal {

// Little-endian fields and length-prefixed strings from a file whose size is known; every read
// is checked against the bytes left.
class FileWalker {
 public:
  FileWalker(std::ifstream& in, uint64_t size) : in_(in), size_(size) {}

  uint64_t At() const { return at_; }
  uint64_t Left() const { return size_ - at_; }

  bool Seek(uint64_t to) {
    if (to > size_) return false;
    in_.seekg(std::streamoff(to));
    at_ = to;
    return bool(in_);
  }
  uint64_t Size() const { return size_; }
  bool Skip(uint64_t n) { return n <= Left() && Seek(at_ + n); }
  bool Bytes(uint64_t n, std::string* out) {
    if (n > Left()) return false;
    out->resize(size_t(n));
    if (n > 0 && !in_.read(out->data(), std::streamsize(n))) return false;
    at_ += n;
    return true;
  }

  // `n` raw bytes into `out`.
  bool Raw(void* out, size_t n) {
    if (n > Left() || (n > 0 && !in_.read(static_cast<char*>(out), std::streamsize(n))))
      return false;
    at_ += n;
    return true;
  }

  template <typename T>
  bool Read(T* value) {
    unsigned char bytes[sizeof(T)];
    if (Left() < sizeof(T) || !in_.read(reinterpret_cast<char*>(bytes), sizeof(T))) return false;
    at_ += sizeof(T);
    uint64_t v = 0;
    for (size_t i = 0; i < sizeof(T); ++i) v |= uint64_t(bytes[i]) << (8 * i);
    std::memcpy(value, &v, sizeof(T));  // little-endian host (x86-64, aarch64)
    return true;
  }

  // A string as OpenVDB writes it: uint32 length, then the bytes. Strings longer than `keep`
  // are skipped, not read (names this walk reports stay short).
  std::string String(const std::string& what, std::string* out, size_t keep = 256) {
    uint32_t length = 0;
    if (!Read(&length)) return what + " is cut short";
    if (length > Left()) {
      return what + " declares " + std::to_string(length) + " bytes; " + std::to_string(Left()) +
             " are left";
    }
    if (out != nullptr && length <= keep) {
      out->resize(length);
      if (length > 0 && !in_.read(out->data(), length)) return what + " is cut short";
      at_ += length;
      return "";
    }
    return Skip(length) ? "" : what + " is cut short";
  }

 private:
  std::ifstream& in_;
  uint64_t size_;
  uint64_t at_ = 0;
};

}  // namespace probebake::volume_internal
