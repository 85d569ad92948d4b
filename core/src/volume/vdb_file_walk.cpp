#include "vdb_file_walk.h"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>

#include <openvdb/version.h>

namespace probebake::volume_internal {
namespace {

// Little-endian fields and length-prefixed strings from a file whose size is known; every read
// is checked against the bytes left.
class Walker {
 public:
  Walker(std::ifstream& in, uint64_t size) : in_(in), size_(size) {}

  uint64_t At() const { return at_; }
  uint64_t Left() const { return size_ - at_; }

  bool Seek(uint64_t to) {
    if (to > size_) return false;
    in_.seekg(std::streamoff(to));
    at_ = to;
    return bool(in_);
  }
  bool Skip(uint64_t n) { return n <= Left() && Seek(at_ + n); }

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

// A MetaMap: uint32 count, then per entry a name, a type name and a uint32-sized value.
std::string WalkMetadata(Walker& w, const std::string& what) {
  uint32_t count = 0;
  if (!w.Read(&count)) return what + " is cut short";
  // Each entry takes at least 12 bytes (three lengths).
  if (count > w.Left() / 12) {
    return what + " declares " + std::to_string(count) + " entries; " + std::to_string(w.Left()) +
           " bytes are left";
  }
  for (uint32_t i = 0; i < count; ++i) {
    std::string name;
    const std::string entry = what + " entry " + std::to_string(i);
    if (std::string p = w.String(entry + "'s name", &name); !p.empty()) return p;
    const std::string named = name.empty() ? entry : what + " \"" + name + "\"";
    if (std::string p = w.String(named + "'s type", nullptr); !p.empty()) return p;
    if (std::string p = w.String(named + "'s value", nullptr); !p.empty()) return p;
  }
  return "";
}

}  // namespace

std::string VdbFileProblem(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return "cannot open it";
  const std::streamoff end = in.tellg();
  if (end < 0) return "cannot tell its size";
  in.seekg(0);
  Walker w(in, uint64_t(end));

  int64_t magic = 0;
  uint32_t version = 0, libraryMajor = 0, libraryMinor = 0;
  char hasGridOffsets = 0;
  if (!w.Read(&magic) || magic != int64_t(openvdb::OPENVDB_MAGIC)) return "not an OpenVDB file";
  if (!w.Read(&version) || !w.Read(&libraryMajor) || !w.Read(&libraryMinor) ||
      !w.Read(&hasGridOffsets)) {
    return "its header is cut short";
  }
  if (version < openvdb::OPENVDB_FILE_VERSION_FLOAT_FRUSTUM_BBOX) {
    return "file format version " + std::to_string(version) + " is older than OpenVDB reads";
  }
  if (version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION && !w.Skip(1))
    return "its header is cut short";
  if (!w.Skip(36)) return "its header is cut short";  // the UUID, 36 ASCII characters
  if (!hasGridOffsets) return "it was written as a stream without grid offsets";

  if (std::string p = WalkMetadata(w, "file metadata"); !p.empty()) return p;
  int32_t grids = 0;
  if (!w.Read(&grids)) return "its grid count is cut short";
  // A descriptor takes at least 36 bytes (three lengths, three offsets).
  if (grids < 0 || uint64_t(grids) > w.Left() / 36) {
    return "it declares " + std::to_string(grids) + " grids; " + std::to_string(w.Left()) +
           " bytes are left";
  }
  for (int32_t g = 0; g < grids; ++g) {
    const std::string what = "grid descriptor " + std::to_string(g);
    std::string name;
    if (std::string p = w.String(what + "'s name", &name); !p.empty()) return p;
    const std::string grid = name.empty() ? what : "grid \"" + name + "\"";
    if (std::string p = w.String(grid + "'s type", nullptr); !p.empty()) return p;
    if (version >= openvdb::OPENVDB_FILE_VERSION_GRID_INSTANCING) {
      if (std::string p = w.String(grid + "'s instance parent", nullptr); !p.empty()) return p;
    }
    int64_t gridPos = 0, blockPos = 0, endPos = 0;
    if (!w.Read(&gridPos) || !w.Read(&blockPos) || !w.Read(&endPos))
      return grid + "'s offsets are cut short";
    const uint64_t descriptorEnd = w.At();
    const int64_t size = int64_t(end);
    if (!(int64_t(descriptorEnd) <= gridPos && gridPos <= blockPos && blockPos <= endPos &&
          endPos <= size)) {
      return grid + "'s offsets (" + std::to_string(gridPos) + ", " + std::to_string(blockPos) +
             ", " + std::to_string(endPos) + ") are not in order within the file's " +
             std::to_string(size) + " bytes";
    }
    // The grid's own metadata, read when the grid is: compression flags, then a MetaMap.
    if (!w.Seek(uint64_t(gridPos))) return grid + " is cut short";
    if (version >= openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION && !w.Skip(4))
      return grid + "'s compression flags are cut short";
    if (std::string p = WalkMetadata(w, grid + "'s metadata"); !p.empty()) return p;
    if (!w.Seek(uint64_t(endPos))) return grid + " is cut short";
  }
  return "";
}

}  // namespace probebake::volume_internal
