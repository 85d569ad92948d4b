// A native-endian byte writer and a bounds-checked reader, for data a process hands to its own
// child or parent on one machine (mesh_imports.h): never for files that outlive the processes.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace probebake::job_internal {

class ByteWriter {
 public:
  template <typename T>
  void Put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  void PutString(std::string_view s) {
    Put(uint64_t(s.size()));
    bytes_.append(s);
  }
  // A count, then the elements' bytes.
  template <typename T>
  void PutVector(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    Put(uint64_t(values.size()));
    if (!values.empty())
      bytes_.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  }
  std::string Take() { return std::move(bytes_); }

 private:
  std::string bytes_;
};

// Every Get fails (returns false, and keeps failing) rather than read past the end.
class ByteReader {
 public:
  explicit ByteReader(std::string_view bytes) : bytes_(bytes) {}

  template <typename T>
  bool Get(T* value) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (!Have(sizeof(T))) return false;
    std::memcpy(value, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return true;
  }
  bool GetString(std::string* s) {
    uint64_t size = 0;
    if (!Get(&size) || !Have(size)) return Fail();
    s->assign(bytes_.data() + at_, size_t(size));
    at_ += size_t(size);
    return true;
  }
  template <typename T>
  bool GetVector(std::vector<T>* values) {
    static_assert(std::is_trivially_copyable_v<T>);
    uint64_t count = 0;
    if (!Get(&count) || count > (bytes_.size() - at_) / sizeof(T)) return Fail();
    values->resize(size_t(count));
    if (count > 0) std::memcpy(values->data(), bytes_.data() + at_, size_t(count) * sizeof(T));
    at_ += size_t(count) * sizeof(T);
    return true;
  }
  // A count of items each at least `minItemBytes` long: refused when the bytes left cannot hold
  // them, so that a damaged count never sizes an allocation.
  bool GetCount(uint64_t minItemBytes, uint64_t* count) {
    if (!Get(count) || *count > (bytes_.size() - at_) / minItemBytes) return Fail();
    return true;
  }
  bool AtEnd() const { return ok_ && at_ == bytes_.size(); }
  bool ok() const { return ok_; }

 private:
  bool Have(uint64_t n) {
    if (!ok_ || n > bytes_.size() - at_) return Fail();
    return true;
  }
  bool Fail() {
    ok_ = false;
    return false;
  }

  std::string_view bytes_;
  size_t at_ = 0;
  bool ok_ = true;
};

}  // namespace probebake::job_internal
