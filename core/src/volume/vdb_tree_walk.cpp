#include "vdb_tree_walk.h"

#include <algorithm>
#include <array>
#include <bit>
#include <map>
#include <set>
#include <tuple>
#include <vector>

namespace probebake::volume_internal {
namespace {

// io::COMPRESS_* (openvdb/io/Compression.h).
constexpr uint32_t kZip = 0x1, kActiveMask = 0x2, kBlosc = 0x4;

// The per-node metadata byte of io::readCompressedValues, 0..6 (NO_MASK_OR_INACTIVE_VALS ..
// NO_MASK_AND_ALL_VALS).
constexpr int8_t kOneInactive = 2, kMaskNoInactive = 3, kMaskOneInactive = 4, kMaskTwoInactive = 5,
                 kAllValues = 6;

// The 5-4-3 tree: node log2 dimensions from the upper internal node down to the leaf.
constexpr int kUpperLog2 = 5, kLowerLog2 = 4, kLeafLog2 = 3;
constexpr uint64_t NodeValues(int log2) {
  return uint64_t(1) << (3 * log2);
}
constexpr size_t MaskWords(int log2) {
  return size_t(NodeValues(log2) / 64);
}
// A root key is a multiple of the upper node's extent.
constexpr int64_t kRootKeyStep = int64_t(1) << (kUpperLog2 + kLowerLog2 + kLeafLog2);

using LeafMask = std::array<uint64_t, MaskWords(kLeafLog2)>;

// Bytes of one value as the tree holds it, and as saved in half floats (0: never half; such
// types are read at full size whatever the descriptor says).
struct ValueLayout {
  uint64_t bytes = 0;
  uint64_t halfBytes = 0;
};

const std::map<std::string, ValueLayout>& Layouts() {
  static const std::map<std::string, ValueLayout> kLayouts = {
      {"Tree_float_5_4_3", {4, 2}}, {"Tree_double_5_4_3", {8, 2}}, {"Tree_int32_5_4_3", {4, 0}},
      {"Tree_int64_5_4_3", {8, 0}}, {"Tree_vec3s_5_4_3", {12, 6}}, {"Tree_vec3d_5_4_3", {24, 6}},
      {"Tree_vec3i_5_4_3", {12, 0}}};
  return kLayouts;
}

// The descriptor's type without OpenVDB's half-float suffix, and whether it had one.
std::pair<std::string, bool> SplitHalf(const std::string& type) {
  static const std::string kHalf = "_HalfFloat";
  if (type.size() > kHalf.size() && type.ends_with(kHalf))
    return {type.substr(0, type.size() - kHalf.size()), true};
  return {type, false};
}

// Bytes each linear map reads (math/Maps.h read()): a Mat4d, or Vec3d fields.
const std::map<std::string, uint64_t>& LinearMapBytes() {
  static const std::map<std::string, uint64_t> kMaps = {{"AffineMap", 128},
                                                        {"UnitaryMap", 128},
                                                        {"ScaleMap", 5 * 24},
                                                        {"UniformScaleMap", 5 * 24},
                                                        {"TranslationMap", 24},
                                                        {"ScaleTranslateMap", 6 * 24},
                                                        {"UniformScaleTranslateMap", 6 * 24}};
  return kMaps;
}

struct RootChild {
  std::array<int32_t, 3> origin{};
  std::vector<LeafMask> leaves;  // in the order their buffers follow
};

class TreeWalk {
 public:
  TreeWalk(FileWalker& w, const GridBody& grid, ValueLayout layout, bool half)
      : w_(w),
        grid_(grid),
        valueBytes_(layout.bytes),
        storedBytes_(half && layout.halfBytes > 0 ? layout.halfBytes : layout.bytes),
        halfReader_(half && layout.halfBytes > 0) {}

  std::string Walk() {
    if (std::string p = Transform(); !p.empty()) return p;
    if (grid_.instance) return "";
    if (std::string p = Topology(); !p.empty()) return p;
    if (w_.At() != grid_.blockPos) {
      return grid_.what + "'s topology ends at byte " + std::to_string(w_.At()) +
             "; its descriptor puts the leaf buffers at " + std::to_string(grid_.blockPos);
    }
    if (std::string p = Buffers(); !p.empty()) return p;
    if (w_.At() != grid_.endPos) {
      return grid_.what + "'s leaf buffers end at byte " + std::to_string(w_.At()) +
             "; its descriptor ends the grid at " + std::to_string(grid_.endPos);
    }
    return "";
  }

 private:
  std::string CutShort(const std::string& what) const { return what + " is cut short"; }

  std::string Transform() {
    std::string type;
    const std::string what = grid_.what + "'s transform";
    if (std::string p = w_.String(what, &type, 64); !p.empty()) return p;
    const auto it = LinearMapBytes().find(type);
    if (it == LinearMapBytes().end())
      return what + " is a \"" + type + "\", which this reader does not take";
    return w_.Skip(it->second) ? "" : CutShort(what);
  }

  std::string Topology() {
    int32_t bufferCount = 0;
    if (!w_.Read(&bufferCount)) return CutShort(grid_.what + "'s tree");
    if (bufferCount != 1) {
      return grid_.what + "'s tree declares " + std::to_string(bufferCount) +
             " buffers per leaf, not 1";
    }
    const std::string root = grid_.what + "'s root";
    uint32_t tiles = 0, children = 0;
    if (!w_.Skip(valueBytes_) || !w_.Read(&tiles) || !w_.Read(&children)) return CutShort(root);
    // Each tile takes a key, a value and a flag; each child at least a key and two masks.
    if (tiles > w_.Left() / (12 + valueBytes_ + 1)) {
      return root + " declares " + std::to_string(tiles) + " tiles; " + std::to_string(w_.Left()) +
             " bytes are left";
    }
    std::set<std::array<int32_t, 3>> keys;
    for (uint32_t t = 0; t < tiles; ++t) {
      const std::string what = root + " tile " + std::to_string(t);
      std::array<int32_t, 3> key{};
      if (std::string p = Key(what, &key, &keys); !p.empty()) return p;
      uint8_t active = 0;
      if (!w_.Skip(valueBytes_) || !w_.Read(&active)) return CutShort(what);
      // OpenVDB loads the byte as a bool: any value but 0 or 1 is undefined behaviour.
      if (active > 1)
        return what + "'s active flag holds " + std::to_string(active) + ", not 0 or 1";
    }
    if (children > w_.Left() / (12 + 2 * 8 * MaskWords(kUpperLog2))) {
      return root + " declares " + std::to_string(children) + " children; " +
             std::to_string(w_.Left()) + " bytes are left";
    }
    children_.resize(children);
    for (uint32_t c = 0; c < children; ++c) {
      const std::string what = root + " child " + std::to_string(c);
      if (std::string p = Key(what, &children_[c].origin, &keys); !p.empty()) return p;
      if (std::string p = Internal(what, kUpperLog2, &children_[c].leaves); !p.empty()) return p;
    }
    // OpenVDB keeps the root's children in a map by key and reads their buffers in that order.
    std::sort(children_.begin(), children_.end(),
              [](const RootChild& a, const RootChild& b) { return a.origin < b.origin; });
    return "";
  }

  // A root key: three int32, a multiple of the upper node's extent, not seen before.
  std::string Key(const std::string& what, std::array<int32_t, 3>* key,
                  std::set<std::array<int32_t, 3>>* seen) {
    for (int32_t& c : *key) {
      if (!w_.Read(&c)) return CutShort(what);
    }
    for (const int32_t c : *key) {
      if (int64_t(c) % kRootKeyStep != 0) {
        return what + "'s origin (" + std::to_string((*key)[0]) + ", " + std::to_string((*key)[1]) +
               ", " + std::to_string((*key)[2]) + ") is not a multiple of " +
               std::to_string(kRootKeyStep);
      }
    }
    if (!seen->insert(*key).second) {
      return what + "'s origin (" + std::to_string((*key)[0]) + ", " + std::to_string((*key)[1]) +
             ", " + std::to_string((*key)[2]) + ") is used twice";
    }
    return "";
  }

  // An internal node of 2^(3 log2) entries: child mask, value mask, its values, then its
  // children (internal nodes or leaves) in mask order. Leaf masks are appended to `leaves`.
  std::string Internal(const std::string& what, int log2, std::vector<LeafMask>* leaves) {
    const size_t words = MaskWords(log2);
    std::vector<uint64_t> childMask(words), valueMask(words);
    if (!w_.Raw(childMask.data(), 8 * words) || !w_.Raw(valueMask.data(), 8 * words))
      return CutShort(what + "'s masks");
    uint64_t active = 0;
    for (size_t i = 0; i < words; ++i) {
      // OpenVDB keeps a child or a tile value per entry, never both.
      if ((childMask[i] & valueMask[i]) != 0)
        return what + " marks entries as both a child and an active tile";
      active += uint64_t(std::popcount(valueMask[i]));
    }
    if (std::string p = Values(what + "'s values", NodeValues(log2), active, 8 * words);
        !p.empty()) {
      return p;
    }
    uint64_t child = 0;
    for (size_t i = 0; i < words; ++i) {
      for (uint64_t bits = childMask[i]; bits != 0; bits &= bits - 1, ++child) {
        const std::string childWhat = what + " child " + std::to_string(child);
        if (log2 == kUpperLog2) {
          if (std::string p = Internal(childWhat, kLowerLog2, leaves); !p.empty()) return p;
          continue;
        }
        LeafMask mask{};
        if (!w_.Raw(mask.data(), sizeof(mask))) return CutShort(childWhat + "'s mask");
        leaves->push_back(mask);
      }
    }
    return "";
  }

  // Each leaf's buffer: its value mask again (OpenVDB skips it in a seekable file and reads it
  // otherwise, so it must equal the topology's), then its values.
  std::string Buffers() {
    uint64_t leaf = 0;
    for (const RootChild& child : children_) {
      for (const LeafMask& mask : child.leaves) {
        const std::string what = grid_.what + " leaf " + std::to_string(leaf++);
        LeafMask again{};
        if (!w_.Raw(again.data(), sizeof(again))) return CutShort(what + "'s buffer");
        if (again != mask) return what + "'s buffer mask differs from its topology mask";
        uint64_t active = 0;
        for (const uint64_t word : mask) active += uint64_t(std::popcount(word));
        if (std::string p = Values(what + "'s values", NodeValues(kLeafLog2), active, sizeof(mask));
            !p.empty()) {
          return p;
        }
      }
    }
    return "";
  }

  // io::readCompressedValues for a node of `count` values, `active` of them active.
  std::string Values(const std::string& what, uint64_t count, uint64_t active, uint64_t maskBytes) {
    int8_t metadata = 0;
    if (!w_.Read(&metadata)) return CutShort(what);
    if (metadata < 0 || metadata > kAllValues) {
      return what + " have compression metadata " + std::to_string(metadata) +
             ", which OpenVDB does not write";
    }
    if (metadata == kOneInactive || metadata == kMaskOneInactive || metadata == kMaskTwoInactive) {
      // Inactive values are stored at full size, half floats or not.
      const uint64_t inactive = metadata == kMaskTwoInactive ? 2 : 1;
      if (!w_.Skip(inactive * valueBytes_)) return CutShort(what);
    }
    if ((metadata == kMaskNoInactive || metadata == kMaskOneInactive ||
         metadata == kMaskTwoInactive) &&
        !w_.Skip(maskBytes)) {
      return CutShort(what);
    }
    const bool maskCompressed = (grid_.compression & kActiveMask) != 0;
    const uint64_t stored = maskCompressed && metadata != kAllValues ? active : count;
    // OpenVDB's half reader reads nothing at all for no values; every other path reads a chunk.
    if (halfReader_ && stored == 0) return "";
    const uint64_t bytes = stored * storedBytes_;
    if ((grid_.compression & (kBlosc | kZip)) == 0) return w_.Skip(bytes) ? "" : CutShort(what);
    return Chunk(what, bytes, (grid_.compression & kBlosc) != 0);
  }

  // A compressed chunk: int64 size (negative: stored uncompressed), then the bytes.
  std::string Chunk(const std::string& what, uint64_t bytes, bool blosc) {
    int64_t declared = 0;
    if (!w_.Read(&declared)) return CutShort(what);
    if (declared <= 0) {
      const uint64_t raw = uint64_t(0) - uint64_t(declared);
      if (raw != bytes) {
        return what + " declare an uncompressed chunk of " + std::to_string(raw) +
               " bytes; the node holds " + std::to_string(bytes);
      }
      return w_.Skip(raw) ? "" : CutShort(what);
    }
    if (uint64_t(declared) > w_.Left()) {
      return what + " declare a compressed chunk of " + std::to_string(declared) + " bytes; " +
             std::to_string(w_.Left()) + " are left";
    }
    if (!blosc) return w_.Skip(uint64_t(declared)) ? "" : CutShort(what);
    // Blosc's header: version, versionlz, flags, typesize, then nbytes (uncompressed), blocksize
    // and cbytes (the whole chunk), uint32 each. Blosc decompresses by the header alone.
    constexpr uint64_t kHeader = 16;
    std::array<uint8_t, kHeader> header{};
    if (uint64_t(declared) < kHeader || !w_.Raw(header.data(), kHeader)) {
      return what + " declare a Blosc chunk of " + std::to_string(declared) +
             " bytes, shorter than its header";
    }
    const auto u32 = [&](size_t at) {
      uint32_t v = 0;
      for (size_t i = 0; i < 4; ++i) v |= uint32_t(header[at + i]) << (8 * i);
      return v;
    };
    if (u32(4) != bytes) {
      return what + "' Blosc chunk decompresses to " + std::to_string(u32(4)) +
             " bytes; the node holds " + std::to_string(bytes);
    }
    if (u32(12) != uint64_t(declared)) {
      return what + "' Blosc chunk says it takes " + std::to_string(u32(12)) +
             " bytes; the file gives it " + std::to_string(declared);
    }
    return w_.Skip(uint64_t(declared) - kHeader) ? "" : CutShort(what);
  }

  FileWalker& w_;
  const GridBody& grid_;
  uint64_t valueBytes_;
  uint64_t storedBytes_;
  bool halfReader_;
  std::vector<RootChild> children_;
};

}  // namespace

std::string GridTypeProblem(const GridBody& grid) {
  if (Layouts().count(SplitHalf(grid.type).first) == 0) {
    return grid.what + " has type \"" + grid.type +
           "\", which this reader does not take (numeric 5-4-3 trees only)";
  }
  return "";
}

std::string WalkGridBody(FileWalker& w, const GridBody& grid) {
  if (std::string p = GridTypeProblem(grid); !p.empty()) return p;
  const auto [type, half] = SplitHalf(grid.type);
  return TreeWalk(w, grid, Layouts().at(type), half).Walk();
}

}  // namespace probebake::volume_internal
