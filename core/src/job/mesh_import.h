// Mesh files through assimp (private to core/src/job).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake::job_internal {

// Where a file material's map is read: its uv set, and the affine map from the set's coordinates
// (u, 1 - v as assimp gives them: x right, y down) to image coordinates (scene.h's TextureMap),
// x' = m[0] x + m[1] y + m[2], y' = m[3] x + m[4] y + m[5] (glTF's KHR_texture_transform).
struct MapPlacement {
  unsigned uvSet = 0;
  std::array<double, 6> transform = {1, 0, 0, 0, 1, 0};
};

// A material of a model file, reduced to what diffuse transport reads: `material` with its maps
// decoded (its name is the file's), and where each map is read.
struct FileMaterial {
  Material material;
  MapPlacement albedoAt, emissionAt, coverageAt;
};

// A file's photometric lights in the job's radiometric units: glTF's candela (point, spot) and
// lux (directional) divided by 683 lm/W, so that a 683 cd point light is a job point light of
// intensity 1 and 683 lux a directional irradiance of 1.
inline constexpr double kLumensPerWatt = 683;

// Triangles of a mesh file in the file's world space (node transforms applied, in double), except
// for the meshes the node tree places more than once: those are held once, in their own frame, as
// a group with its placements.
struct ImportedMesh {
  std::vector<Vec3d> positions;
  std::vector<uint32_t> indices;            // 3 per triangle, counter-clockwise front faces
  std::vector<uint32_t> triangleMaterials;  // per triangle, an index into `materials`
  // Per triangle (empty: all 0): 0 for a triangle in world space, g > 0 for one of group g - 1,
  // whose vertices are in its mesh's own frame and serve no other group.
  std::vector<uint32_t> triangleGroups;
  // Per group: where the file places it (node transforms), at least two placements.
  std::vector<std::vector<MeshPlacement>> groupPlacements;
  std::vector<FileMaterial> materials;  // the file's materials the triangles use
  // Per vertex, when a material the triangles use needs them (else empty): image coordinates of
  // its maps (each vertex has one material) and linear RGBA vertex colours (1 where a vertex has
  // none).
  std::vector<std::array<float, 2>> albedoUv, emissionUv, coverageUv;
  std::vector<std::array<float, 4>> colors;
  // With the file's materials: its lights (glTF KHR_lights_punctual), placed by their nodes, in
  // the job's units (photometric values / kLumensPerWatt).
  std::vector<Light> lights;
  // With the file's materials: the glTF extensions the file uses that the bake ignores (they do
  // not change diffuse transport), sorted; each is logged once.
  std::vector<std::string> ignoredExtensions;
  // Every file the model referenced and the import read, by its normalized path
  // (NormalizeModelPath) to its bytes: a glTF's external buffers and images, an OBJ's .mtl and
  // texture maps.
  std::map<std::string, std::string> references;
  // The digests of those files by the same paths: what BuildBakeJob keeps of them, and all that a
  // hand-over between processes carries (imported_mesh_codec.h).
  struct FileDigest {
    std::string sha256;  // Sha256Hex
    int64_t sizeBytes = 0;
  };
  std::map<std::string, FileDigest> referenceDigests;
};

// The bytes of the file a model references, by the normalized path the model writes; an error
// names the mesh's field and that path. Called from the importing thread only.
using ReferenceReader = std::function<absl::StatusOr<std::string>(const std::string& modelPath)>;

// Reads `bytes` as `format` ("obj", "ply", "gltf", "glb"): polygons triangulated, points and lines
// ignored, every mesh instance of the node tree merged with its accumulated node transform; but
// when the nodes place more than `flattenUpToTriangles` triangles, the meshes that several nodes
// place alike (8 triangles or more) are kept once as a group with their transforms (JobLimits).
// The
// files it references (an OBJ's mtllib and map_Kd/map_Ke/map_d textures, a glTF's external buffers
// and images) are read through `readReference` only, never opened by path; a reference it cannot
// read refuses the file. Without `fileMaterials` (the job gives the mesh a material) the files only
// materials use (an OBJ's .mtl, textures) are not read, and `materials` holds assimp's reduction
// of the file's constant factors; with them, the maps are decoded (8-bit PNG, JPEG, TGA or BMP;
// a texture above `maxTexturePixels` pixels, 0: no limit, or one that cannot be decoded is
// refused naming `fieldPath`, the material and the path the model wrote). Only the importer of
// `format` reads the bytes (assimp would otherwise try each of its other formats), and a PLY header
// is checked before assimp reads it. INVALID_ARGUMENT "<fieldPath>: ..." when assimp cannot read
// it, when it holds no triangle, or when its triangles would bring the scene's count
// (`trianglesBefore` before this file; a group's triangles count once, each placement as 8)
// above `maxTriangles`
// (0: no limit); that check runs before any vertex is copied. `name` is the file's name for
// messages.
absl::StatusOr<ImportedMesh> ImportMesh(std::string_view bytes, const std::string& format,
                                        const std::string& name, const std::string& fieldPath,
                                        int64_t trianglesBefore, int64_t maxTriangles,
                                        int64_t flattenUpToTriangles,
                                        const ReferenceReader& readReference, bool fileMaterials,
                                        int64_t maxTexturePixels);

}  // namespace probebake::job_internal
