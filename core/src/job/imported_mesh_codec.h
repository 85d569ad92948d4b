// One entry of a MeshImports hand-over (probebake/job/mesh_imports.h): an ImportedMesh and what
// it was imported from. Private to core/src/job (BuildBakeJob writes and reads entries).
#pragma once

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "mesh_import.h"

namespace probebake::job_internal {

// What an import is bound to: a parent uses an entry only for the same mesh, bytes and choice.
struct ImportBinding {
  int mesh = 0;        // index in scene.meshes
  std::string sha256;  // Sha256Hex of the mesh file's bytes
  std::string format;  // "obj", "ply", "gltf", "glb"
  bool fileMaterials = false;
};

// The entry of `mesh`: everything but `references` (their digests, `referenceDigests`, are kept).
// A texture several materials share is written once.
std::string EncodeImportedMesh(const ImportBinding& binding, const ImportedMesh& mesh);

// The ImportedMesh of `entry` (`references` empty, `referenceDigests` filled), checked as
// BuildBakeJob relies on it (indices within the vertices, material and texture indices within
// their tables, per-vertex arrays empty or one per vertex, texel counts matching the sizes).
// INTERNAL naming the mismatch when `entry` is bound to anything but `binding`, or is damaged.
absl::StatusOr<ImportedMesh> DecodeImportedMesh(std::string_view entry,
                                                const ImportBinding& binding);

}  // namespace probebake::job_internal
