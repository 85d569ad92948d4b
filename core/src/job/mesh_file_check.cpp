#include "mesh_file_check.h"

#include <cstdint>
#include <cstring>
#include <vector>

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <cmath>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "json_nesting.h"
#include "text.h"

namespace probebake::job_internal {
namespace {

// A PLY header's size cap: real headers are a few hundred bytes, comments included.
constexpr size_t kMaxHeaderBytes = size_t{1} << 20;

enum class Format { kAscii, kLittleEndian, kBigEndian };

struct Property {
  bool list = false;
  int countBytes = 0;  // list: size of the count
  bool countSigned = false;
  int bytes = 0;  // scalar size, or a list item's size
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
};

// Size of a PLY scalar type (0 when unknown), and whether it is an integer and signed.
int TypeBytes(absl::string_view type, bool* integer = nullptr, bool* isSigned = nullptr) {
  struct Type {
    const char* name;
    int bytes;
    bool integer, isSigned;
  };
  static constexpr Type kTypes[] = {
      {"char", 1, true, true},     {"int8", 1, true, true},     {"uchar", 1, true, false},
      {"uint8", 1, true, false},   {"short", 2, true, true},    {"int16", 2, true, true},
      {"ushort", 2, true, false},  {"uint16", 2, true, false},  {"int", 4, true, true},
      {"int32", 4, true, true},    {"uint", 4, true, false},    {"uint32", 4, true, false},
      {"float", 4, false, true},   {"float32", 4, false, true}, {"double", 8, false, true},
      {"float64", 8, false, true},
  };
  for (const Type& t : kTypes) {
    if (type == t.name) {
      if (integer) *integer = t.integer;
      if (isSigned) *isSigned = t.isSigned;
      return t.bytes;
    }
  }
  return 0;
}

// A list count of `bytes` bytes at `p`, in the file's byte order; -1 for a negative one.
int64_t ReadCount(const unsigned char* p, int bytes, bool isSigned, bool bigEndian) {
  uint64_t u = 0;
  for (int k = 0; k < bytes; ++k)
    u |= uint64_t(p[bigEndian ? k : bytes - 1 - k]) << (8 * (bytes - 1 - k));
  if (isSigned && (u >> (8 * bytes - 1)) & 1) return -1;
  return int64_t(u);
}

std::string Where(const Element& e, uint64_t item) {
  return "element '" + e.name + "' item " + std::to_string(item);
}

std::string CheckBinary(std::string_view body, const std::vector<Element>& elements,
                        bool bigEndian) {
  const auto* p = reinterpret_cast<const unsigned char*>(body.data());
  uint64_t left = body.size();
  for (const Element& e : elements) {
    if (e.count == 0) continue;
    uint64_t fixed = 0;
    bool lists = false;
    for (const Property& q : e.properties) {
      fixed += uint64_t(q.list ? q.countBytes : q.bytes);
      lists = lists || q.list;
    }
    // Every item needs at least its fixed bytes: a count past the body is refused before looping.
    if (e.count > left / fixed) return "the body ends before " + Where(e, left / fixed);
    if (!lists) {
      p += e.count * fixed;
      left -= e.count * fixed;
      continue;
    }
    for (uint64_t i = 0; i < e.count; ++i) {
      for (const Property& q : e.properties) {
        const uint64_t head = uint64_t(q.list ? q.countBytes : q.bytes);
        if (left < head) return "the body ends inside " + Where(e, i);
        if (!q.list) {
          p += head;
          left -= head;
          continue;
        }
        const int64_t n = ReadCount(p, q.countBytes, q.countSigned, bigEndian);
        p += head;
        left -= head;
        if (n < 0) return Where(e, i) + " has a negative list count";
        if (uint64_t(n) > left / uint64_t(q.bytes)) return "the body ends inside " + Where(e, i);
        p += uint64_t(n) * q.bytes;
        left -= uint64_t(n) * q.bytes;
      }
    }
  }
  return "";
}

std::string CheckAscii(std::string_view body, const std::vector<Element>& elements) {
  size_t at = 0;
  // The next whitespace-separated token, or an empty view at the end.
  auto next = [&]() -> std::string_view {
    while (at < body.size() && std::strchr(" \t\r\n", body[at]) != nullptr) ++at;
    const size_t start = at;
    while (at < body.size() && std::strchr(" \t\r\n", body[at]) == nullptr) ++at;
    return body.substr(start, at - start);
  };
  for (const Element& e : elements) {
    if (e.count == 0) continue;
    // Every item needs a number and a separator per property at least.
    const uint64_t perItem = 2 * e.properties.size();
    if (e.count > (body.size() - at + 1) / perItem) {
      return "the body ends before " + Where(e, (body.size() - at + 1) / perItem);
    }
    for (uint64_t i = 0; i < e.count; ++i) {
      for (const Property& q : e.properties) {
        const std::string_view token = next();
        if (token.empty()) return "the body ends inside " + Where(e, i);
        if (!q.list) continue;
        int64_t n = 0;
        if (!absl::SimpleAtoi(absl::string_view(token.data(), token.size()), &n) || n < 0)
          return Where(e, i) + " has a list count that is not a non-negative integer";
        if (uint64_t(n) > (body.size() - at + 1) / 2) return "the body ends inside " + Where(e, i);
        for (int64_t k = 0; k < n; ++k) {
          if (next().empty()) return "the body ends inside " + Where(e, i);
        }
      }
    }
  }
  return "";
}

}  // namespace

std::string PlyProblem(std::string_view bytes) {
  const std::string_view window = bytes.substr(0, kMaxHeaderBytes);
  std::vector<Element> elements;
  size_t lineStart = 0;
  int line = 0;
  bool formatSeen = false;
  Format format = Format::kAscii;
  while (lineStart < window.size()) {
    const size_t end = window.find('\n', lineStart);
    if (end == std::string_view::npos) break;
    std::string_view text = window.substr(lineStart, end - lineStart);
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
    lineStart = end + 1;
    ++line;
    const std::string at = " on line " + std::to_string(line);
    for (const char ch : text) {
      const auto c = static_cast<unsigned char>(ch);
      if ((c < 0x20 && c != '\t') || c > 0x7e)
        return "its header has a byte that is not text (" + std::to_string(int(c)) + ")" + at;
    }
    const std::vector<absl::string_view> words = absl::StrSplit(
        absl::string_view(text.data(), text.size()), absl::ByAnyChar(" \t"), absl::SkipEmpty());
    if (line == 1) {
      if (text != "ply") return "it does not start with a \"ply\" line";
      continue;
    }
    if (words.empty() || words[0] == "comment" || words[0] == "obj_info") continue;
    if (words[0] == "format") {
      if (formatSeen) return "its header has a second format line" + at;
      if (words.size() != 3 || words[2] != "1.0")
        return "line " + std::to_string(line) + " names an unknown format (\"" + std::string(text) +
               "\")";
      if (words[1] == "ascii") {
        format = Format::kAscii;
      } else if (words[1] == "binary_little_endian") {
        format = Format::kLittleEndian;
      } else if (words[1] == "binary_big_endian") {
        format = Format::kBigEndian;
      } else {
        return "line " + std::to_string(line) + " names an unknown format (\"" + std::string(text) +
               "\")";
      }
      formatSeen = true;
    } else if (words[0] == "element") {
      Element e;
      if (words.size() != 3 || !absl::SimpleAtoi(words[2], &e.count))
        return "its header has a malformed element line" + at;
      e.name = std::string(words[1]);
      elements.push_back(std::move(e));
    } else if (words[0] == "property") {
      if (elements.empty()) return "its header has a property before any element" + at;
      Property q;
      if (words.size() == 5 && words[1] == "list") {
        bool integer = false;
        q.list = true;
        q.countBytes = TypeBytes(words[2], &integer, &q.countSigned);
        q.bytes = TypeBytes(words[3]);
        if (q.countBytes == 0 || !integer || q.bytes == 0)
          return "its header has a list property of unknown or non-integer count type" + at;
      } else if (words.size() == 3) {
        q.bytes = TypeBytes(words[1]);
        if (q.bytes == 0) return "its header has a property of unknown type" + at;
      } else {
        return "its header has a malformed property line" + at;
      }
      elements.back().properties.push_back(q);
    } else if (words[0] == "end_header" && words.size() == 1) {
      if (!formatSeen) return "its header has no format line";
      for (const Element& e : elements) {
        if (e.count > 0 && e.properties.empty())
          return "element '" + e.name + "' has items but no properties";
        // Assimp keeps one triangle of each strip and drops the rest without a word.
        if (e.count > 0 && e.name == "tristrips") {
          return "it stores triangle strips (element 'tristrips'), which are not supported: "
                 "export triangles or polygons (element 'face')";
        }
      }
      const std::string_view body = bytes.substr(lineStart);
      return format == Format::kAscii ? CheckAscii(body, elements)
                                      : CheckBinary(body, elements, format == Format::kBigEndian);
    } else {
      return "its header has an unknown line" + at + " (\"" + std::string(text.substr(0, 40)) +
             "\")";
    }
  }
  if (line == 0) return "it does not start with a \"ply\" line";
  return "its header has no end_header line" +
         std::string(bytes.size() > kMaxHeaderBytes
                         ? " in its first " + std::to_string(kMaxHeaderBytes) + " bytes"
                         : "");
}

std::string GlbProblem(std::string_view bytes) {
  auto u32 = [&](size_t at) {
    uint32_t v = 0;
    for (int k = 3; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(bytes[at + size_t(k)]);
    return v;
  };
  if (bytes.size() < 20 || bytes.substr(0, 4) != "glTF")
    return "it does not start with a GLB header";
  const uint32_t version = u32(4);
  const uint64_t length = u32(8);
  if (version != 1 && version != 2) return "its GLB version is " + std::to_string(version);
  if (length > bytes.size() || length < 20) {
    return "its GLB header declares " + std::to_string(length) + " bytes; the file has " +
           std::to_string(bytes.size());
  }
  if (version == 1) {
    if (u32(12) > length - 20) return "its GLB content does not fit in the file";
    return "";
  }
  uint64_t at = 12;
  for (int chunk = 0; at + 8 <= length; ++chunk) {
    const uint64_t size = u32(at);
    if (chunk == 0 && bytes.substr(at + 4, 4) != "JSON") return "its first GLB chunk is not JSON";
    if (size > length - at - 8) {
      return "GLB chunk " + std::to_string(chunk) + " declares " + std::to_string(size) +
             " bytes; " + std::to_string(length - at - 8) + " are left";
    }
    at += 8 + size;
  }
  return GltfProblem(bytes.substr(20, u32(12)));  // the JSON chunk, which fits
}

namespace {

// A node graph that is not a forest: a child index out of range, a node with two parents (each
// level doubling the scene: 22 levels took 2.7 GB before assimp was stopped), a cycle, or nesting
// deeper than 1000.
std::string NodeProblem(const google::protobuf::Value& root) {
  const auto& fields = root.struct_value().fields();
  const auto nodesField = fields.find("nodes");
  if (nodesField == fields.end()) return "";
  const auto& nodes = nodesField->second.list_value().values();
  const int count = nodes.size();
  std::vector<int> parent(size_t(count), -1);
  for (int i = 0; i < count; ++i) {
    const auto& node = nodes[i].struct_value().fields();
    const auto children = node.find("children");
    if (children == node.end()) continue;
    for (const google::protobuf::Value& c : children->second.list_value().values()) {
      const double index = c.number_value();
      if (!(index >= 0 && index < count) || index != std::floor(index))
        return "node " + std::to_string(i) + " names a child that does not exist";
      const int child = int(index);
      if (parent[size_t(child)] >= 0 || child == i)
        return "node " + std::to_string(child) + " has two parents (glTF nodes form trees)";
      parent[size_t(child)] = i;
    }
  }
  // With one parent each, a node's depth is its chain of parents; a chain longer than the node
  // count is a cycle. Depths found are kept, so each node is walked once.
  constexpr int kMaxDepth = 1000;
  std::vector<int> depth(size_t(count), -1);
  std::vector<int> chain;
  for (int i = 0; i < count; ++i) {
    chain.clear();
    int n = i;
    for (; n >= 0 && depth[size_t(n)] < 0; n = parent[size_t(n)]) {
      chain.push_back(n);
      if (int(chain.size()) > count) return "its nodes form a cycle";
    }
    // Depths from the top of the chain down: its known depth, or 0 at a root.
    int next = n >= 0 ? depth[size_t(n)] + 1 : 0;
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) depth[size_t(*it)] = next++;
    if (depth[size_t(i)] > kMaxDepth)
      return "its nodes nest deeper than " + std::to_string(kMaxDepth) + " levels";
  }
  return "";
}

// Geometry assimp would read wrong without a word: the quantized or meshopt-compressed attributes
// of extensions it does not implement (int16 positions read as floats), triangle lists whose
// index (or vertex) count is not a multiple of 3 (the rest dropped), and a node whose morph
// target weights (its own, else its mesh's) are not all zero (not applied).
std::string PrimitiveProblem(const google::protobuf::Value& root) {
  const auto& fields = root.struct_value().fields();
  for (const char* list : {"extensionsUsed", "extensionsRequired"}) {
    const auto used = fields.find(list);
    if (used == fields.end()) continue;
    for (const google::protobuf::Value& name : used->second.list_value().values()) {
      const std::string& extension = name.string_value();
      if (extension == "KHR_mesh_quantization" || extension == "EXT_meshopt_compression" ||
          extension == "KHR_meshopt_compression") {
        return "it uses the glTF extension " + extension +
               ", which the importer does not read: export without it";
      }
    }
  }
  const auto member = [](const google::protobuf::Value& v, const char* name) {
    const auto& f = v.struct_value().fields();
    const auto it = f.find(name);
    return it == f.end() ? nullptr : &it->second;
  };
  const google::protobuf::Value* accessors = member(root, "accessors");
  // The count of accessor `index`, or -1 when the file does not say.
  const auto accessorCount = [&](const google::protobuf::Value* index) -> double {
    if (index == nullptr || accessors == nullptr) return -1;
    const auto& list = accessors->list_value().values();
    const double i = index->number_value();
    if (!(i >= 0 && i < list.size()) || i != std::floor(i)) return -1;
    const google::protobuf::Value* count = member(list[int(i)], "count");
    return count == nullptr ? -1 : count->number_value();
  };
  const google::protobuf::Value* meshes = member(root, "meshes");
  if (meshes == nullptr) return "";
  const auto& meshList = meshes->list_value().values();
  const auto anyNonZero = [](const google::protobuf::Value* weights) {
    if (weights == nullptr) return false;
    for (const google::protobuf::Value& w : weights->list_value().values())
      if (w.number_value() != 0) return true;
    return false;
  };
  // A node's weights, when it has them, override its mesh's (glTF 2.0, 3.7.2.2).
  if (const google::protobuf::Value* nodes = member(root, "nodes")) {
    const auto& nodeList = nodes->list_value().values();
    for (int n = 0; n < nodeList.size(); ++n) {
      const google::protobuf::Value* mesh = member(nodeList[n], "mesh");
      if (mesh == nullptr) continue;
      const double m = mesh->number_value();
      if (!(m >= 0 && m < meshList.size()) || m != std::floor(m)) continue;  // assimp's to refuse
      const google::protobuf::Value* nodeWeights = member(nodeList[n], "weights");
      if (anyNonZero(nodeWeights != nullptr ? nodeWeights : member(meshList[int(m)], "weights"))) {
        return "node " + std::to_string(n) + " morphs mesh " + Num(int64_t(m)) +
               " (non-zero morph target weights), which is not applied: apply the morph to the "
               "mesh before export";
      }
    }
  }
  for (int m = 0; m < meshList.size(); ++m) {
    const std::string where = "mesh " + std::to_string(m);
    const google::protobuf::Value* primitives = member(meshList[m], "primitives");
    if (primitives == nullptr) continue;
    const auto& primitiveList = primitives->list_value().values();
    for (int p = 0; p < primitiveList.size(); ++p) {
      const google::protobuf::Value& primitive = primitiveList[p];
      const google::protobuf::Value* mode = member(primitive, "mode");
      if (mode != nullptr && mode->number_value() != 4) continue;  // TRIANGLES is 4, the default
      const google::protobuf::Value* indices = member(primitive, "indices");
      const google::protobuf::Value* attributes = member(primitive, "attributes");
      const double count =
          indices != nullptr
              ? accessorCount(indices)
              : accessorCount(attributes ? member(*attributes, "POSITION") : nullptr);
      if (count > 0 && std::fmod(count, 3) != 0) {
        return where + " primitive " + std::to_string(p) + " is a triangle list of " +
               Num(int64_t(count)) + (indices != nullptr ? " indices" : " vertices") +
               ", not a multiple of 3";
      }
    }
  }
  return "";
}

}  // namespace

std::string GltfProblem(std::string_view json) {
  constexpr int kMaxNesting = 100;
  if (JsonNestsDeeperThan(json, kMaxNesting))
    return "its JSON nests deeper than " + std::to_string(kMaxNesting) + " levels";
  google::protobuf::Value root;
  if (!google::protobuf::util::JsonStringToMessage(std::string(json), &root).ok()) return "";
  for (const auto check : {NodeProblem, PrimitiveProblem}) {
    if (std::string problem = check(root); !problem.empty()) return problem;
  }
  return "";
}

std::string MeshFileProblem(std::string_view bytes, const std::string& format) {
  if (format == "ply") return PlyProblem(bytes);
  if (format == "glb") return GlbProblem(bytes);
  if (format == "gltf") return GltfProblem(bytes);
  return "";
}

}  // namespace probebake::job_internal
