// A native-endian byte writer and a bounds-checked reader, for data that stays on one machine:
// checkpoints a server reads back after a restart (server/checkpoint.h) and the mesh imports an
// asset-check child hands its parent (probebake/job/mesh_imports.h). Plain values are their bytes,
// strings and vectors a uint64 count first.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace probebake {

class ByteWriter {
 public:
  template <typename T>
  void Pod(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  void String(std::string_view s) {
    Pod(uint64_t(s.size()));
    bytes_.append(s);
  }
  template <typename T>
  void Vector(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    Pod(uint64_t(v.size()));
    if (!v.empty()) bytes_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  std::string& bytes() { return bytes_; }

 private:
  std::string bytes_;
};

// Every read returns false, reading nothing, when the bytes left cannot hold what it asks for.
class ByteReader {
 public:
  explicit ByteReader(std::string_view bytes) : bytes_(bytes) {}
  template <typename T>
  bool Pod(T* v) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (bytes_.size() < sizeof(T)) return false;
    std::memcpy(v, bytes_.data(), sizeof(T));
    bytes_.remove_prefix(sizeof(T));
    return true;
  }
  bool String(std::string* s) {
    uint64_t n;
    if (!Pod(&n) || n > bytes_.size()) return false;
    s->assign(bytes_.data(), size_t(n));
    bytes_.remove_prefix(size_t(n));
    return true;
  }
  template <typename T>
  bool Vector(std::vector<T>* v) {
    static_assert(std::is_trivially_copyable_v<T>);
    uint64_t n;
    if (!Pod(&n) || n > bytes_.size() / sizeof(T)) return false;
    v->resize(size_t(n));
    // memcpy from or to an empty vector's null data() is undefined, even for 0 bytes.
    if (n > 0) std::memcpy(v->data(), bytes_.data(), size_t(n) * sizeof(T));
    bytes_.remove_prefix(size_t(n) * sizeof(T));
    return true;
  }
  // A count of items each at least `minItemBytes` long: false when the bytes left cannot hold
  // them, so that a damaged count never sizes an allocation.
  bool Count(uint64_t minItemBytes, uint64_t* n) {
    return Pod(n) && *n <= bytes_.size() / minItemBytes;
  }
  bool AtEnd() const { return bytes_.empty(); }

 private:
  std::string_view bytes_;
};

}  // namespace probebake
