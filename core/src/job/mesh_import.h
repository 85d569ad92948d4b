// Mesh files through assimp (private to core/src/job).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/math/vec3.h"

namespace probebake::job_internal {

// A material of a model file, reduced to what diffuse transport reads (constant factors only).
struct FileMaterial {
  std::string name;  // the file's material name, for messages
  Vec3d albedo;      // diffuse albedo, each channel in [0, 1)
  Vec3d emission;    // emitted radiance, each channel >= 0
};

// Triangles of a mesh file in the file's world space (node transforms applied, in double).
struct ImportedMesh {
  std::vector<Vec3d> positions;
  std::vector<uint32_t> indices;            // 3 per triangle, counter-clockwise front faces
  std::vector<uint32_t> triangleMaterials;  // per triangle, an index into `materials`
  std::vector<FileMaterial> materials;      // the file's materials the triangles use
  // Every file the model referenced and the import read, by its normalized path
  // (NormalizeModelPath) to its bytes: a glTF's external buffers and images, an OBJ's .mtl and
  // texture maps.
  std::map<std::string, std::string> references;
};

// The bytes of the file a model references, by the normalized path the model writes; an error
// names the mesh's field and that path. Called from the importing thread only.
using ReferenceReader = std::function<absl::StatusOr<std::string>(const std::string& modelPath)>;

// Reads `bytes` as `format` ("obj", "ply", "gltf", "glb"): polygons triangulated, points and lines
// ignored, every mesh instance of the node tree merged with its accumulated node transform. The
// files it references (an OBJ's mtllib and map_Kd/map_Ke/map_d textures, a glTF's external buffers
// and images) are read through `readReference` only, never opened by path; a reference it cannot
// read refuses the file. Without `fileMaterials` (the job gives the mesh a material) the files only
// materials use (an OBJ's .mtl, textures) are not read, and `materials` holds assimp's reduction
// of the file's materials either way. Only the importer of `format` reads the bytes (assimp would
// otherwise try each of its other formats), and a PLY header is checked before assimp reads it.
// INVALID_ARGUMENT "<fieldPath>: ..." when assimp cannot read it, when it holds no triangle, or
// when its triangles would bring the scene's count (`trianglesBefore` before this file) above
// `maxTriangles` (0: no limit); that check runs before any vertex is copied. `name` is the file's
// name for messages.
absl::StatusOr<ImportedMesh> ImportMesh(std::string_view bytes, const std::string& format,
                                        const std::string& name, const std::string& fieldPath,
                                        int64_t trianglesBefore, int64_t maxTriangles,
                                        const ReferenceReader& readReference, bool fileMaterials);

}  // namespace probebake::job_internal
