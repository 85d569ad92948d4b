// Mesh imports an asset-check child hands its parent (probebake/job/mesh_imports.h). The child has
// just run an importer on a client's file: a file that subverted it could make it write anything,
// so the parent's reader is a trust boundary like any other parser of outside input. Each entry is
// decoded against the binding it states itself, so that mutations reach the body. Seeds: the
// hand-overs of `probebake check-assets` for assimp's BoxTextured glTF with its own material (a
// 211 x 211 texture) and for an OBJ quad and that glTF under a job material.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/src/job/imported_mesh_codec.h"
#include "probebake/base/byte_codec.h"
#include "probebake/base/log.h"
#include "probebake/job/mesh_imports.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = (probebake::SetLogLevel(spdlog::level::off), true);
  (void)quiet;
  const absl::StatusOr<probebake::MeshImports> imports =
      probebake::MeshImports::Parse(std::string_view(reinterpret_cast<const char*>(data), size));
  if (!imports.ok()) return 0;
  for (int mesh = 0; mesh < 64; ++mesh) {
    const std::string* entry = imports->Find(mesh);
    if (entry == nullptr || entry->size() < 8) continue;
    // The binding the entry states: after its 8-byte header, the mesh index, hash, format and
    // material choice.
    probebake::ByteReader header(std::string_view(*entry).substr(8));
    probebake::job_internal::ImportBinding binding;
    uint8_t fileMaterials = 0;
    if (!header.Pod(&binding.mesh) || !header.String(&binding.sha256) ||
        !header.String(&binding.format) || !header.Pod(&fileMaterials))
      continue;
    binding.fileMaterials = fileMaterials == 1;
    (void)probebake::job_internal::DecodeImportedMesh(*entry, binding);
  }
  return 0;
}
