#include "vdb_file_walk.h"

#include "vdb_file_walker.h"
#include "vdb_tree_walk.h"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <string_view>

#include <openvdb/version.h>

namespace probebake::volume_internal {
namespace {

// OpenVDB's own per-grid metadata of leaf-buffer masks and sizes ("file_delayed_load"), which it
// writes into every grid and reads by the counts inside it.
constexpr const char* kDelayedLoad = "__delayedload";

// The delayed-load value: a count, then a mask of `count` int8 and `count` int64 sizes, each raw
// or Blosc-compressed (uint32 byte size first; UINT32_MAX for no sizes). OpenVDB sizes its arrays
// by the count and by the uncompressed size in the Blosc header, so both are bounded by what a
// writer can produce: one entry per leaf buffer (at least a byte of the file each), and at most
// 8 bytes per byte of the file uncompressed (OpenVDB's writer pads the arrays a little).
std::string DelayedLoadProblem(std::string_view value, uint64_t fileBytes,
                               const std::string& what) {
  if (value.empty()) return "";
  const auto u32 = [&](size_t at) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t(uint8_t(value[at + size_t(i)])) << (8 * i);
    return v;
  };
  if (value.size() < 8) return what + " is cut short";
  const uint64_t count = u32(0);
  if (count > fileBytes) {
    return what + " declares " + std::to_string(count) + " leaf buffers in a file of " +
           std::to_string(fileBytes) + " bytes";
  }
  size_t at = 4;
  for (const uint64_t entryBytes : {uint64_t(1), uint64_t(8)}) {
    if (value.size() - at < 4) return what + " is cut short";
    const uint32_t bytes = u32(at);
    at += 4;
    if (entryBytes == 8 && bytes == UINT32_MAX) return "";  // no sizes stored
    if (bytes == 0) {
      if (count * entryBytes > value.size() - at) return what + " is cut short";
      at += size_t(count * entryBytes);
      continue;
    }
    // Blosc's header: version, versionlz, flags, typesize, then nbytes (uint32, uncompressed).
    if (bytes < 16 || bytes > value.size() - at) return what + " is cut short";
    if (u32(at + 4) > 8 * fileBytes) {
      return what + "'s compressed data declares " + std::to_string(u32(at + 4)) +
             " bytes in a file of " + std::to_string(fileBytes);
    }
    at += bytes;
  }
  return "";
}

// The bytes OpenVDB reads for a value of metadata type `type`: its fixed-size types read
// sizeof(T) whatever size the file declares, so a different declared size would make OpenVDB part
// from this walk. 0 for a string (the declared size); -1 for a type this reader does not take.
int64_t MetadataValueBytes(const std::string& type) {
  static const std::map<std::string, int64_t> kFixed = {
      {"bool", 1},   {"int32", 4},  {"int64", 8},  {"float", 4},  {"double", 8}, {"vec2i", 8},
      {"vec2s", 8},  {"vec2d", 16}, {"vec3i", 12}, {"vec3s", 12}, {"vec3d", 24}, {"vec4i", 16},
      {"vec4s", 16}, {"vec4d", 32}, {"mat4s", 64}, {"mat4d", 128}};
  if (type == "string" || type == kDelayedLoad) return 0;
  const auto it = kFixed.find(type);
  return it == kFixed.end() ? -1 : it->second;
}

// A MetaMap: uint32 count, then per entry a name, a type name and a uint32-sized value.
std::string WalkMetadata(FileWalker& w, const std::string& what) {
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
    std::string type;
    if (std::string p = w.String(named + "'s type", &type); !p.empty()) return p;
    const int64_t valueBytes = MetadataValueBytes(type);
    if (valueBytes < 0)
      return named + " has type \"" + type + "\", which this reader does not take";
    uint32_t declared = 0;
    if (!w.Read(&declared)) return named + "'s value is cut short";
    if (valueBytes > 0 && declared != uint64_t(valueBytes)) {
      return named + " (" + type + ") declares " + std::to_string(declared) + " bytes, not " +
             std::to_string(valueBytes);
    }
    if (type == "bool" && declared <= w.Left()) {
      // OpenVDB loads the byte as a bool: any value but 0 or 1 is undefined behaviour.
      std::string value;
      if (!w.Bytes(1, &value)) return named + "'s value is cut short";
      if (uint8_t(value[0]) > 1) {
        return named + " (bool) holds " + std::to_string(uint8_t(value[0])) + ", not 0 or 1";
      }
    } else if (type == kDelayedLoad && declared <= w.Left()) {
      std::string value;
      if (!w.Bytes(declared, &value)) return named + "'s value is cut short";
      if (std::string p = DelayedLoadProblem(value, w.Size(), named); !p.empty()) return p;
    } else if (!w.Skip(declared)) {
      return named + "'s value declares " + std::to_string(declared) + " bytes; " +
             std::to_string(w.Left()) + " are left";
    }
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
  FileWalker w(in, uint64_t(end));

  int64_t magic = 0;
  uint32_t version = 0, libraryMajor = 0, libraryMinor = 0;
  char hasGridOffsets = 0;
  if (!w.Read(&magic) || magic != int64_t(openvdb::OPENVDB_MAGIC)) return "not an OpenVDB file";
  if (!w.Read(&version) || !w.Read(&libraryMajor) || !w.Read(&libraryMinor) ||
      !w.Read(&hasGridOffsets)) {
    return "its header is cut short";
  }
  // Files older than OpenVDB 2.0 (2013) lay grid trees out differently; the tree walk follows
  // the current layout only.
  if (version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) {
    return "file format version " + std::to_string(version) + " is older than this reader takes";
  }
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
    GridBody body;
    body.what = grid;
    if (std::string p = w.String(grid + "'s type", &body.type); !p.empty()) return p;
    std::string parent;
    if (std::string p =
            w.String(grid + "'s instance parent", &parent, std::numeric_limits<size_t>::max());
        !p.empty())
      return p;
    body.instance = !parent.empty();
    if (std::string p = GridTypeProblem(body); !p.empty()) return p;
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
    // The grid as OpenVDB reads it: compression flags, a MetaMap, then its body.
    body.blockPos = uint64_t(blockPos);
    body.endPos = uint64_t(endPos);
    if (!w.Seek(uint64_t(gridPos)) || !w.Read(&body.compression))
      return grid + "'s compression flags are cut short";
    if (std::string p = WalkMetadata(w, grid + "'s metadata"); !p.empty()) return p;
    if (std::string p = WalkGridBody(w, body); !p.empty()) return p;
    if (!w.Seek(uint64_t(endPos))) return grid + " is cut short";
  }
  return "";
}

}  // namespace probebake::volume_internal
