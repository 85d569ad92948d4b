// Mesh files through assimp (private to core/src/job).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/math/vec3.h"

namespace probebake::job_internal {

// Triangles of a mesh file in the file's world space (node transforms applied, in double).
struct ImportedMesh {
  std::vector<Vec3d> positions;
  std::vector<uint32_t> indices;  // 3 per triangle, counter-clockwise front faces
};

// Reads `bytes` as `format` ("obj", "ply", "gltf", "glb"): polygons triangulated, points and lines
// ignored, every mesh instance of the node tree merged with its accumulated node transform. The
// file's materials are ignored and the files it references (an OBJ's mtllib, a glTF's external
// buffers) are never opened. Only the importer of `format` reads the bytes (assimp would otherwise
// try each of its other formats), and a PLY header is checked before assimp reads it.
// INVALID_ARGUMENT "<fieldPath>: ..." when assimp cannot read it, when it holds no triangle, or
// when its triangles would bring the scene's count (`trianglesBefore` before this file) above
// `maxTriangles` (0: no limit); that check runs before any vertex is copied. `name` is the file's
// name for messages.
absl::StatusOr<ImportedMesh> ImportMesh(std::string_view bytes, const std::string& format,
                                        const std::string& name, const std::string& fieldPath,
                                        int64_t trianglesBefore, int64_t maxTriangles);

}  // namespace probebake::job_internal
