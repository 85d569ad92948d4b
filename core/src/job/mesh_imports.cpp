#include "probebake/job/mesh_imports.h"

#include "probebake/base/byte_codec.h"

namespace probebake {
namespace {

constexpr std::string_view kMagic = "PBIMPORTS1";

}  // namespace

const std::string* MeshImports::Find(int mesh) const {
  const auto it = entries_.find(mesh);
  return it == entries_.end() ? nullptr : &it->second;
}

void MeshImports::Put(int mesh, std::string entry) {
  entries_[mesh] = std::move(entry);
}

std::string MeshImports::Serialize() const {
  ByteWriter out;
  out.bytes().append(kMagic);
  out.Pod(uint64_t(entries_.size()));
  for (const auto& [mesh, entry] : entries_) {
    out.Pod(int32_t(mesh));
    out.String(entry);
  }
  return std::move(out.bytes());
}

absl::StatusOr<MeshImports> MeshImports::Parse(std::string_view bytes) {
  if (bytes.substr(0, kMagic.size()) != kMagic)
    return absl::InternalError("mesh imports: not a hand-over of mesh imports");
  ByteReader in(bytes.substr(kMagic.size()));
  MeshImports imports;
  uint64_t count = 0;
  // An entry is at least its index and its length.
  if (!in.Count(sizeof(int32_t) + sizeof(uint64_t), &count))
    return absl::InternalError("mesh imports: cut short in the entry count");
  for (uint64_t k = 0; k < count; ++k) {
    int32_t mesh = 0;
    std::string entry;
    if (!in.Pod(&mesh) || !in.String(&entry))
      return absl::InternalError("mesh imports: cut short in entry " + std::to_string(k));
    if (mesh < 0 || imports.entries_.count(mesh))
      return absl::InternalError("mesh imports: entry " + std::to_string(k) +
                                 " has a bad or repeated mesh index");
    imports.entries_.emplace(mesh, std::move(entry));
  }
  if (!in.AtEnd()) return absl::InternalError("mesh imports: bytes after the last entry");
  return imports;
}

}  // namespace probebake
